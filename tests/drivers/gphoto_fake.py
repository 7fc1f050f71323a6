"""A scripted stand-in for python-gphoto2 as drivers.camera.gphoto uses it, replaying what libgphoto2 does with a
Nikon D610 (read from libgphoto2 2.5's camlibs/ptp2 config.c and library.c, not run against a camera):

* ``Camera``: init/exit, the CameraWidget tree (get_config, get_single_config, set_single_config), get_summary,
  trigger_capture / capture, wait_for_event, file_get / file_delete, capture_preview;
* ``GPhoto2Error`` with libgphoto2's codes and their generic text, and ``gp_log_add_func``: the real reason of a
  failure is only in the log (GP_LOG_ERROR lines, ``gp_context_error`` messages), as in libgphoto2;
* ``shutterspeed`` (ExposureTime in 0.1 ms: 1/4000 s reads "0,0002s") and ``shutterspeed2`` (Nikon's exact
  "1/4000", "10/13", "30") over one exposure setting; ``bulb``=1 sets the exposure to Bulb itself (as
  ``_put_Nikon_Bulb`` does) and ``bulb``=0 sends TerminateCapture, then waits for the camera and may answer
  -110 or -1 (0xA200 'Bulb Release Busy'); live view is refused on Bulb ("Liveview cannot start: Bulb warning");
* labels in English, German or French (libgphoto2's own catalogues: "Langzeitbelichtung", "Pose longue",
  "interner Speicher", "NEF (brut)", "An"/"Aus", "%0.4f s");
* Nikon capture: ``trigger_capture`` returns once the camera is no longer busy (after the exposure, and after the
  long-exposure NR dark frame when that is on); files are announced by FILE_ADDED events, a NEF+JPEG pair's second
  file possibly many event reads later.

Time: the driver runs on a :class:`FakeClock`; the stand-in moves it on as the camera would (an exposure, a
wait_for_event that times out), except the bulb release's wait, which blocks on ``release_gate`` so that tests
can see expose() return, and the light go off, before it ends.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

GENERIC = {-1: "Unspecified error", -2: "Bad parameters", -6: "Unsupported operation", -7: "I/O problem",
           -10: "Timeout reading from or writing to the port",
           -52: "Could not find the requested device on the USB port",
           -53: "Could not claim the USB device", -105: "Unknown model", -108: "File not found",
           -110: "I/O in progress"}
EV_UNKNOWN, EV_TIMEOUT, EV_FILE_ADDED, EV_FOLDER_ADDED, EV_CAPTURE_COMPLETE = 0, 1, 2, 3, 4
KINDS = {"window": 0, "section": 1, "text": 2, "range": 3, "toggle": 4, "radio": 5, "menu": 6}
BULB = None                                     # the exposure setting's value for Bulb

LANGS = {
    "en": dict(bulb="Bulb", on="On", off="Off", ram="Internal RAM", card="Memory card", raw="NEF (Raw)",
               pair="NEF+Fine", jpeg="JPEG Fine", secs="{:.4f}s", point="."),
    "de": dict(bulb="Langzeitbelichtung", on="An", off="Aus", ram="interner Speicher", card="Speicherkarte",
               raw="NEF (Raw)", pair="NEF+Fine", jpeg="JPEG Fine", secs="{:.4f}s", point=","),
    "fr": dict(bulb="Pose longue", on="Activé", off="Désactivé", ram="Mémoire interne", card="Carte mémoire",
               raw="NEF (brut)", pair="NEF+Fine", jpeg="JPEG Fine", secs="{:.4f} s", point=","),
}
# (numerator, denominator) of the D610's speeds as Nikon's ExposureTime property lists them (a selection)
D610_SPEEDS = [(1, 4000), (1, 3200), (1, 2000), (1, 250), (1, 125), (1, 60), (1, 8), (1, 2), (10, 13), (1, 1),
               (13, 10), (5, 1), (10, 1), (15, 1), (30, 1)]
NIKON_SUMMARY = ("Manufacturer: Nikon Corporation\nModel: D610\nVendor Extension ID: 0xa (1.0)\n"
                 "\nDevice Capabilities:\n\tFile Download, File Deletion, File Upload\n"
                 "\tGeneric Image Capture, No Open Capture, Nikon Capture 1, Nikon Capture 2, Nikon Capture 3\n")
GENERIC_SUMMARY = ("Vendor Extension ID: 0xa (1.0)\n"
                   "\tGeneric Image Capture, No Open Capture, No vendor specific capture\n")


def _small_jpeg() -> bytes:
    from io import BytesIO

    from PIL import Image

    buf = BytesIO()
    Image.new("RGB", (16, 12), (90, 90, 90)).save(buf, format="JPEG")
    return buf.getvalue()


class GPhoto2Error(Exception):
    def __init__(self, code: int):
        self.code = code
        self.string = GENERIC.get(code, "Unknown error")
        super().__init__(f"[{code}] {self.string}")


class FakeClock:
    def __init__(self):
        self.now = 0.0
        self.sleeps: list[float] = []
        self._lock = threading.Lock()

    def sleep(self, s: float) -> None:
        self.sleeps.append(s)
        self.advance(s)

    def advance(self, s: float) -> None:
        with self._lock:
            self.now += s

    def __call__(self) -> float:
        self.advance(0.001)                     # every look at the clock lets a little time pass
        return self.now


class Widget:
    def __init__(self, name, kind, value=None, choices=(), readonly=False, children=(), label=None):
        self.name, self.kind, self.value = name, kind, value
        self.choices, self.readonly, self.children = list(choices), readonly, list(children)
        self.label = label or name.title()

    def get_type(self): return KINDS[self.kind]
    def get_name(self): return self.name
    def get_label(self): return self.label
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


@dataclass
class Queued:
    kind: int
    data: Any
    ready_at: int                               # visible from this wait_for_event read on


class ScriptedD610:
    """The camera. Knobs (set before the calls they affect) script its behaviour; ``writes``, ``calls`` and
    ``releases`` record what the driver did."""

    def __init__(self, module: FakeGPhoto2, lang: str = "en", speeds=D610_SPEEDS, summary: str = NIKON_SUMMARY):
        self.gp, self.t = module, LANGS[lang]
        self.speeds = list(speeds)
        self.summary = summary
        self.exposure: tuple[int, int] | None = (1, 125)
        self.quality, self.target, self.iso = self.t["jpeg"], self.t["ram"], "100"
        self.isoauto, self.longexpnr, self.live_view, self.shutter_open = True, True, False, False
        self.locked: set[str] = set()           # settings whose writes fail (-1, with libgphoto2's logged reason)
        self.set_errors: dict[str, list[int]] = {}   # one-shot error codes per setting write
        self.init_error: tuple[int, str] | None = None
        self.trigger_busy = 0                   # trigger_capture answers -110 this many times first
        self.shutter_lag_s = 0.1
        self.pair_late_reads = 0                # the pair's JPEG is announced this many event reads after the NEF
        self.jpeg_first = False
        self.release_gate: threading.Event | None = None   # libgphoto2's wait after TerminateCapture lasts
        self.gate_opened: bool | None = None                # until this is set (True) or 10 s passed (False)
        self.release_error: int | None = None
        self.terminate_fails = False
        self.processing_reads = 2               # event reads after a bulb release before its file is announced
        self.preview_data = _small_jpeg()
        self.writes: list[tuple[str, object]] = []
        self.calls: list[str] = []
        self.releases: list[float] = []
        self.events: list[Queued] = []
        self.files: dict[str, bytes] = {}
        self.reads = 0
        self.counter = 0
        self.exited = False
        self.clock: FakeClock | None = None

    # ------------------------------------------------------------------------------------ labels
    def _speed_label(self, speed: tuple[int, int] | None) -> str:
        if speed is BULB:
            return self.t["bulb"]
        units = int(speed[0] * 10000 / speed[1])            # ExposureTime is in 0.1 ms
        return self.t["secs"].format(units / 10000).replace(".", self.t["point"])

    @staticmethod
    def _speed2_label(speed: tuple[int, int] | None, t: dict) -> str:
        if speed is BULB:
            return t["bulb"]
        return f"{speed[0]}" if speed[1] == 1 else f"{speed[0]}/{speed[1]}"

    def widgets(self) -> dict[str, Widget]:
        t, speeds = self.t, self.speeds + [BULB]

        def on_off(v):
            return t["on"] if v else t["off"]

        return {w.name: w for w in [
            Widget("iso", "radio", self.iso, ["100", "200", "400", "800", "1600", "Hi 1"], label="ISO Speed"),
            Widget("isoauto", "radio", on_off(self.isoauto), [t["on"], t["off"]], label="ISO Auto"),
            Widget("shutterspeed", "radio", self._speed_label(self.exposure), [self._speed_label(s) for s in speeds]),
            Widget("shutterspeed2", "radio", self._speed2_label(self.exposure, t),
                   [self._speed2_label(s, t) for s in speeds]),
            Widget("f-number", "radio", "f/8", ["f/4", "f/5.6", "f/8", "f/11", "f/16"]),
            Widget("imagequality", "radio", self.quality, [t["jpeg"], t["raw"], t["pair"]]),
            Widget("capturetarget", "radio", self.target, [t["ram"], t["card"]]),
            Widget("longexpnr", "radio", on_off(self.longexpnr), [t["on"], t["off"]]),
            Widget("bulb", "toggle", 2),
            Widget("viewfinder", "toggle", int(self.live_view)),
            Widget("batterylevel", "text", "80%", readonly=True),
        ]}

    # ------------------------------------------------------------------------------------ camera API
    def init(self):
        self.calls.append("init")
        if self.init_error:
            code, logged = self.init_error
            if logged:
                self.gp.log("gp_context_error", logged)
            raise GPhoto2Error(code)

    def exit(self): self.exited = True
    def get_abilities(self): return SimpleNamespace(model="Nikon DSC D610")
    def get_summary(self): return self.summary
    def set_port_info(self, info): self.calls.append(f"port {info.get_path()}")
    def set_abilities(self, abilities): pass

    def get_config(self):
        return Widget("main", "window", children=[Widget("s", "section", children=list(self.widgets().values()))])

    def get_single_config(self, name):
        w = self.widgets()[name]
        return Widget(w.name, w.kind, w.value, w.choices, w.readonly, label=w.label)

    def set_single_config(self, name, widget):
        value = widget.value
        self.writes.append((name, value))
        errors = self.set_errors.get(name)
        if errors:
            code = errors.pop(0)
            self.gp.log("gp_context_error", f"The property '{name}' / 0x5004 was not set (0x2006: Parameter not "
                                            "Supported)")
            raise GPhoto2Error(code)
        if name in self.locked:
            self.gp.log("gp_context_error", f"The property '{name}' / 0x5004 was not set (0xa005: Set Property "
                                            "Not Supported)")
            raise GPhoto2Error(-1)
        getattr(self, f"_put_{name.replace('-', '_')}", lambda v: None)(value)

    def _put_iso(self, v): self.iso = v
    def _put_isoauto(self, v): self.isoauto = v == self.t["on"]
    def _put_longexpnr(self, v): self.longexpnr = v == self.t["on"]
    def _put_imagequality(self, v): self.quality = v
    def _put_capturetarget(self, v): self.target = v

    def _put_shutterspeed2(self, v):
        self.exposure = next(s for s in self.speeds + [BULB] if self._speed2_label(s, self.t) == v)

    def _put_shutterspeed(self, v):
        self.exposure = next(s for s in self.speeds + [BULB] if self._speed_label(s) == v)

    def _put_viewfinder(self, v):
        if v and self.exposure is BULB:
            self.gp.log("gp_context_error", "Liveview cannot start: Bulb warning")
            raise GPhoto2Error(-1)
        self.live_view = bool(v)

    def _put_bulb(self, v):
        if v:
            self.exposure = BULB                 # _put_Nikon_Bulb sets ExposureTime to bulb itself
            self.shutter_open = True
            return
        self.releases.append(time.monotonic())
        if self.terminate_fails:
            self.gp.log("_put_Nikon_Bulb [config.c:9324]",
                        "'ptp_nikon_terminatecapture (params, 0, 0)' failed: PTP I/O Error (0x02ff)")
            raise GPhoto2Error(-7)
        self.shutter_open = False
        if self.release_gate is not None:
            self.gate_opened = self.release_gate.wait(10)
        self._announce(processing=self.processing_reads)
        if self.release_error is not None:
            what = "Bulb Release Busy (0xa200)" if self.release_error == -1 else "Device Busy (0x2019)"
            self.gp.log("_put_Nikon_Bulb [config.c:9325]", f"'nikon_wait_busy(params, 100, 5000)' failed: {what}")
            raise GPhoto2Error(self.release_error)

    def _new_name(self, ext: str) -> tuple[str, str]:
        self.counter += 1
        if self.target == self.t["ram"]:
            return "/", f"capt{self.counter - 1:04d}.{ext.lower()}"
        return "/store_00010001/DCIM/100D610", f"DSC_{(self.counter + 1) // 2:04d}.{ext.upper()}"

    def _announce(self, processing: int = 0) -> None:
        """Queue this capture's FILE_ADDED events (raw, and the JPEG of a pair) and CAPTURE_COMPLETE."""
        at = self.reads + processing
        names = [("nef", b"NEF")]
        if self.quality == self.t["pair"]:
            names.append(("jpg", b"JPG"))
            if self.jpeg_first:
                names.reverse()
        for i, (ext, head) in enumerate(names):
            folder, name = self._new_name(ext)
            self.files[name] = head + b"-" + name.encode()
            late = self.pair_late_reads if i == 1 else 0
            self.events.append(Queued(EV_FILE_ADDED, SimpleNamespace(folder=folder, name=name), at + late))
        self.events.append(Queued(EV_CAPTURE_COMPLETE, None, at))
        self.events.sort(key=lambda q: q.ready_at)

    def trigger_capture(self):
        self.calls.append("trigger")
        if self.trigger_busy:
            self.trigger_busy -= 1
            raise GPhoto2Error(-110)
        seconds = self.exposure[0] / self.exposure[1] if self.exposure is not BULB else 0.0
        nr = seconds if self.longexpnr and seconds >= 1 else 0.0
        if self.clock:
            self.clock.advance(self.shutter_lag_s + seconds + nr)   # busy until the exposure (and NR) ended
        self._announce()

    def capture(self, kind):
        self.calls.append("capture")
        self.trigger_capture()
        event = next(q for q in self.events if q.kind == EV_FILE_ADDED)
        self.events.remove(event)
        return event.data

    def wait_for_event(self, timeout_ms):
        self.reads += 1
        ready = next((q for q in self.events if q.ready_at <= self.reads), None)
        if ready is not None:
            self.events.remove(ready)
            return ready.kind, ready.data
        if self.clock:
            self.clock.advance(timeout_ms / 1000)
        return EV_TIMEOUT, None

    def file_get(self, folder, name, kind):
        if name not in self.files:
            raise GPhoto2Error(-108)
        mime = "image/x-nikon-nef" if name.lower().endswith(".nef") else "image/jpeg"
        return FakeFile(self.files[name], mime)

    def file_delete(self, folder, name):
        self.files.pop(name, None)

    def capture_preview(self):
        self.calls.append("preview")
        if self.exposure is BULB:
            self.gp.log("gp_context_error", "Liveview cannot start: Bulb warning")
            raise GPhoto2Error(-1)
        self.live_view = True
        return FakeFile(self.preview_data, "image/jpeg")


class FakeGPhoto2:
    """The module: constants, GPhoto2Error, the log callbacks, Camera() -> the one ScriptedD610."""

    GPhoto2Error = GPhoto2Error
    GP_EVENT_UNKNOWN, GP_EVENT_TIMEOUT, GP_EVENT_FILE_ADDED = EV_UNKNOWN, EV_TIMEOUT, EV_FILE_ADDED
    GP_EVENT_FOLDER_ADDED, GP_EVENT_CAPTURE_COMPLETE = EV_FOLDER_ADDED, EV_CAPTURE_COMPLETE
    GP_CAPTURE_IMAGE, GP_FILE_TYPE_NORMAL = 0, 1
    GP_LOG_ERROR, GP_LOG_VERBOSE, GP_LOG_DEBUG, GP_LOG_DATA = 0, 1, 2, 3

    def __init__(self, lang: str = "en", **camera_kw):
        self.callbacks: list = []
        self.ports = ["usb:001,007"]
        self.camera = ScriptedD610(self, lang, **camera_kw)

    def Camera(self):
        return self.camera

    def gp_log_add_func(self, level, func):
        self.callbacks.append((level, func))
        return [len(self.callbacks), object()]

    def log(self, domain: str, text: str) -> None:
        """What libgphoto2's GP_LOG_E / gp_context_error do: every callback at level >= ERROR gets the line."""
        for _level, func in self.callbacks:
            func(self.GP_LOG_ERROR, domain, text)

    def PortInfoList(self):
        return _PortList(SimpleNamespace(get_path=lambda p=p: p) for p in self.ports)


class _PortList(list):
    def load(self): pass
    def count(self): return len(self)


def open_scripted(lang: str = "en", setup: Callable[[ScriptedD610], None] | None = None, **driver_kw):
    """A GPhotoCamera opened on a ScriptedD610 (knobs set by ``setup`` before open): (camera, d610, clock, gp)."""
    from dualrgb.drivers.camera.gphoto import GPhotoCamera

    gp = FakeGPhoto2(lang)
    clock = FakeClock()
    gp.camera.clock = clock
    if setup is not None:
        setup(gp.camera)
    driver_kw.setdefault("busy_delay_s", 0.01)
    cam = GPhotoCamera(gp_module=gp, sleep=clock.sleep, clock=clock, **driver_kw)
    cam.open()
    return cam, gp.camera, clock, gp
