"""GPhotoCamera against libgphoto2's OWN virtual camera (the real library path, no mocks).

VCAMERADIR must be set before gphoto2 is imported, so each scenario runs gphoto_vcam_helper.py in a
subprocess with the environment set (and XDG_CONFIG_HOME at a temp dir, where libgphoto2 keeps
capturetarget); the rest of the suite never sees the virtual camera.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rawtestfiles import mosaic_14bit, write_dng

HELPER = Path(__file__).with_name("gphoto_vcam_helper.py")

pytest.importorskip("gphoto2")


def run_helper(scenario: str, tmp_path: Path, *, virtual: bool = True, env_extra: dict | None = None) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "VCAMERADIR"}
    env.update(env_extra or {})
    env["XDG_CONFIG_HOME"] = str(tmp_path / "xdg")
    if virtual:
        env["VCAMERADIR"] = str(tmp_path / "vcamera")
    proc = subprocess.run([sys.executable, str(HELPER), scenario], env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def make_vcamera_folder(root: Path) -> Path:
    """The virtual camera's folder: a JPEG for capture() to return and a D610-like DNG to download."""
    from PIL import Image

    folder = root / "vcamera"
    folder.mkdir()
    rgb = (np.random.default_rng(0).random((48, 64, 3)) * 255).astype(np.uint8)
    Image.fromarray(rgb).save(folder / "frame.jpg")
    write_dng(folder / "VIRT_0001.DNG", mosaic_14bit(32, 48))
    return folder


@pytest.fixture
def vcamera(tmp_path):
    return make_vcamera_folder(tmp_path)


def test_detect_lists_the_virtual_camera(tmp_path, vcamera):
    assert run_helper("detect", tmp_path)["cameras"] == [["Nikon DSC D750", "usb:001,001"]]


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """One open/configure/capture/download/close session, shared by the tests that check its parts."""
    root = tmp_path_factory.mktemp("vcam_session")
    make_vcamera_folder(root)
    return run_helper("session", root)


def test_configuration_listing(session):
    config = session["config"]
    assert session["model"] == "Nikon DSC D750"
    assert config["capturetarget"]["choices"] == ["Internal RAM", "Memory card"]
    assert config["shutterspeed"]["kind"] == "radio"
    assert "0.0100s" in config["shutterspeed"]["choices"]
    assert "f/8" in config["f-number"]["choices"]
    assert config["serialnumber"]["readonly"] is True
    assert session["settings_before"]["shutter_s"] > 0
    assert session["shutter_speeds"] == sorted(session["shutter_speeds"])
    assert session["shutter_speeds"][-1] == pytest.approx(1.0)


def test_setting_values_by_parsed_number(session):
    # 0.011 s snaps to the offered 0.0100s label, f/7.9 to f/8
    assert session["applied"]["shutter_s"] == pytest.approx(0.01)
    assert session["shutter_widget_after"] == "0.0100s"
    assert session["applied"]["aperture"] == pytest.approx(8.0)
    assert session["f_number_after"] == "f/8"
    assert session["applied"]["capture_target"] == "Internal RAM"
    # choices are matched case-insensitively and the camera's label comes back
    assert session["capturetarget_set"] == "Memory card"


def test_capture_downloads_into_memory(session):
    cap = session["capture"]
    assert cap["head"] == "ffd8ff"          # the virtual camera captures JPEGs
    assert cap["size"] > 1000
    assert cap["mime"] == "image/jpeg"
    assert cap["exposure_s"] == pytest.approx(0.1)
    assert cap["aperture"] == pytest.approx(8.0)
    assert cap["camera"] == "Nikon DSC D750"
    assert cap["bulb"] is False
    assert cap["filename"].upper().endswith(".JPG")


def test_dng_download_is_byte_identical(session):
    assert session["dng"] == {"name": "VIRT_0001.DNG", "mime": "image/x-adobe-dng", "identical": True}
    assert any(f.endswith("/VIRT_0001.DNG") for f in session["files"])


def test_user_errors_are_one_line_with_codes(session):
    errors = session["errors"]
    assert errors["bad_choice"]["code"] == -2
    assert "'Nowhere' is not offered" in errors["bad_choice"]["message"]
    assert "Memory card" in errors["bad_choice"]["message"]
    assert "read-only" in errors["read_only"]["message"]
    assert errors["missing_setting"]["code"] == -6
    assert "no bulb" in errors["too_long_no_bulb"]["message"]
    assert errors["preview"]["code"] == -6            # capture_preview is unsupported by the virtual camera
    assert errors["preview"]["message"].startswith("live view: not supported")
    assert errors["missing_file"]["code"] == -108
    for err in errors.values():
        assert "\n" not in err["message"]


def test_close_releases_and_reopen_works(session):
    assert session["reopened"]["open"] is True and session["reopened"]["f_number"].startswith("f/")
    assert session["closed"] is True
    assert "not open" in session["after_close"]["message"]
    assert session["reopen_model"] == "Nikon DSC D750"
    assert session["wrong_port"]["code"] == -52
    assert "usb:009,009" in session["wrong_port"]["message"]


def test_real_gphoto2_errors_map_to_advice(tmp_path, vcamera):
    out = run_helper("errors", tmp_path)
    assert "connect the camera by USB and switch it on" in out["-105"]["message"]
    assert "gvfs-gphoto2-volume-monitor" in out["-53"]["message"]
    assert "gio mount -s gphoto2" in out["-53"]["message"]
    assert "busy" in out["-110"]["message"]
    assert "reconnect" in out["-52"]["message"]
    assert "did not answer in time" in out["-10"]["message"]
    assert "not supported" in out["-6"]["message"]
    assert "the camera refused the request" in out["-1"]["message"]      # advice for -1 (issue 15, item 5)
    for code, err in out.items():
        assert err["code"] == int(code)
        assert err["message"].endswith(f"[gphoto2 {code}]")


def test_no_camera_attached(tmp_path):
    out = run_helper("nocamera", tmp_path, virtual=False)
    if out["detect"]:
        pytest.skip(f"a real camera is attached: {out['detect']}")
    assert out["raw"]["code"] == -105                   # gp.Camera().init() itself
    assert out["ours"]["code"] == -105
    assert out["ours"]["message"] == ("open camera: no camera found: connect the camera by USB and switch it on "
                                      "(libgphoto2: Could not detect any camera) [gphoto2 -105]")


def test_capture_uses_trigger_and_the_file_announced_at_the_end_of_the_exposure(session):
    # the virtual camera is not a Nikon-capture camera: expose() waited for its FILE_ADDED / CAPTURE_COMPLETE
    cap = session["capture"]
    assert session["trigger_waits"] is False
    assert cap["filename"].startswith("GPH_") and cap["latency_s"] is not None and cap["latency_s"] < 5


def test_libgphoto2_answers_in_english_whatever_the_locale(tmp_path, vcamera):
    # python-gphoto2 binds libgphoto2's catalogues on import; a German desktop gets German labels and errors
    # until the driver re-binds them (issue 15, item 6)
    out = run_helper("locale", tmp_path, env_extra={"LANGUAGE": "de", "LC_ALL": "C.UTF-8"})
    assert out["before"]["error"] == "Unbekanntes Modell"          # the catalogue is really in use here
    assert out["after"]["error"] == "Unknown model"
    assert out["after"]["capturetarget"] == ["Internal RAM", "Memory card"]
    assert out["after"]["set_target"] == "Internal RAM"
