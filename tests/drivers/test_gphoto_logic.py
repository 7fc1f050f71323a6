"""GPhotoCamera logic the virtual camera cannot show: value parsing, error advice, busy retry, bulb, live view.

A small stand-in for the gphoto2 module (same calls, same widget API) plays a D610 with localised shutter
labels, a Bulb choice and a 'bulb' toggle. The real-library path is covered by test_gphoto_vcam.py.
"""
from __future__ import annotations

import subprocess
import sys
from io import BytesIO
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from drivers.camera.base import CameraError, CameraSettings
from drivers.camera.gphoto import (GPhotoCamera, camera_error, format_shutter, nearest_by_value, parse_aperture,
                                   parse_iso, parse_shutter, retry_busy)

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
    code = "import sys, drivers.camera, drivers.camera.gphoto; print('gphoto2' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# ---------------------------------------------------------------------------- a stand-in D610 module
EV_UNKNOWN, EV_TIMEOUT, EV_FILE_ADDED = 0, 1, 2
KINDS = {"window": 0, "section": 1, "text": 2, "range": 3, "toggle": 4, "radio": 5, "menu": 6}


class Widget:
    def __init__(self, name, kind, value=None, choices=(), readonly=False, children=()):
        self.name, self.kind, self.value = name, kind, value
        self.choices, self.readonly, self.children = list(choices), readonly, list(children)

    def get_type(self): return KINDS[self.kind]
    def get_name(self): return self.name
    def get_label(self): return self.name.title()
    def get_value(self): return self.value
    def set_value(self, value): self.value = value
    def get_readonly(self): return int(self.readonly)
    def count_choices(self): return len(self.choices)
    def get_choice(self, i): return self.choices[i]
    def count_children(self): return len(self.children)
    def get_child(self, i): return self.children[i]


class FakeFile:
    def __init__(self, data: bytes, mime: str):
        self.data, self.mime = data, mime

    def get_data_and_size(self): return self.data
    def get_mime_type(self): return self.mime


D610_SHUTTER = ["0,0002s", "0,0010s", "0,0040s", "0,0080s", "0,0167s", "0,1000s", "0,5000s", "1,0000s",
                "15,0000s", "30,0000s", "Bulb"]


class FakeD610:
    """Records every config write; releasing the bulb queues a FILE_ADDED event like the real camera."""

    def __init__(self, widgets=None):
        self.widgets = {w.name: w for w in (widgets or self.default_widgets())}
        self.writes: list[tuple[str, object]] = []
        self.events: list[tuple[int, object]] = []
        self.files: dict[str, bytes] = {}
        self.preview_data = b""
        self.counter = 0
        self.exited = False
        self.file_on_bulb_release = True

    @staticmethod
    def default_widgets():
        return [
            Widget("iso", "radio", "100", ["Auto", "100", "200", "400", "800", "Hi 1"]),
            Widget("shutterspeed", "radio", "0,0080s", D610_SHUTTER),
            Widget("f-number", "radio", "f/8", ["f/4", "f/5.6", "f/8", "f/11", "f/16"]),
            Widget("imagequality", "radio", "JPEG Fine", ["JPEG Basic", "JPEG Fine", "NEF (Raw)",
                                                          "NEF+Fine"]),
            Widget("capturetarget", "radio", "Memory card", ["Internal RAM", "Memory card"]),
            Widget("bulb", "toggle", 0),
            Widget("viewfinder", "toggle", 0),
            Widget("batterylevel", "text", "80%", readonly=True),
        ]

    # camera API used by GPhotoCamera
    def init(self): pass
    def exit(self): self.exited = True
    def get_abilities(self): return SimpleNamespace(model="Nikon DSC D610")
    def get_config(self): return Widget("main", "window", children=[Widget("s", "section", children=list(self.widgets.values()))])

    def get_single_config(self, name):
        w = self.widgets[name]
        return Widget(w.name, w.kind, w.value, w.choices, w.readonly)

    def set_single_config(self, name, widget):
        self.writes.append((name, widget.value))
        self.widgets[name].value = widget.value
        if name == "bulb" and widget.value == 0 and self.file_on_bulb_release and \
                any(n == "bulb" and v == 1 for n, v in self.writes):
            self.events.append((EV_UNKNOWN, "PTP Property d1a2 changed"))
            self.events.append((EV_FILE_ADDED, self._new_file()))

    def _new_file(self):
        self.counter += 1
        name = f"DSC_{self.counter:04d}.NEF"
        self.files[name] = f"NEF-{self.counter}".encode()
        return SimpleNamespace(folder="/store_00010001/DCIM/100D610", name=name)

    def wait_for_event(self, timeout_ms):
        if self.events:
            return self.events.pop(0)
        return EV_TIMEOUT, None

    def capture(self, kind):
        return self._new_file()

    def file_get(self, folder, name, kind):
        return FakeFile(self.files[name], "image/x-nikon-nef")

    def capture_preview(self):
        return FakeFile(self.preview_data, "image/jpeg")


def fake_module(cam: FakeD610):
    return SimpleNamespace(Camera=lambda: cam, GPhoto2Error=FakeGPhoto2Error, GP_EVENT_TIMEOUT=EV_TIMEOUT,
                           GP_EVENT_FILE_ADDED=EV_FILE_ADDED, GP_CAPTURE_IMAGE=0, GP_FILE_TYPE_NORMAL=1,
                           GP_LOG_ERROR=0, GP_LOG_VERBOSE=1, GP_LOG_DEBUG=2, GP_LOG_DATA=3,
                           use_python_logging=lambda mapping=None: object())


class FakeClock:
    def __init__(self):
        self.now = 0.0
        self.sleeps: list[float] = []

    def sleep(self, s):
        self.sleeps.append(s)
        self.now += s

    def __call__(self):
        self.now += 0.01  # every look at the clock lets a little time pass
        return self.now


def open_fake(widgets=None, **kw):
    d610 = FakeD610(widgets)
    clock = FakeClock()
    cam = GPhotoCamera(gp_module=fake_module(d610), sleep=clock.sleep, clock=clock, **kw)
    cam.open()
    return cam, d610, clock


def test_localised_shutter_labels_are_matched_by_value():
    cam, d610, _ = open_fake()
    assert cam.shutter_speeds()[0] == pytest.approx(0.0002)
    assert cam.shutter_speeds()[-1] == pytest.approx(30.0)
    taken = cam.apply(CameraSettings(shutter_s=1 / 125, iso=250, aperture=5.6, image_quality="nef (raw)",
                                     capture_target="Internal RAM"))
    assert ("shutterspeed", "0,0080s") not in d610.writes     # already set: not written again
    assert taken.shutter_s == pytest.approx(0.008)
    assert ("iso", "200") in d610.writes                      # 250 -> nearest offered number
    assert ("f-number", "f/5.6") in d610.writes
    assert ("imagequality", "NEF (Raw)") in d610.writes       # the camera's own spelling
    assert taken.image_quality == "NEF (Raw)" and taken.capture_target == "Internal RAM"
    cam.apply(CameraSettings(shutter_s=0.9))
    assert d610.widgets["shutterspeed"].value == "1,0000s"
    assert cam.config_summary()["battery"] == "80%"


def test_nikon_shutterspeed2_is_used_when_shutterspeed_is_missing():
    widgets = [w for w in FakeD610.default_widgets() if w.name != "shutterspeed"]
    widgets.append(Widget("shutterspeed2", "radio", "1/125", ["1/4000", "1/125", "1/60", "1", "30", "Bulb"]))
    cam, d610, _ = open_fake(widgets)
    assert cam.shutter_speeds() == pytest.approx([1 / 4000, 1 / 125, 1 / 60, 1.0, 30.0])
    cam.apply(CameraSettings(shutter_s=1 / 50))
    assert d610.writes[-1] == ("shutterspeed2", "1/60")


def test_timed_capture_downloads_the_raw_file():
    cam, d610, _ = open_fake()
    cap = cam.capture(0.5)
    assert cap.data == b"NEF-1" and cap.filename == "DSC_0001.NEF"
    assert cap.exposure_s == pytest.approx(0.5) and cap.extra["bulb"] is False
    assert cap.camera == "Nikon DSC D610" and cap.iso == 100 and cap.aperture == 8.0
    assert ("bulb", 1) not in d610.writes


def test_bulb_exposure_sequence():
    cam, d610, clock = open_fake()
    cap = cam.capture(45.0)
    shutter_write = d610.writes.index(("shutterspeed", "Bulb"))
    bulb_on = d610.writes.index(("bulb", 1))
    bulb_off = d610.writes.index(("bulb", 0))
    assert shutter_write < bulb_on < bulb_off
    assert 45.0 in clock.sleeps                      # held open for the exposure
    assert cap.extra["bulb"] is True
    assert cap.exposure_s == 45.0
    assert cap.data == b"NEF-1" and cap.filename == "DSC_0001.NEF"
    assert cam.settings().shutter_s == 45.0          # Bulb reads back as the exposure it was set for
    # 30 s is still a timed speed: no bulb
    cam.capture(30.0)
    assert d610.widgets["shutterspeed"].value == "30,0000s"
    assert d610.writes.count(("bulb", 1)) == 1


def test_bulb_is_released_when_the_wait_is_interrupted():
    cam, d610, _ = open_fake()

    def interrupted(_s):
        raise KeyboardInterrupt

    cam._sleep = interrupted
    with pytest.raises(KeyboardInterrupt):
        cam.capture(60.0)
    assert d610.writes[-1] == ("bulb", 0)
    assert d610.widgets["bulb"].value == 0


def test_bulb_file_timeout():
    cam, d610, _ = open_fake(file_timeout_s=5.0)
    d610.file_on_bulb_release = False
    with pytest.raises(CameraError) as err:
        cam.capture(40.0)
    assert err.value.code == -10
    assert "no file arrived within 45 s" in str(err.value)
    assert d610.widgets["bulb"].value == 0


def test_extra_files_are_reported():
    cam, d610, _ = open_fake()
    d610.events.append((EV_FILE_ADDED, SimpleNamespace(folder="/store_00010001/DCIM/100D610",
                                                       name="DSC_0001.JPG")))
    cap = cam.capture(0.5)
    assert cap.extra["extra_files"] == ["/store_00010001/DCIM/100D610/DSC_0001.JPG"]


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
    real_capture = d610.capture
    failures = [FakeGPhoto2Error(-110, "I/O in progress")]

    def busy_once(kind):
        if failures:
            raise failures.pop()
        return real_capture(kind)

    d610.capture = busy_once
    assert cam.capture(0.5).filename == "DSC_0001.NEF"
    assert 0.5 in clock.sleeps


def test_unknown_values_and_missing_settings():
    cam, _, _ = open_fake()
    with pytest.raises(CameraError, match="'TIFF' is not offered; the camera offers JPEG Basic"):
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
    d610 = FakeD610()
    cam = GPhotoCamera(gp_module=fake_module(d610))          # default sleep: waits on the abort event
    cam.open()
    real_set = d610.set_single_config

    def press_abort_when_bulb_opens(name, widget):
        real_set(name, widget)
        if name == "bulb" and widget.value == 1:
            cam.abort()                                      # as the GUI's Abort button would, from its thread

    d610.set_single_config = press_abort_when_bulb_opens
    with pytest.raises(CameraError, match="bulb exposure aborted after 0 s of 600 s") as err:
        cam.capture(600.0)
    assert err.value.code == -112
    assert d610.writes[-1] == ("bulb", 0)
    # the next capture is not affected by the earlier abort
    d610.set_single_config = real_set
    assert cam.capture(0.5).filename.endswith(".NEF")


def test_reopen_after_reenumeration():
    cam, d610, _ = open_fake()
    cam.reopen()
    assert d610.exited and cam.is_open
