"""The real camera (Nikon D610 at the copy stand) through python-gphoto2 / libgphoto2.

All gphoto2 calls of the project live in this module. ``gphoto2`` is imported lazily (first detect/open), so
``import drivers.camera`` works on a machine without it, and tests can set ``VCAMERADIR`` (libgphoto2's own
virtual camera) before the first import.

* Settings are found by config name (``iso``, ``shutterspeed``/``shutterspeed2``, ``f-number``/``aperture``,
  ``imagequality``, ``capturetarget``) and numeric settings are matched by *parsed value*, never by the
  (localised) label: "30,0000s", "1/4000", "0.5", '0"3' all parse to seconds and the nearest offered value
  is picked (in stops).
* ``expose(exposure_s)`` returns when the shutter has closed (libgphoto2's capture, which returns once the
  camera has stored the frame; for bulb, as soon as ``bulb`` is 0 again) and ``fetch()`` then waits for the file
  if need be and downloads it into memory, so the light can be off during the download; ``capture()`` does both.
  Exposures longer than the longest timed speed (30 s on the D610) use bulb: shutter 'Bulb', ``bulb``=1, wait,
  ``bulb``=0; FILE_ADDED is waited for in ``fetch()``. The bulb is always released again, even when the wait is
  interrupted.
* Every libgphoto2 call has a host-side deadline (:func:`drivers.camera.base.call_with_deadline`): a call that
  hangs becomes a one-line CameraError after ``call_timeout_s`` (capture: the exposure plus
  ``capture_timeout_s``; download: ``download_timeout_s``), and the camera refuses further calls until the hung
  one has returned (it is never entered twice).
* libgphoto2 errors become :class:`CameraError` with a one-line, actionable message and the libgphoto2 code;
  'camera busy' (-110) is retried a bounded number of times with backoff.
"""
from __future__ import annotations

import logging
import math
import re
import threading
import time
from dataclasses import dataclass, field
from io import BytesIO
from typing import Any, Callable, Iterable, Optional, Sequence, TypeVar

import numpy as np

from drivers.camera.base import (Camera, CameraError, CameraSettings, CameraTimeout, Exposure, RawCapture,
                                 call_with_deadline)

log = logging.getLogger(__name__)

T = TypeVar("T")

# libgphoto2 result codes (gphoto2.GP_ERROR_*), spelled out so the mapper works without importing gphoto2
GP_ERROR = -1
GP_ERROR_BAD_PARAMETERS = -2
GP_ERROR_NOT_SUPPORTED = -6
GP_ERROR_IO = -7
GP_ERROR_TIMEOUT = -10
GP_ERROR_IO_USB_FIND = -52
GP_ERROR_IO_USB_CLAIM = -53
GP_ERROR_IO_LOCK = -60
GP_ERROR_MODEL_NOT_FOUND = -105
GP_ERROR_FILE_NOT_FOUND = -108
GP_ERROR_CAMERA_BUSY = -110
GP_ERROR_CANCEL = -112
GP_ERROR_CAMERA_ERROR = -113
GP_ERROR_NO_SPACE = -115

GVFS_ADVICE = ("run `gio mount -s gphoto2` and `pkill -f gvfs-gphoto2-volume-monitor` "
               "(and close other photo programs), then retry")

ERROR_ADVICE: dict[int, str] = {
    GP_ERROR_MODEL_NOT_FOUND: "no camera found: connect the camera by USB and switch it on",
    GP_ERROR_IO_USB_CLAIM: ("the camera's USB interface is claimed by another program, usually the desktop's "
                            "gvfs-gphoto2-volume-monitor: " + GVFS_ADVICE),
    GP_ERROR_IO_LOCK: "another program holds the camera's USB device: " + GVFS_ADVICE,
    GP_ERROR_CAMERA_BUSY: ("the camera is busy (I/O in progress): let it finish writing, leave its menus and "
                           "playback, then retry"),
    GP_ERROR_IO_USB_FIND: ("the camera is no longer on its USB port (unplugged, or re-enumerated after "
                           "sleeping): reconnect it and reopen the camera"),
    GP_ERROR_TIMEOUT: ("the camera did not answer in time: check the USB cable, wake the camera "
                       "(half-press the shutter release) and retry"),
    GP_ERROR_NOT_SUPPORTED: ("not supported by this camera in its current mode (set the mode dial to M and "
                             "check the camera's USB/PTP setting)"),
    GP_ERROR_IO: ("USB I/O error talking to the camera: check the cable (avoid hubs), then reconnect and "
                  "reopen the camera"),
    GP_ERROR_BAD_PARAMETERS: "the camera rejected the request (setting missing or value not allowed)",
    GP_ERROR_FILE_NOT_FOUND: "the file is not on the camera (any more)",
    GP_ERROR_NO_SPACE: "the camera's memory is full: free space on the card or capture to Internal RAM",
    GP_ERROR_CAMERA_ERROR: "the camera reported an error: check its display (lens, card, battery, mode dial)",
    GP_ERROR_CANCEL: "cancelled",
}

# Name -> libgphoto2 widget type (gphoto2.GP_WIDGET_*)
WIDGET_KINDS = {0: "window", 1: "section", 2: "text", 3: "range", 4: "toggle", 5: "radio", 6: "menu",
                7: "button", 8: "date"}
_CHOICE_KINDS = ("radio", "menu")

# Config names, most preferred first (Nikon PTP names; Canon/others where they differ)
ISO_NAMES = ("iso", "isospeed")
SHUTTER_NAMES = ("shutterspeed", "shutterspeed2", "exptime")
APERTURE_NAMES = ("f-number", "aperture")
QUALITY_NAMES = ("imagequality", "imageformat")
TARGET_NAMES = ("capturetarget",)

RAW_QUALITY = "NEF (Raw)"
BULB_LIMIT_S = 30.0          # the D610's longest timed speed; longer exposures use bulb
SNAP_WARN_STOPS = 1.0 / 6.0  # warn when the offered speed/aperture is further than this from the request


def gphoto_error_code(exc: BaseException) -> Optional[int]:
    code = getattr(exc, "code", None)
    return int(code) if isinstance(code, int) else None


def camera_error(exc: BaseException, action: str) -> CameraError:
    """A one-line :class:`CameraError` for a libgphoto2 error (anything with an int ``code``), keeping the code.

    ``action`` says what was being done ("open camera", "set shutterspeed", ...).
    """
    code = gphoto_error_code(exc)
    detail = getattr(exc, "string", None) or str(exc)
    detail = " ".join(str(detail).split())
    advice = ERROR_ADVICE.get(code) if code is not None else None
    if advice is None:
        advice = f"camera error: {detail}" if detail else "camera error"
    msg = f"{action}: {advice} [gphoto2 {code}]" if code is not None else f"{action}: {advice}"
    return CameraError(msg, code)


def retry_busy(fn: Callable[[], T], action: str, *, error_type: type = Exception, tries: int = 3,
               delay_s: float = 0.5, sleep: Callable[[float], None] = time.sleep) -> T:
    """Call ``fn``; retry on 'camera busy' (-110) up to ``tries`` times with doubling delay, map errors.

    Only exceptions of ``error_type`` that carry a libgphoto2 code are mapped to :class:`CameraError`.
    """
    for attempt in range(1, tries + 1):
        try:
            return fn()
        except error_type as exc:
            code = gphoto_error_code(exc)
            if code is None:
                raise
            if code == GP_ERROR_CAMERA_BUSY and attempt < tries:
                wait = delay_s * 2 ** (attempt - 1)
                log.info("%s: camera busy, retry %d/%d in %.1f s", action, attempt, tries - 1, wait)
                sleep(wait)
                continue
            raise camera_error(exc, action) from exc
    raise AssertionError("unreachable")  # pragma: no cover


# ---------------------------------------------------------------------------------------------- parsing
_NUM = r"(\d+(?:[.,]\d*)?|[.,]\d+)"
_UNIT = r"\s*(?:s|sec|secs|second|seconds)?\.?"


def _num(s: str) -> float:
    return float(s.replace(",", "."))


def parse_shutter(text: object) -> Optional[float]:
    """Exposure time in seconds from a shutter-speed label, or None for Bulb/Time/auto/flash-sync/unknown.

    Handles libgphoto2's localised "30,0000s" / "0.0100s", Nikon shutterspeed2 "1/4000", "30", "10/13",
    Canon '0"3' / '30"' and plain numbers.
    """
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return float(text) if text > 0 else None
    s = str(text).strip().lower()
    if not s:
        return None
    m = re.fullmatch(_NUM + r"\s*/\s*" + _NUM + _UNIT, s)
    if m:
        den = _num(m.group(2))
        value = _num(m.group(1)) / den if den > 0 else 0.0
        return value if value > 0 else None
    m = re.fullmatch(r'(\d+)"(\d+)?', s)  # Canon: 0"3 = 0.3 s, 30" = 30 s
    if m:
        value = float(f"{m.group(1)}.{m.group(2) or 0}")
        return value if value > 0 else None
    m = re.fullmatch(_NUM + _UNIT, s)
    if m:
        value = _num(m.group(1))
        return value if value > 0 else None
    return None


def is_bulb_label(text: object) -> bool:
    return str(text).strip().lower() in ("bulb", "b")


def parse_aperture(text: object) -> Optional[float]:
    """f-number from "f/5.6", "f5,6", "5.6"; None for anything else (e.g. a lens without aperture contact)."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return float(text) if text > 0 else None
    m = re.fullmatch(r"(?:f\s*/?\s*)?" + _NUM, str(text).strip().lower())
    if not m:
        return None
    value = _num(m.group(1))
    return value if value > 0 else None


def parse_iso(text: object) -> Optional[int]:
    """ISO number from "100", "ISO 100"; None for 'Auto', 'Hi 1', 'Lo 1' and other labels."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return int(text) if text > 0 else None
    m = re.fullmatch(r"(?:iso\s*)?(\d+)", str(text).strip().lower())
    return int(m.group(1)) if m and int(m.group(1)) > 0 else None


def nearest_by_value(target: float, options: Sequence[tuple[float, T]]) -> tuple[float, T]:
    """The (value, label) nearest to ``target`` in log space (stops), ties to the first offered."""
    if not options:
        raise ValueError("no values to choose from")
    return min(options, key=lambda o: abs(math.log(o[0] / target)))


def format_shutter(seconds: Optional[float]) -> str:
    if seconds is None:
        return "bulb"
    if seconds >= 1 or seconds <= 0:
        return f"{seconds:g} s"
    inv = 1.0 / seconds
    return f"1/{inv:.0f} s" if abs(inv - round(inv)) < 0.05 * inv else f"{seconds:.4g} s"


# ------------------------------------------------------------------------------------------ config view
@dataclass
class ConfigEntry:
    """One leaf of the camera's configuration tree, for display and for setting values."""

    name: str
    label: str
    kind: str                           # 'text', 'range', 'toggle', 'radio', 'menu', 'button', 'date'
    value: Any
    readonly: bool = False
    choices: list[str] = field(default_factory=list)
    range: Optional[tuple[float, float, float]] = None   # (min, max, step) for 'range'


def _import_gphoto():
    try:
        import gphoto2
    except ImportError as exc:
        raise CameraError("python-gphoto2 is not installed: pip install gphoto2 (it bundles libgphoto2)") from exc
    return gphoto2


_gp_log_callbacks: list = []


def _route_gphoto_logging(gp) -> None:
    """Send libgphoto2's own log to Python logging at DEBUG (only when debug logging is on; once)."""
    if _gp_log_callbacks or not logging.getLogger("gphoto2").isEnabledFor(logging.DEBUG):
        return
    levels = {gp.GP_LOG_ERROR: logging.DEBUG, gp.GP_LOG_VERBOSE: logging.DEBUG,
              gp.GP_LOG_DEBUG: logging.DEBUG, gp.GP_LOG_DATA: logging.DEBUG}
    _gp_log_callbacks.append(gp.use_python_logging(mapping=levels))


class GPhotoCamera(Camera):
    """A camera driven through libgphoto2 (PTP over USB).

    ``model``/``port`` pick one of :meth:`detect`'s results (default: the first camera found).
    ``bulb_limit_s``: exposures longer than this (and than the longest timed speed) use bulb.
    ``file_timeout_s``: extra time allowed after a bulb exposure for the file to appear (long-exposure
    noise reduction takes as long again as the exposure, which is added on top).
    ``delete_from_card``: delete each file from the camera after download (only matters when capturing
    to the memory card; Internal RAM files are gone after download anyway).
    ``call_timeout_s``, ``capture_timeout_s`` (beyond the exposure), ``download_timeout_s``: host-side deadlines.
    ``gp_module``, ``sleep``, ``clock``: stand-ins for gphoto2, time.sleep and time.monotonic (tests).
    """

    name = "gphoto2"

    def __init__(self, model: Optional[str] = None, port: Optional[str] = None, *,
                 bulb_limit_s: float = BULB_LIMIT_S, file_timeout_s: float = 60.0,
                 busy_tries: int = 3, busy_delay_s: float = 0.5, delete_from_card: bool = False,
                 call_timeout_s: float = 20.0, capture_timeout_s: float = 30.0, download_timeout_s: float = 120.0,
                 gp_module: Any = None, sleep: Optional[Callable[[float], None]] = None,
                 clock: Callable[[], float] = time.monotonic):
        self.model = model                  # after open(): the model libgphoto2 reports
        self.port = port
        self._requested_model = model       # what open() asks for (reopen() asks the same again)
        self.bulb_limit_s = bulb_limit_s
        self.file_timeout_s = file_timeout_s
        self.busy_tries = busy_tries
        self.busy_delay_s = busy_delay_s
        self.delete_from_card = delete_from_card
        self.call_timeout_s = call_timeout_s
        self.capture_timeout_s = capture_timeout_s
        self.download_timeout_s = download_timeout_s
        self._stuck: Optional[tuple[str, threading.Thread, float]] = None    # a call that passed its deadline
        self._gp = gp_module
        self._abort_event = threading.Event()
        self._sleep = sleep if sleep is not None else self._abort_event.wait  # abort() ends a bulb wait early
        self._clock = clock
        self._cam: Any = None
        self._names: dict[str, str] = {}        # config name -> widget kind
        self._lock = threading.RLock()
        self._bulb_exposure_s: Optional[float] = None
        self._live_view = False

    # ------------------------------------------------------------------------------ discovery and life
    @staticmethod
    def detect(gp_module: Any = None) -> list[tuple[str, str]]:
        """(model, port) of every camera libgphoto2 can see, e.g. [('Nikon DSC D610', 'usb:001,007')]."""
        gp = gp_module or _import_gphoto()
        try:
            cameras = gp.Camera.autodetect()
        except gp.GPhoto2Error as exc:
            raise camera_error(exc, "detect cameras") from exc
        return [(cameras.get_name(i), cameras.get_value(i)) for i in range(cameras.count())]

    @property
    def is_open(self) -> bool:
        return self._cam is not None

    def _gp_module(self):
        if self._gp is None:
            self._gp = _import_gphoto()
        return self._gp

    def _call(self, action: str, fn: Callable[..., T], *args: Any, deadline_s: Optional[float] = None) -> T:
        """One libgphoto2 call: busy retries, error mapping, and a host-side deadline (default call_timeout_s)."""
        gp = self._gp_module()
        deadline = self.call_timeout_s if deadline_s is None else deadline_s

        def attempt() -> T:
            self._check_not_stuck()
            try:
                return call_with_deadline(lambda: fn(*args), deadline, action)
            except CameraTimeout as exc:
                self._stuck = (action, exc.worker, self._clock())
                raise
        with self._lock:
            return retry_busy(attempt, action, error_type=gp.GPhoto2Error, tries=self.busy_tries,
                              delay_s=self.busy_delay_s, sleep=self._sleep)

    def _check_not_stuck(self) -> None:
        """libgphoto2 is not re-entrant: while a call that passed its deadline is still inside, refuse."""
        if self._stuck is None:
            return
        action, worker, since = self._stuck
        if worker is not None and worker.is_alive():
            raise CameraError(f"the camera has not finished '{action}' ({self._clock() - since:.0f} s ago): switch "
                              "it off and on, then reconnect it", GP_ERROR_TIMEOUT)
        self._stuck = None

    def _require_open(self):
        if self._cam is None:
            raise CameraError("the camera is not open: call open() first (or use it as a context manager)")
        return self._cam

    def open(self) -> None:
        if self._cam is not None:
            return
        gp = self._gp_module()
        _route_gphoto_logging(gp)
        cam = gp.Camera()
        where = f" on {self.port}" if self.port else ""
        if self.port:
            ports = gp.PortInfoList()
            ports.load()
            # look the path up by hand: PortInfoList.lookup_path on a missing path is not safe with every
            # port driver (the virtual camera's crashed the interpreter here)
            match = [ports[i] for i in range(ports.count()) if ports[i].get_path() == self.port]
            if not match:
                raise CameraError(f"open camera: no USB/serial port {self.port} (the camera was unplugged or "
                                  "re-enumerated): run `dualrgb devices` and reopen", GP_ERROR_IO_USB_FIND)
            cam.set_port_info(match[0])
        if self._requested_model:
            abilities = gp.CameraAbilitiesList()
            abilities.load()
            try:
                cam.set_abilities(abilities[abilities.lookup_model(self._requested_model)])
            except gp.GPhoto2Error as exc:
                raise camera_error(exc, f"open camera {self._requested_model}") from exc
        self._call(f"open camera{where}", cam.init)
        self._cam = cam
        try:
            self.model = cam.get_abilities().model or self.model
            self._names = {e.name: e.kind for e in self._walk_config(self._call("read configuration",
                                                                               cam.get_config))}
        except CameraError:
            self.close()
            raise
        log.info("opened %s%s (%d config entries)", self.model, where, len(self._names))

    def close(self) -> None:
        """End live view and free the USB device (safe to call twice)."""
        cam, self._cam = self._cam, None
        if cam is None:
            return
        gp = self._gp_module()
        with self._lock:
            if self._live_view and "viewfinder" in self._names:
                try:
                    self._set_on(cam, "viewfinder", 0)
                except (gp.GPhoto2Error, CameraError) as exc:
                    log.debug("could not end live view: %s", exc)
            self._live_view = False
            try:
                self._check_not_stuck()
                call_with_deadline(cam.exit, self.call_timeout_s, "close camera")
            except (gp.GPhoto2Error, CameraError) as exc:
                log.warning("camera exit: %s", exc)
        log.info("closed %s", self.model)

    release = close  # 'release the camera' = give the USB device back to the system

    def reopen(self) -> None:
        """Close and open again: the way back after -52 (the camera re-enumerated on USB after sleeping)."""
        self.close()
        self.open()

    def abort(self) -> None:
        """End a running bulb exposure early (safe to call from another thread); capture() then raises."""
        self._abort_event.set()

    # ---------------------------------------------------------------------------------- configuration
    def _walk_config(self, widget: Any) -> list[ConfigEntry]:
        gp = self._gp_module()
        out: list[ConfigEntry] = []
        stack = [widget]
        while stack:
            w = stack.pop(0)
            kind = WIDGET_KINDS.get(w.get_type(), str(w.get_type()))
            if kind in ("window", "section"):
                stack[:0] = [w.get_child(i) for i in range(w.count_children())]
                continue
            try:
                value = w.get_value()
            except gp.GPhoto2Error:
                value = None
            entry = ConfigEntry(name=w.get_name(), label=w.get_label(), kind=kind, value=value,
                                readonly=bool(w.get_readonly()))
            if kind in _CHOICE_KINDS:
                entry.choices = [w.get_choice(i) for i in range(w.count_choices())]
            elif kind == "range":
                entry.range = tuple(float(x) for x in w.get_range())
            out.append(entry)
        return out

    def list_config(self) -> dict[str, ConfigEntry]:
        """Every configuration leaf by name (value, choices, read-only flag) as the camera reports it now."""
        cam = self._require_open()
        entries = self._walk_config(self._call("read configuration", cam.get_config))
        return {e.name: e for e in entries}

    def _first_name(self, names: Iterable[str]) -> Optional[str]:
        return next((n for n in names if n in self._names), None)

    def _entry(self, name: str) -> ConfigEntry:
        cam = self._require_open()
        w = self._call(f"read {name}", cam.get_single_config, name)
        return self._walk_config(w)[0]

    def get_config_value(self, name: str) -> Any:
        if name not in self._names:
            raise CameraError(f"this camera has no '{name}' setting", GP_ERROR_NOT_SUPPORTED)
        return self._entry(name).value

    def set_config_value(self, name: str, value: Any) -> Any:
        """Set one configuration leaf by name; a choice must be one offered (compared case-insensitively).

        Returns the value read back from the camera.
        """
        cam = self._require_open()
        if name not in self._names:
            raise CameraError(f"this camera has no '{name}' setting", GP_ERROR_NOT_SUPPORTED)
        gp = self._gp_module()
        w = self._call(f"read {name}", cam.get_single_config, name)
        entry = self._walk_config(w)[0]
        if entry.readonly:
            raise CameraError(f"set {name}: read-only on this camera now (set the mode dial to M, or change "
                              "it on the camera body)", GP_ERROR_NOT_SUPPORTED)
        if entry.kind in _CHOICE_KINDS:
            wanted = str(value).strip().lower()
            match = next((c for c in entry.choices if c.strip().lower() == wanted), None)
            if match is None:
                shown = ", ".join(entry.choices[:12]) + (" ..." if len(entry.choices) > 12 else "")
                raise CameraError(f"set {name}: {value!r} is not offered; the camera offers {shown}",
                                  GP_ERROR_BAD_PARAMETERS)
            value = match
        elif entry.kind == "toggle":
            value = int(bool(value))
        elif entry.kind == "range":
            value = float(value)
        elif entry.kind == "date":
            value = int(value)
        else:
            value = str(value)
        try:
            w.set_value(value)
        except gp.GPhoto2Error as exc:
            raise camera_error(exc, f"set {name} to {value!r}") from exc
        self._call(f"set {name} to {value!r}", cam.set_single_config, name, w)
        log.debug("set %s = %r", name, value)
        return self._entry(name).value

    def _set_on(self, cam: Any, name: str, value: Any) -> None:
        w = self._call(f"read {name}", cam.get_single_config, name)
        w.set_value(value)
        self._call(f"set {name} to {value!r}", cam.set_single_config, name, w)

    # ------------------------------------------------------------------------------------- settings
    def _shutter_entry(self) -> Optional[ConfigEntry]:
        """The first shutter-speed setting that offers parsable speeds (Nikon: shutterspeed, shutterspeed2)."""
        for name in SHUTTER_NAMES:
            if name in self._names and self._names[name] in _CHOICE_KINDS:
                entry = self._entry(name)
                if any(parse_shutter(c) for c in entry.choices):
                    return entry
        return None

    def _shutter_options(self, entry: ConfigEntry) -> list[tuple[float, str]]:
        opts = [(parse_shutter(c), c) for c in entry.choices]
        return sorted((v, c) for v, c in opts if v is not None)

    def shutter_speeds(self) -> list[float]:
        self._require_open()
        entry = self._shutter_entry()
        return [] if entry is None else [v for v, _ in self._shutter_options(entry)]

    def settings(self) -> CameraSettings:
        self._require_open()
        s = CameraSettings()
        name = self._first_name(ISO_NAMES)
        if name:
            s.iso = parse_iso(self._entry(name).value)
        entry = self._shutter_entry()
        if entry is not None:
            if is_bulb_label(entry.value):
                s.shutter_s = self._bulb_exposure_s
            else:
                s.shutter_s = parse_shutter(entry.value)
        name = self._first_name(APERTURE_NAMES)
        if name:
            s.aperture = parse_aperture(self._entry(name).value)
        name = self._first_name(QUALITY_NAMES)
        if name:
            s.image_quality = self._entry(name).value
        name = self._first_name(TARGET_NAMES)
        if name:
            s.capture_target = self._entry(name).value
        return s

    def _needs_bulb(self, exposure_s: float, options: list[tuple[float, str]]) -> bool:
        longest = options[-1][0] if options else 0.0
        # beyond the longest timed speed by more than a third of a stop: a timed speed would be wrong
        return exposure_s > self.bulb_limit_s and exposure_s > longest * 2 ** (1 / 3)

    def _set_shutter(self, exposure_s: float) -> tuple[float, bool]:
        """Set the shutter for ``exposure_s``; returns (exposure the camera will give, uses bulb)."""
        if not exposure_s or exposure_s <= 0:
            raise CameraError(f"exposure must be a positive number of seconds, got {exposure_s!r}")
        entry = self._shutter_entry()
        if entry is None:
            raise CameraError("this camera offers no shutter-speed setting over USB (set the mode dial to M)",
                              GP_ERROR_NOT_SUPPORTED)
        options = self._shutter_options(entry)
        if self._needs_bulb(exposure_s, options):
            bulb = next((c for c in entry.choices if is_bulb_label(c)), None)
            if bulb is None or "bulb" not in self._names:
                raise CameraError(f"set shutter: {format_shutter(exposure_s)} is longer than the longest speed "
                                  f"{format_shutter(options[-1][0])} and this camera offers no bulb over USB "
                                  "(mode dial to M, shutter to Bulb)", GP_ERROR_NOT_SUPPORTED)
            if entry.value != bulb:
                self.set_config_value(entry.name, bulb)
            self._bulb_exposure_s = exposure_s
            return exposure_s, True
        value, label = nearest_by_value(exposure_s, options)
        stops = abs(math.log2(value / exposure_s))
        if stops > SNAP_WARN_STOPS:
            log.warning("shutter %s not offered; using %s (%.2f stops off)", format_shutter(exposure_s),
                        label, stops)
        if entry.value != label:
            self.set_config_value(entry.name, label)
        self._bulb_exposure_s = None
        return value, False

    def apply(self, settings: CameraSettings) -> CameraSettings:
        self._require_open()
        with self._lock:
            if settings.image_quality is not None:
                name = self._first_name(QUALITY_NAMES)
                if name is None:
                    raise CameraError("this camera has no image-quality setting over USB", GP_ERROR_NOT_SUPPORTED)
                self.set_config_value(name, settings.image_quality)
            if settings.capture_target is not None:
                name = self._first_name(TARGET_NAMES)
                if name is None:
                    raise CameraError("this camera has no capture-target setting", GP_ERROR_NOT_SUPPORTED)
                self.set_config_value(name, settings.capture_target)
            if settings.iso is not None:
                name = self._first_name(ISO_NAMES)
                if name is None:
                    raise CameraError("this camera has no ISO setting over USB", GP_ERROR_NOT_SUPPORTED)
                entry = self._entry(name)
                options = [(float(v), c) for v, c in ((parse_iso(c), c) for c in entry.choices) if v]
                if not options:
                    raise CameraError(f"set ISO: the camera offers no numeric ISO ({entry.choices[:6]})",
                                      GP_ERROR_NOT_SUPPORTED)
                value, label = nearest_by_value(float(settings.iso), options)
                if value != settings.iso:
                    log.warning("ISO %s not offered; using %s", settings.iso, label)
                self.set_config_value(name, label)
            if settings.aperture is not None:
                name = self._first_name(APERTURE_NAMES)
                if name is None:
                    raise CameraError("this camera has no aperture setting over USB (manual lens?)",
                                      GP_ERROR_NOT_SUPPORTED)
                entry = self._entry(name)
                options = [(v, c) for v, c in ((parse_aperture(c), c) for c in entry.choices) if v]
                if not options:
                    raise CameraError(f"set aperture: the camera offers no f-numbers ({entry.choices[:6]}); "
                                      "a manual lens is set on the lens", GP_ERROR_NOT_SUPPORTED)
                value, label = nearest_by_value(float(settings.aperture), options)
                if abs(math.log2(value / settings.aperture)) > SNAP_WARN_STOPS:
                    log.warning("aperture f/%g not offered; using %s", settings.aperture, label)
                self.set_config_value(name, label)
            if settings.shutter_s is not None:
                self._set_shutter(float(settings.shutter_s))
            return self.settings()

    def config_summary(self) -> dict[str, object]:
        out: dict[str, object] = {"camera": self.model or "", "port": self.port or ""}
        out.update(super().config_summary())
        if "batterylevel" in self._names:
            out["battery"] = self.get_config_value("batterylevel")
        return out

    # -------------------------------------------------------------------------------------- capture
    def _drain_events(self, max_events: int = 50) -> list[tuple[str, str]]:
        """Read queued events without waiting; returns files that were added meanwhile."""
        cam = self._require_open()
        gp = self._gp_module()
        added = []
        for _ in range(max_events):
            kind, data = self._call("read camera events", cam.wait_for_event, 10)
            if kind == gp.GP_EVENT_TIMEOUT:
                break
            if kind == gp.GP_EVENT_FILE_ADDED:
                added.append((data.folder, data.name))
        return added

    def _wait_for_file(self, timeout_s: float) -> tuple[str, str]:
        cam = self._require_open()
        gp = self._gp_module()
        deadline = self._clock() + timeout_s
        while True:
            left = deadline - self._clock()
            if left <= 0:
                raise CameraError(f"capture: no file arrived within {timeout_s:.0f} s after the exposure ended "
                                  "(check the card/Internal RAM and the camera display)", GP_ERROR_TIMEOUT)
            kind, data = self._call("wait for the captured file", cam.wait_for_event,
                                    int(min(left, 1.0) * 1000) or 1, deadline_s=min(left, 1.0) + self.call_timeout_s)
            if kind == gp.GP_EVENT_FILE_ADDED:
                return data.folder, data.name

    def _bulb_exposure(self, exposure_s: float) -> None:
        cam = self._require_open()
        gp = self._gp_module()
        self._drain_events()
        self._abort_event.clear()
        opened = False
        started = self._clock()
        try:
            self._set_on(cam, "bulb", 1)
            opened = True
            log.info("bulb open for %s", format_shutter(exposure_s))
            self._sleep(exposure_s)
        finally:
            # always close the shutter again, also when opening failed half-way or the wait was interrupted
            try:
                self._set_on(cam, "bulb", 0)
            except (CameraError, gp.GPhoto2Error) as exc:
                if opened:
                    raise CameraError("bulb could not be ended: the shutter may still be open; switch the "
                                      f"camera off and on ({exc})", gphoto_error_code(exc)) from exc
                log.debug("releasing bulb after a failed start: %s", exc)
        if self._abort_event.is_set():
            self._abort_event.clear()
            raise CameraError(f"capture: bulb exposure aborted after {self._clock() - started:.0f} s of "
                              f"{exposure_s:g} s (the camera may still store the short frame)", GP_ERROR_CANCEL)

    def expose(self, exposure_s: Optional[float] = None) -> Exposure:
        """The exposure, returning once the shutter has closed; the file is fetched by :meth:`fetch`."""
        cam = self._require_open()
        gp = self._gp_module()
        with self._lock:
            if exposure_s is not None:
                actual, bulb = self._set_shutter(float(exposure_s))
            else:
                current = self.settings().shutter_s
                entry = self._shutter_entry()
                bulb = entry is not None and is_bulb_label(entry.value)
                if bulb and self._bulb_exposure_s is None:
                    raise CameraError("capture: the shutter is on Bulb but no exposure time was given")
                actual = self._bulb_exposure_s if bulb else current
            started = self._clock()
            if bulb:
                self._bulb_exposure(float(actual))
                handle = None                   # the file is announced (FILE_ADDED) after the shutter closed
            else:
                path = self._call("capture", cam.capture, gp.GP_CAPTURE_IMAGE,
                                  deadline_s=float(actual or 0.0) + self.capture_timeout_s)
                handle = (path.folder, path.name)
            return Exposure(exposure_s=float(actual) if actual else 0.0, started=started, ended=self._clock(),
                            bulb=bulb, handle=handle)

    def fetch(self, exposure: Exposure) -> RawCapture:
        """Wait for the exposure's file if the camera has not announced it yet (bulb), then download it."""
        cam = self._require_open()
        actual, bulb = exposure.exposure_s, exposure.bulb
        with self._lock:
            if exposure.handle is None:
                folder, name = self._wait_for_file(self.file_timeout_s + actual)
            else:
                folder, name = exposure.handle
            extra_files = self._drain_events()
            extra_files = [f for f in extra_files if f != (folder, name)]
            if extra_files:
                log.warning("the camera also stored %s (set image quality to %s only)",
                            ", ".join(n for _, n in extra_files), RAW_QUALITY)
            data, mime = self.download(folder, name)
            if self.delete_from_card:
                try:
                    self._call(f"delete {name} from the camera", cam.file_delete, folder, name)
                except CameraError as exc:
                    log.warning("%s", exc)
            s = self.settings()
        log.info("captured %s (%d bytes, %s)", name, len(data), format_shutter(actual))
        return RawCapture(data=data, filename=name, exposure_s=float(actual) if actual else 0.0, iso=s.iso,
                          aperture=s.aperture, camera=self.model or "",
                          extra={"folder": folder, "mime": mime, "bulb": bulb,
                                 "extra_files": [f"{f}/{n}" for f, n in extra_files]})

    def download(self, folder: str, name: str) -> tuple[bytes, str]:
        """One file from the camera into memory: (bytes, MIME type)."""
        cam = self._require_open()
        gp = self._gp_module()
        cfile = self._call(f"download {folder}/{name}", cam.file_get, folder, name, gp.GP_FILE_TYPE_NORMAL,
                           deadline_s=self.download_timeout_s)
        data = bytes(memoryview(cfile.get_data_and_size()))
        return data, cfile.get_mime_type()

    def list_files(self, folder: str = "/") -> list[str]:
        """Paths of every file on the camera below ``folder``."""
        cam = self._require_open()
        out: list[str] = []
        stack = [folder]
        while stack:
            f = stack.pop(0)
            files = self._call(f"list {f}", cam.folder_list_files, f)
            out += [f.rstrip("/") + "/" + files.get_name(i) for i in range(files.count())]
            sub = self._call(f"list {f}", cam.folder_list_folders, f)
            stack += [f.rstrip("/") + "/" + sub.get_name(i) for i in range(sub.count())]
        return out

    def preview(self) -> np.ndarray:
        cam = self._require_open()
        from PIL import Image, UnidentifiedImageError

        cfile = self._call("live view", cam.capture_preview)
        self._live_view = True
        data = bytes(memoryview(cfile.get_data_and_size()))
        try:
            with Image.open(BytesIO(data)) as img:
                return np.asarray(img.convert("RGB"), dtype=np.uint8)
        except (UnidentifiedImageError, OSError) as exc:
            raise CameraError(f"live view: the camera sent {len(data)} bytes that are not a JPEG ({exc})") from exc
