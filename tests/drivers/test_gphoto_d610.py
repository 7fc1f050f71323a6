"""What a real D610 does through libgphoto2 (issue 15), replayed by the scripted stand-in (gphoto_fake.py): one test
per item: 1 the bulb release, 2 the NEF of a NEF+JPEG pair, 3 Bulb left set and live view, 4 libgphoto2's own
error text, 5 the error mapping, 6 translated labels, 7 the exact exposure, 8 auto ISO."""
from __future__ import annotations

import logging
import threading

import pytest
from gphoto_fake import BULB, FakeGPhoto2, open_scripted

from dualrgb.core.light_safety import SafetySettings
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.drivers.camera.base import CameraError, CameraSettings
from dualrgb.drivers.camera.gphoto import GPhotoCamera


# ------------------------------------------------------------------------------------------ 1 bulb release
@pytest.mark.fault("camera")
@pytest.mark.parametrize("code", [-110, -1])
def test_bulb_release_is_sent_once_and_busy_afterwards_means_closed(code, caplog):
    def busy_release(d610):
        d610.release_error, d610.release_gate, d610.processing_reads = code, threading.Event(), 3

    cam, d610, _, _ = open_scripted(setup=busy_release, bulb_release_grace_s=0.01)
    exposure = cam.expose(45.0)
    # expose() returned after the release was sent, while libgphoto2 still waits for the camera
    assert not d610.shutter_open and len(d610.releases) == 1 and d610.gate_opened is None
    d610.release_gate.set()
    with caplog.at_level(logging.INFO, logger="dualrgb.drivers.camera.gphoto"):
        raw = cam.fetch(exposure)                    # waits for the release, then for the file
    assert raw.filename == "capt0000.nef" and raw.extra["bulb"] and d610.gate_opened is True
    assert d610.writes.count(("bulb", 0)) == 1       # released once: no retry of the release
    assert "still processing" in caplog.text and ("0xa200" in caplog.text or "0x2019" in caplog.text)


@pytest.mark.fault("camera")
def test_a_failed_terminate_capture_says_the_shutter_may_still_be_open():
    cam, d610, _, _ = open_scripted(setup=lambda d: setattr(d, "terminate_fails", True))
    with pytest.raises(CameraError) as err:
        cam.expose(45.0)
    msg = str(err.value)
    assert msg.startswith("bulb could not be ended: the shutter may still be open") and "\n" not in msg
    assert "ptp_nikon_terminatecapture" in msg and err.value.code == -7


@pytest.mark.fault("camera")
def test_long_exposure_nr_is_switched_off_and_recorded():
    cam, d610, _, _ = open_scripted()
    assert ("longexpnr", "Off") in d610.writes and not d610.longexpnr
    raw = cam.capture(5.0)
    assert raw.extra["long_exposure_nr"] == "switched off"
    assert cam.latency_for(5.0) == cam.latency_s


@pytest.mark.fault("light safety")
def test_long_exposure_nr_left_on_allows_twice_the_exposure_and_says_so():
    cam, d610, _, _ = open_scripted(setup=lambda d: d.locked.add("longexpnr"), latency_s=2.0)
    assert cam.long_exposure_nr.startswith("on: could not be switched off") and "0xa005" in cam.long_exposure_nr
    assert cam.latency_for(0.5) == 2.0 and cam.latency_for(5.0) == 7.0      # the dark frame after 5 s
    safety = SafetySettings().for_camera(cam)
    assert safety.max_exposure_s == pytest.approx(3.9, abs=1e-6)   # 0.2 + t + 2 + t <= 10 s
    raw = cam.capture(3.0)
    assert raw.extra["long_exposure_nr"].startswith("on: could not be switched off")


# ------------------------------------------------------------------------------------------ 2 pick the NEF
@pytest.mark.fault("camera")
def test_raw_only_quality_is_forced_at_open_and_before_each_capture():
    cam, d610, _, _ = open_scripted()
    assert d610.writes[0] == ("imagequality", "NEF (Raw)")
    d610.quality = "NEF+Fine"                         # someone turned the camera's quality dial
    d610.writes.clear(), d610.calls.clear()
    raw = cam.capture(1 / 60)
    assert sorted(d610.writes) == [("imagequality", "NEF (Raw)"), ("shutterspeed2", "1/60")]   # before the trigger
    assert d610.calls == ["trigger"]
    assert raw.filename.endswith(".nef") and raw.extra["extra_files"] == []


@pytest.mark.fault("camera")
@pytest.mark.parametrize("jpeg_first, late_reads", [(True, 0), (False, 0), (False, 3), (False, 40)])
def test_nef_jpeg_pairs_the_nef_is_kept_and_a_late_jpeg_is_never_a_frame(jpeg_first, late_reads):
    def pairs(d610):
        d610.locked.add("imagequality")
        d610.quality, d610.jpeg_first, d610.pair_late_reads = "NEF+Fine", jpeg_first, late_reads

    cam, d610, _, _ = open_scripted(setup=pairs, pair_timeout_s=2.0)
    assert cam.stores_pairs
    frames = [cam.capture(1 / 125) for _ in range(3)]
    assert [f.filename[-4:] for f in frames] == [".nef"] * 3
    assert len({f.data for f in frames}) == 3 and all(f.data.startswith(b"NEF-") for f in frames)


# ------------------------------------------------------------------------------- 3 Bulb left set, live view
@pytest.mark.fault("camera")
def test_after_bulb_the_timed_speed_is_back_and_live_view_works():
    cam, d610, _, _ = open_scripted()
    cam.apply(CameraSettings(shutter_s=1 / 30 * 2))                  # 1/15 -> nearest offered 1/8
    before = d610.widgets()["shutterspeed2"].value
    cam.preview()                                                    # live view on
    raw = cam.capture(45.0)
    assert d610.writes.index(("viewfinder", 0)) < d610.writes.index(("bulb", 1))   # live view off before bulb
    assert raw.exposure_s == cam.settings().shutter_s == 45.0        # the frame's record says bulb, 45 s
    d610.calls.clear()
    cam.preview()                                                    # no "Bulb warning": restored first
    assert d610.widgets()["shutterspeed2"].value == before and d610.calls == ["preview"]


@pytest.mark.fault("camera")
def test_bulb_left_set_by_an_earlier_program_live_view_is_refused_in_one_line():
    cam, d610, _, _ = open_scripted(setup=lambda d: setattr(d, "exposure", BULB))
    with pytest.raises(CameraError) as err:
        cam.preview()
    msg = str(err.value)
    assert "Liveview cannot start: Bulb warning" in msg and "set a timed shutter speed" in msg and "\n" not in msg


# -------------------------------------------------------------------------- 4, 5 errors and their logged text
OPEN_FAILURES = {
    "claimed by gvfs": (-53, "Could not claim interface 0 (Device or resource busy). Make sure no other program "
                             "(gvfs-gphoto2-volume-monitor) or kernel module (such as sdc2xx, stv680, spca50x) is "
                             "using the device and you have read/write access to the device.", "gio mount -s gphoto2"),
    "claim not permitted": (-53, "Could not claim interface 0 (Permission denied). Make sure no other program ...",
                            "udev rules"),
    "open not permitted": (-7, "'libusb_open (port->pl->d, &port->pl->dh)' failed: Access denied (insufficient "
                               "permissions) (-3)", "plugdev"),
    "no camera at the port": (-108, "", "no camera detected at this port"),
    "camera refused": (-1, "Nikon enable liveview failed", "the camera refused the request"),
}


@pytest.mark.fault("camera")
@pytest.mark.parametrize("case", list(OPEN_FAILURES))
def test_open_errors_give_advice_and_libgphoto2s_own_reason(case):
    code, logged, advice = OPEN_FAILURES[case]
    gp = FakeGPhoto2()
    gp.camera.init_error = (code, logged)
    with pytest.raises(CameraError) as err:
        GPhotoCamera(port="usb:001,007", gp_module=gp).open()
    msg = str(err.value)
    assert err.value.code == code and advice in msg and msg.endswith(f"[gphoto2 {code}]") and "\n" not in msg
    if logged:
        assert f"(libgphoto2: {logged[:40]}" in msg
    assert "the file is not on the camera" not in msg


@pytest.mark.fault("camera")
def test_a_refused_setting_names_libgphoto2s_reason():
    cam, d610, _, _ = open_scripted()
    d610.locked.add("f-number")
    with pytest.raises(CameraError) as err:
        cam.apply(CameraSettings(aperture=11))
    assert "was not set (0xa005: Set Property Not Supported)" in str(err.value) and err.value.code == -1


@pytest.mark.fault("camera")
def test_minus_2_on_a_settings_write_is_read_again_and_written_once_more():
    cam, d610, _, _ = open_scripted()
    d610.set_errors["iso"] = [-2]
    assert cam.apply(CameraSettings(iso=400)).iso == 400
    assert d610.writes.count(("iso", "400")) == 2
    d610.set_errors["iso"] = [-2, -2]
    with pytest.raises(CameraError) as err:
        cam.apply(CameraSettings(iso=800))
    assert err.value.code == -2 and "busy" in str(err.value) and "Parameter not Supported" in str(err.value)


# ------------------------------------------------------------------------------------------ 6 locales
@pytest.mark.fault("camera")
@pytest.mark.parametrize("lang, bulb, ram, raw, off", [
    ("de", "Langzeitbelichtung", "interner Speicher", "NEF (Raw)", "Aus"),
    ("fr", "Pose longue", "Mémoire interne", "NEF (brut)", "Désactivé"),
])
def test_translated_labels_are_matched_by_meaning(lang, bulb, ram, raw, off):
    cam, d610, _, _ = open_scripted(lang)
    assert ("imagequality", raw) in d610.writes and ("isoauto", off) in d610.writes
    assert ("longexpnr", off) in d610.writes
    cam.apply(CameraSettings(capture_target="Memory card"))
    cam.apply(CameraSettings(capture_target="Internal RAM"))
    assert d610.writes[-1] == ("capturetarget", ram)
    assert cam.shutter_speeds()[4] == pytest.approx(1 / 125)        # "0,0080s" / "0,0080 s" read as numbers
    raw_frame = cam.capture(45.0)
    assert ("shutterspeed2", bulb) in d610.writes and raw_frame.exposure_s == 45.0 and raw_frame.extra["bulb"]


# ------------------------------------------------------------------------------------------ 7 precision
@pytest.mark.fault("camera")
@pytest.mark.parametrize("asked, exact, rounded", [(1 / 4000, 1 / 4000, "0.0002s"), (0.75, 10 / 13, "0.7692s")])
def test_the_manifest_records_the_exact_exposure_of_shutterspeed2(asked, exact, rounded, tmp_path):
    cam, d610, _, _ = open_scripted()
    raw = cam.capture(asked)
    assert d610.widgets()["shutterspeed"].value == rounded           # what shutterspeed would have said
    assert raw.exposure_s == exact and raw.extra["shutter_setting"] == "shutterspeed2"
    session = CaptureSession.create(tmp_path / "s", {"test": "exact exposure"})
    entry = session.record(raw, "dark", step_id="dark/1")
    reread = CaptureSession.open(tmp_path / "s", readonly=True).entry("dark/1")
    assert entry.exposure_s == reread.exposure_s == exact            # HDR weighting reads this (pipeline)


# ------------------------------------------------------------------------------------------ 8 auto ISO
@pytest.mark.fault("camera")
def test_auto_iso_is_switched_off_at_open_and_when_iso_is_set_and_recorded():
    cam, d610, _, _ = open_scripted()
    assert ("isoauto", "Off") in d610.writes and cam.auto_iso == "switched off"
    d610.isoauto = True                                              # switched on again on the body
    cam.apply(CameraSettings(iso=200))
    assert d610.writes[-2:] == [("isoauto", "Off"), ("iso", "200")] and not d610.isoauto
    assert cam.capture(1 / 125).extra["auto_iso"] == "switched off"
    d610.isoauto = True
    d610.locked.add("isoauto")
    cam.apply(CameraSettings(iso=400))
    assert cam.capture(1 / 125).extra["auto_iso"].startswith("on: could not be switched off")


# ------------------------------------------------------------------------------------------ latency
def test_expose_ends_when_the_camera_is_ready_and_the_latency_is_measured():
    cam, d610, clock, _ = open_scripted(setup=lambda d: setattr(d, "shutter_lag_s", 0.3))
    d610.reads = 0
    exposure = cam.expose(1 / 125)
    assert d610.reads == 1                      # only the quick look for stale files: no file read, no download
    assert exposure.ended - exposure.started == pytest.approx(0.3 + 1 / 125, abs=0.05)
    assert cam.fetch(exposure).extra["latency_s"] == pytest.approx(0.3, abs=0.05)


def test_a_camera_that_is_no_nikon_reports_the_end_of_the_exposure_by_event():
    from gphoto_fake import GENERIC_SUMMARY

    cam, d610, _, _ = open_scripted(setup=lambda d: setattr(d, "summary", GENERIC_SUMMARY))
    assert cam._trigger_waits is False
    exposure = cam.expose(1 / 125)
    assert exposure.handle.files == [("/", "capt0000.nef")]          # its FILE_ADDED came before CAPTURE_COMPLETE
    assert cam.fetch(exposure).filename == "capt0000.nef"


def test_trigger_waits_only_on_nikon_capture_paths():
    from dualrgb.drivers.camera.gphoto import trigger_waits_for_exposure

    assert trigger_waits_for_exposure("\tGeneric Image Capture, Nikon Capture 3\n", to_ram=False)
    assert trigger_waits_for_exposure("Nikon Capture 1, Nikon Capture 2", to_ram=True)
    assert not trigger_waits_for_exposure("Nikon Capture 1, Nikon Capture 2", to_ram=False)
    assert not trigger_waits_for_exposure("Generic Image Capture, No vendor specific capture", to_ram=True)
