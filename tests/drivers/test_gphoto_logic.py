"""GPhotoCamera logic the virtual camera cannot show: value parsing, error advice, busy retry, bulb, live view.

The scripted stand-in for python-gphoto2 (gphoto_fake.py) plays a D610; test_gphoto_d610.py replays what a real
D610 does through libgphoto2 (issue 15). The real-library path is covered by test_gphoto_vcam.py.
"""
from __future__ import annotations

import gc
import subprocess
import sys
from io import BytesIO
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from gphoto_fake import EV_FILE_ADDED, FakeGPhoto2, Queued, open_scripted

from dualrgb.drivers.camera.base import CameraError, CameraSettings
from dualrgb.drivers.camera.gphoto import GPhotoCamera
from dualrgb.drivers.camera.gphoto_errors import LibraryLog, camera_error, retry_busy
from dualrgb.drivers.camera.gphoto_labels import (
    format_shutter,
    nearest_by_value,
    parse_aperture,
    parse_iso,
    parse_shutter,
)

ROOT = Path(__file__).resolve().parents[2]


# ------------------------------------------------------------------------------------------ parsing
@pytest.mark.parametrize("label, seconds", [
    ("30,0000s", 30.0), ("30.0000s", 30.0), ("0,0002s", 0.0002), ("0.0100s", 0.01), ("1/4000", 1 / 4000),
    ("1/4000s", 1 / 4000), ("1/125 sec", 1 / 125), ("30", 30.0), ("0.5", 0.5), ("0,5", 0.5), ("10/13", 10 / 13),
    ("13/10", 1.3), ('0"3', 0.3), ('30"', 30.0), ('1"5', 1.5), (" 2 s ", 2.0), (".5", 0.5), (0.25, 0.25),
])
def test_parse_shutter(label, seconds):
    assert parse_shutter(label) == pytest.approx(seconds)


@pytest.mark.parametrize("label", ["Bulb", "bulb", "Time", "x 1/200", "Auto", "", "0", "1/0", "-1", None])
def test_parse_shutter_non_numbers(label):
    assert parse_shutter(label) is None


def test_parse_aperture_and_iso():
    assert parse_aperture("f/5.6") == 5.6
    assert parse_aperture("f5,6") == 5.6
    assert parse_aperture("F/8") == 8.0
    assert parse_aperture("11") == 11.0
    assert parse_aperture("f/--") is None
    assert parse_aperture("implicit auto") is None
    assert parse_iso("100") == 100
    assert parse_iso("ISO 6400") == 6400
    assert parse_iso("Auto") is None
    assert parse_iso("Hi 1") is None


def test_nearest_in_stops_and_format():
    options = [(0.01, "a"), (0.0125, "b"), (1 / 60, "c")]
    assert nearest_by_value(0.011, options)[1] == "a"
    assert nearest_by_value(0.0118, options)[1] == "b"
    assert nearest_by_value(100.0, options)[1] == "c"
    assert format_shutter(1 / 125) == "1/125 s"
    assert format_shutter(45) == "45 s"
    assert format_shutter(None) == "bulb"


# ------------------------------------------------------------------------------------- error advice
class FakeGPhoto2Error(Exception):
    def __init__(self, code: int, string: str = ""):
        super().__init__(f"[{code}] {string}")
        self.code = code
        self.string = string or "fake"


@pytest.mark.parametrize("code, words", [
    (-105, "connect the camera by USB and switch it on"),
    (-53, "pkill -f gvfs-gphoto2-volume-monitor"),
    (-53, "gio mount -s gphoto2"),
    (-110, "busy"),
    (-52, "reconnect it and reopen"),
    (-10, "did not answer in time"),
    (-6, "not supported"),
])
def test_error_mapper(code, words):
    err = camera_error(FakeGPhoto2Error(code), "open camera")
    assert isinstance(err, CameraError)
    assert err.code == code
    assert words in str(err)
    assert str(err).startswith("open camera: ")
    assert "\n" not in str(err)


def test_error_mapper_unknown_code_keeps_library_text():
    err = camera_error(FakeGPhoto2Error(-999, "Something odd\nhappened"), "capture")
    assert str(err) == "capture: camera error: Something odd happened [gphoto2 -999]"
    assert err.code == -999


def test_busy_is_retried_with_backoff_then_succeeds():
    calls, sleeps = [], []

    def flaky():
        calls.append(1)
        if len(calls) < 3:
            raise FakeGPhoto2Error(-110, "I/O in progress")
        return "ok"

    assert retry_busy(flaky, "capture", error_type=FakeGPhoto2Error, sleep=sleeps.append) == "ok"
    assert sleeps == [0.5, 1.0]


def test_busy_gives_up_after_bounded_tries():
    sleeps = []

    def busy():
        raise FakeGPhoto2Error(-110, "I/O in progress")

    with pytest.raises(CameraError) as err:
        retry_busy(busy, "capture", error_type=FakeGPhoto2Error, tries=3, sleep=sleeps.append)
    assert err.value.code == -110
    assert sleeps == [0.5, 1.0]


def test_other_errors_are_not_retried():
    sleeps = []

    def claimed():
        raise FakeGPhoto2Error(-53)

    with pytest.raises(CameraError) as err:
        retry_busy(claimed, "open camera", error_type=FakeGPhoto2Error, sleep=sleeps.append)
    assert err.value.code == -53 and sleeps == []


def test_import_does_not_load_gphoto2():
    code = "import sys, dualrgb.drivers.camera, dualrgb.drivers.camera.gphoto; print('gphoto2' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# ---------------------------------------------------------------------------- on the scripted D610
def open_fake(**kw):
    """(camera, d610, clock) on the scripted D610 (English labels, Internal RAM, NEF)."""
    cam, d610, clock, _ = open_scripted(**kw)
    return cam, d610, clock


def test_localised_shutter_labels_are_matched_by_value():
    cam, d610, _, _ = open_scripted("de")
    assert cam.shutter_speeds()[0] == pytest.approx(1 / 4000)
    assert cam.shutter_speeds()[-1] == pytest.approx(30.0)
    d610.writes.clear()
    taken = cam.apply(CameraSettings(shutter_s=1 / 125, iso=250, aperture=5.6, image_quality="nef (raw)",
                                     capture_target="Internal RAM"))
    assert not any(n.startswith("shutterspeed") for n, _ in d610.writes)   # already set: not written again
    assert taken.shutter_s == pytest.approx(1 / 125)
    assert ("iso", "200") in d610.writes                      # 250 -> nearest offered number
    assert ("f-number", "f/5.6") in d610.writes
    assert ("capturetarget", "interner Speicher") in d610.writes   # the camera's own (German) spelling
    assert taken.image_quality == "NEF (Raw)" and taken.capture_target == "interner Speicher"
    cam.apply(CameraSettings(shutter_s=0.75))
    assert d610.writes[-1] == ("shutterspeed2", "10/13")
    assert cam.config_summary()["battery"] == "80%"


def test_shutterspeed_is_used_when_shutterspeed2_is_missing():
    cam, d610, _ = open_fake()
    cam._names.pop("shutterspeed2")
    assert cam.shutter_speeds()[0] == pytest.approx(0.0002)          # 1/4000 in 0.1 ms steps
    cam.apply(CameraSettings(shutter_s=1 / 50))
    assert d610.writes[-1] == ("shutterspeed", "0.0166s")


def test_timed_capture_downloads_the_raw_file():
    cam, d610, _ = open_fake()
    cap = cam.capture(0.5)
    assert cap.data == b"NEF-capt0000.nef" and cap.filename == "capt0000.nef"
    assert cap.exposure_s == pytest.approx(0.5) and cap.extra["bulb"] is False
    assert cap.camera == "Nikon DSC D610" and cap.iso == 100 and cap.aperture == 8.0
    assert ("bulb", 1) not in d610.writes and "trigger" in d610.calls and "capture" not in d610.calls


def test_bulb_exposure_sequence():
    cam, d610, clock = open_fake()
    cap = cam.capture(45.0)
    shutter_write = d610.writes.index(("shutterspeed2", "Bulb"))
    bulb_on = d610.writes.index(("bulb", 1))
    bulb_off = d610.writes.index(("bulb", 0))
    assert shutter_write < bulb_on < bulb_off
    assert 45.0 in clock.sleeps                      # held open for the exposure
    assert cap.extra["bulb"] is True and cap.extra["shutter_label"] == "Bulb"
    assert cap.exposure_s == 45.0
    assert cap.data == b"NEF-capt0000.nef"
    # 30 s is still a timed speed: no bulb
    cam.capture(30.0)
    assert d610.writes[-1] == ("shutterspeed2", "30")
    assert d610.writes.count(("bulb", 1)) == 1


def test_bulb_is_released_when_the_wait_is_interrupted():
    cam, d610, _ = open_fake()

    def interrupted(_s):
        raise KeyboardInterrupt

    cam._sleep = interrupted
    with pytest.raises(KeyboardInterrupt):
        cam.capture(60.0)
    assert d610.writes[-1] == ("bulb", 0) and not d610.shutter_open


def test_bulb_file_timeout():
    cam, d610, _ = open_fake(file_timeout_s=5.0)
    d610.processing_reads = 10_000                   # the camera never announces the file
    with pytest.raises(CameraError) as err:
        cam.capture(40.0)
    assert err.value.code == -10
    assert "no raw file arrived within 85 s after the exposure ended" in str(err.value)   # 5 s + twice 40 s
    assert not d610.shutter_open


def test_extra_files_are_reported():
    cam, d610, _ = open_fake()
    exposure = cam.expose(0.5)
    d610.events.append(Queued(EV_FILE_ADDED, SimpleNamespace(folder="/", name="capt0099.jpg"), 0))
    cap = cam.fetch(exposure)
    assert cap.extra["extra_files"] == ["//capt0099.jpg"] and cap.filename == "capt0000.nef"


def test_preview_decodes_jpeg_and_close_ends_live_view():
    from PIL import Image

    cam, d610, _ = open_fake()
    buf = BytesIO()
    Image.fromarray(np.full((12, 16, 3), (200, 100, 50), dtype=np.uint8)).save(buf, format="JPEG", quality=95)
    d610.preview_data = buf.getvalue()
    frame = cam.preview()
    assert frame.shape == (12, 16, 3) and frame.dtype == np.uint8
    assert abs(int(frame[6, 8, 0]) - 200) < 6
    d610.preview_data = b"not a jpeg"
    with pytest.raises(CameraError, match="not a JPEG"):
        cam.preview()
    cam.close()
    assert ("viewfinder", 0) in d610.writes and d610.exited
    cam.close()  # twice is fine


def test_busy_camera_during_capture_is_retried():
    cam, d610, clock = open_fake()
    d610.trigger_busy = 1
    assert cam.capture(0.5).filename == "capt0000.nef"
    assert 0.01 in clock.sleeps


def test_unknown_values_and_missing_settings():
    cam, _, _ = open_fake()
    with pytest.raises(CameraError, match="'TIFF' is not offered; the camera offers JPEG Fine"):
        cam.apply(CameraSettings(image_quality="TIFF"))
    with pytest.raises(CameraError, match="read-only"):
        cam.set_config_value("batterylevel", "100%")
    with pytest.raises(CameraError, match="no 'whitebalance' setting"):
        cam.get_config_value("whitebalance")
    with pytest.raises(CameraError, match="positive number of seconds"):
        cam.capture(0)


def test_detect_with_fake_list():
    class CameraList:
        def count(self): return 1
        def get_name(self, i): return "Nikon DSC D610"
        def get_value(self, i): return "usb:001,007"

    gp = SimpleNamespace(Camera=SimpleNamespace(autodetect=lambda: CameraList()), GPhoto2Error=FakeGPhoto2Error)
    assert GPhotoCamera.detect(gp) == [("Nikon DSC D610", "usb:001,007")]


def test_abort_ends_a_bulb_exposure_and_closes_the_shutter():
    gp = FakeGPhoto2()
    d610 = gp.camera
    cam = GPhotoCamera(gp_module=gp)                         # default sleep: waits on the abort event
    cam.open()
    real_put = d610._put_bulb

    def press_abort_when_bulb_opens(value):
        real_put(value)
        if value == 1:
            cam.abort()                                      # as the GUI's Abort button would, from its thread

    d610._put_bulb = press_abort_when_bulb_opens
    with pytest.raises(CameraError, match="bulb exposure aborted after 0 s of 600 s") as err:
        cam.capture(600.0)
    assert err.value.code == -112
    assert d610.writes[-1] == ("bulb", 0)
    # the next capture is not affected by the earlier abort
    d610._put_bulb = real_put
    assert cam.capture(0.5).filename.endswith(".nef")


def test_reopen_after_reenumeration():
    cam, d610, _ = open_fake()
    cam.reopen()
    assert d610.exited and cam.is_open


def test_library_log_hears_each_new_module_even_at_a_freed_ones_address():
    """A freed gphoto2 stand-in's id can be reused by the next one; the log still registers the new one (it once
    did not, so a test's camera errors lost libgphoto2's reason depending on which tests ran before)."""
    for i in range(30):
        gp = FakeGPhoto2()
        library_log = LibraryLog.attach(gp)
        mark = library_log.mark()
        gp.log("gp_context_error", f"reason {i}")
        assert library_log.reason(mark) == f"reason {i}"
        del gp
        gc.collect()                              # the stand-in and its camera form a cycle
