"""The real camera (Nikon D610 at the copy stand) through python-gphoto2 / libgphoto2.

All gphoto2 calls of the project live in this module and its helpers (``gphoto_errors``: error messages with
libgphoto2's own logged reason; ``gphoto_labels``: what labels mean, in any language; ``gphoto_settings``: the
configuration tree and the copy stand's settings; ``gphoto_files``: events, the raw file of a capture,
downloads). ``gphoto2`` is imported lazily (first detect/open), so ``import drivers.camera`` works without it,
and tests can set ``VCAMERADIR`` (libgphoto2's virtual camera) first.

The light is on only while a frame is exposed, so :meth:`GPhotoCamera.expose` returns as close to the shutter
closing as libgphoto2 allows (libgphoto2's ``capture()`` returns only after the camera has stored the file and,
for Internal RAM, after the whole download; references: libgphoto2 camlibs/ptp2/library.c, ``camera_nikon_capture``
and ``camera_trigger_capture``):

* timed exposures: ``trigger_capture``; on a Nikon (libgphoto2's "Nikon Capture" path) it returns once the camera
  no longer reports busy, i.e. after the exposure, and events are not read with the light on (reading the
  Internal-RAM "file added" event downloads the file); other cameras report CAPTURE_COMPLETE or FILE_ADDED,
  waited for, keeping any file path for :meth:`fetch`;
* bulb (longer than 30 s): ``bulb``=1, wait, ``bulb``=0 once. libgphoto2's release sends TerminateCapture and then
  waits up to 5 s for the camera; :meth:`expose` returns ``bulb_release_grace_s`` after the release was sent and
  leaves that wait running (the next call waits for it). -110 or -1 (Nikon 0xA200 'Bulb Release Busy') after the
  release means "closed, still processing"; only a failed TerminateCapture means the shutter may be open. Live
  view is switched off before, and the timed speed restored before live view starts again (the camera refuses
  live view on Bulb) or the camera is closed.

:meth:`fetch` (light off by then) waits for the raw file (.nef among the files announced, NEF+JPEG pairs drained),
downloads it into memory and records the exact exposure (``shutterspeed2``), auto ISO and long-exposure noise
reduction state in the frame's metadata. :attr:`GPhotoCamera.latency_s` is the light's allowance beyond the
exposure: ``DEFAULT_GPHOTO_LATENCY_S`` or ``$DUALRGB_GPHOTO_LATENCY_S``, measured with
``python -m dualrgb.drivers.camera.gphoto_latency`` (docs/first-session-d610.md).

Every libgphoto2 call has a host-side deadline (:func:`drivers.camera.base.call_with_deadline`) and the camera is
never entered twice; 'camera busy' (-110) is retried a bounded number of times with backoff.
"""
from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from io import BytesIO
from typing import Any, TypeVar

import numpy as np

from dualrgb.drivers.camera.base import Camera, CameraError, CameraTimeout, Exposure, RawCapture, call_with_deadline
from dualrgb.drivers.camera.gphoto_errors import (
    GP_ERROR,
    GP_ERROR_CAMERA_BUSY,
    GP_ERROR_CANCEL,
    GP_ERROR_IO_USB_FIND,
    GP_ERROR_NOT_SUPPORTED,
    GP_ERROR_TIMEOUT,
    LibraryLog,
    camera_error,
    gphoto_error_code,
    retry_busy,
)

# re-exported: the error callers match (e.g. the GUI's advice on a camera another program holds)
from dualrgb.drivers.camera.gphoto_errors import GP_ERROR_IO_USB_CLAIM as GP_ERROR_IO_USB_CLAIM
from dualrgb.drivers.camera.gphoto_files import CapturedFiles, GPhotoFiles
from dualrgb.drivers.camera.gphoto_labels import (
    capture_target_choice,
    force_untranslated,
    format_shutter,
    is_bulb_label,
)
from dualrgb.drivers.camera.gphoto_settings import BULB_LIMIT_S, RAM_TARGET, TARGET_NAMES, GPhotoSettings

log = logging.getLogger(__name__)

T = TypeVar("T")

DEFAULT_GPHOTO_LATENCY_S = 2.0     # see GPhotoCamera: an estimate until measured on the camera
LATENCY_ENV = "DUALRGB_GPHOTO_LATENCY_S"
NR_MIN_EXPOSURE_S = 1.0            # the D610's long-exposure NR works on exposures of 1 s and longer
_NR_CLEAR = ("off", "switched off", "not offered", "")


# gphoto2 (python-gphoto2, which bundles libgphoto2) has no Windows wheels and is not installed there
# (pyproject marker): everything but tethering a real camera works without it.
TETHERING_UNAVAILABLE = ("camera tethering needs libgphoto2 (Linux/macOS: pip install gphoto2, which bundles it); "
                         "it is not installed here, so only the virtual camera is available")


def _import_gphoto():
    try:
        import gphoto2
    except ImportError as exc:
        raise CameraError(TETHERING_UNAVAILABLE) from exc
    return gphoto2


def gphoto_available() -> bool:
    """True when python-gphoto2 (libgphoto2) can be imported, i.e. a real camera can be tethered."""
    try:
        _import_gphoto()
    except CameraError:
        return False
    return True


def latency_from_env() -> float | None:
    """``$DUALRGB_GPHOTO_LATENCY_S`` (the measured allowance), or None when unset; one line when malformed."""
    text = os.environ.get(LATENCY_ENV, "").strip()
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0 < value <= 60:
        raise CameraError(f"{LATENCY_ENV}={text!r}: expected the camera's latency in seconds, 0 < s <= 60 "
                          "(measure it: python -m dualrgb.drivers.camera.gphoto_latency)")
    return value


def trigger_waits_for_exposure(summary: str, to_ram: bool) -> bool:
    """Whether libgphoto2's ``trigger_capture`` returns only after the exposure (its Nikon paths poll the camera
    until it is no longer busy): 'Nikon Capture 3' (capture to any target), or 'Nikon Capture 1/2' to RAM."""
    if "Nikon Capture 3" in summary:
        return True
    return to_ram and ("Nikon Capture 1" in summary or "Nikon Capture 2" in summary)


class PendingCall:
    """A libgphoto2 call left running on its own thread (the bulb release, whose wait for the camera goes on
    after the shutter has closed); the camera is not entered again until it has returned."""

    def __init__(self, action: str, fn: Callable[[], Any], mark: int, on_done: Callable[[PendingCall], None],
                 started: float):
        self.action, self.mark, self.on_done, self.started = action, mark, on_done, started
        self.error: BaseException | None = None
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._run, args=(fn,), name=f"camera: {action}", daemon=True)

    def _run(self, fn: Callable[[], Any]) -> None:
        try:
            fn()
        except BaseException as exc:  # noqa: BLE001 - delivered by on_done to the thread that calls the camera next
            self.error = exc
        finally:
            self.done.set()

    def start(self) -> PendingCall:
        self.thread.start()
        return self


class GPhotoCamera(GPhotoFiles, GPhotoSettings, Camera):
    """A camera driven through libgphoto2 (PTP over USB).

    ``model``/``port`` pick one of :meth:`detect`'s results (default: the first camera found).
    ``bulb_limit_s``: exposures longer than this (and than the longest timed speed) use bulb.
    ``file_timeout_s``: time allowed after an exposure for its file to appear (twice the exposure is added when
    long-exposure noise reduction could not be switched off, and for bulb). ``pair_timeout_s``: how long to wait
    for the second file of a NEF+JPEG pair (drained, never taken for the next capture's file).
    ``latency_s``: the light's allowance beyond the exposure (trigger, shutter lag, reporting the shutter closed);
    default ``$DUALRGB_GPHOTO_LATENCY_S`` or DEFAULT_GPHOTO_LATENCY_S (2 s: libgphoto2's Nikon trigger polls the
    camera every 0.1 s before and after the exposure, plus shutter lag and USB; a margin, since an allowance costs
    light only when the camera is really that slow). ``bulb_release_grace_s``: the light's time after the bulb
    release was sent (TerminateCapture is the release call's first transaction). ``trigger_waits``: override the
    detection of whether trigger_capture returns only after the exposure.
    ``delete_from_card``: delete each file from the camera after download (only matters when capturing
    to the memory card; Internal RAM files are gone after download anyway).
    ``call_timeout_s``, ``capture_timeout_s`` (beyond the exposure), ``download_timeout_s``: host-side deadlines.
    ``gp_module``, ``sleep``, ``clock``: stand-ins for gphoto2, time.sleep and time.monotonic (tests).
    """

    name = "gphoto2"

    def __init__(self, model: str | None = None, port: str | None = None, *,
                 bulb_limit_s: float = BULB_LIMIT_S, file_timeout_s: float = 60.0, pair_timeout_s: float = 5.0,
                 latency_s: float | None = None, bulb_release_grace_s: float = 0.25,
                 trigger_waits: bool | None = None,
                 busy_tries: int = 3, busy_delay_s: float = 0.5, delete_from_card: bool = False,
                 call_timeout_s: float = 20.0, capture_timeout_s: float = 30.0, download_timeout_s: float = 120.0,
                 gp_module: Any = None, sleep: Callable[[float], None] | None = None,
                 clock: Callable[[], float] = time.monotonic):
        self.model = model                  # after open(): the model libgphoto2 reports
        self.port = port
        self._requested_model = model       # what open() asks for (reopen() asks the same again)
        self.bulb_limit_s = bulb_limit_s
        self.file_timeout_s = file_timeout_s
        self.pair_timeout_s = pair_timeout_s
        self._latency_s = float(latency_s) if latency_s is not None else (latency_from_env()
                                                                          or DEFAULT_GPHOTO_LATENCY_S)
        self.bulb_release_grace_s = bulb_release_grace_s
        self.trigger_waits = trigger_waits
        self.busy_tries = busy_tries
        self.busy_delay_s = busy_delay_s
        self.delete_from_card = delete_from_card
        self.call_timeout_s = call_timeout_s
        self.capture_timeout_s = capture_timeout_s
        self.download_timeout_s = download_timeout_s
        self._stuck: tuple[str, threading.Thread | None, float] | None = None    # a call past its deadline
        self._pending: PendingCall | None = None
        self._gp = gp_module
        self._log: LibraryLog | None = None
        self._abort_event = threading.Event()
        self._sleep: Callable[[float], object] = (sleep if sleep is not None
                                                  else self._abort_event.wait)  # abort() ends a bulb wait early
        self._clock = clock
        self._cam: Any = None
        self._names: dict[str, str] = {}        # config name -> widget kind
        self._summary = ""
        self._lock = threading.RLock()
        self._bulb_exposure_s: float | None = None
        self._timed_shutter: tuple[str, str] | None = None   # (setting, label) to restore after bulb
        self._live_view = False
        self.image_quality = ""
        self.auto_iso = ""                      # what the session record says: 'switched off', 'off', ...
        self.long_exposure_nr = ""
        self.last_latency_s: float | None = None   # measured: expose() return minus trigger minus exposure

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

    @property
    def latency_s(self) -> float:
        return self._latency_s

    def latency_for(self, exposure_s: float) -> float:
        """The allowance, plus the exposure again for timed exposures of 1 s or more while long-exposure noise
        reduction may run (it could not be switched off): the camera is busy with its dark frame until then."""
        nr = self.long_exposure_nr not in _NR_CLEAR and NR_MIN_EXPOSURE_S <= exposure_s <= self.bulb_limit_s
        return self._latency_s + (float(exposure_s) if nr else 0.0)

    def _library(self) -> tuple[Any, LibraryLog]:
        """python-gphoto2 (or the stand-in given) and libgphoto2's log, both set up on first use."""
        if self._gp is None:
            self._gp = _import_gphoto()
        if self._log is None:
            force_untranslated(self._gp)
            self._log = LibraryLog.attach(self._gp)
        return self._gp, self._log

    def _gp_module(self) -> Any:
        return self._library()[0]

    def _call(self, action: str, fn: Callable[..., T], *args: Any, deadline_s: float | None = None,
              retry: bool = True, opening_port: bool = False) -> T:
        """One libgphoto2 call: busy retries, error mapping with libgphoto2's logged reason, and a host-side
        deadline (default call_timeout_s)."""
        gp, library_log = self._library()
        deadline = self.call_timeout_s if deadline_s is None else deadline_s

        def attempt() -> T:
            self._check_not_stuck()
            try:
                return call_with_deadline(lambda: fn(*args), deadline, action)
            except CameraTimeout as exc:
                self._stuck = (action, exc.worker, self._clock())
                raise

        with self._lock:
            self._finish_pending()
            mark = library_log.mark()
            return retry_busy(attempt, action, error_type=gp.GPhoto2Error, tries=self.busy_tries if retry else 1,
                              delay_s=self.busy_delay_s, sleep=self._sleep,
                              mapper=lambda exc, act: camera_error(exc, act, logged=library_log.reason(mark),
                                                                   opening_port=opening_port))

    def _check_not_stuck(self) -> None:
        """libgphoto2 is not re-entrant: while a call that passed its deadline is still inside, refuse."""
        if self._stuck is None:
            return
        action, worker, since = self._stuck
        if worker is not None and worker.is_alive():
            raise CameraError(f"the camera has not finished '{action}' ({self._clock() - since:.0f} s ago): switch "
                              "it off and on, then reconnect it", GP_ERROR_TIMEOUT)
        self._stuck = None

    def _finish_pending(self) -> None:
        """Wait for a call left running (the bulb release) and deliver its outcome (it may raise)."""
        pending, self._pending = self._pending, None
        if pending is None:
            return
        if not pending.done.wait(self.call_timeout_s):
            self._stuck = (pending.action, pending.thread, pending.started)
            self._check_not_stuck()
        pending.on_done(pending)

    def _require_open(self) -> Any:
        if self._cam is None:
            raise CameraError("the camera is not open: call open() first (or use it as a context manager)")
        return self._cam

    def open(self) -> None:
        if self._cam is not None:
            return
        gp = self._gp_module()
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
        self._call(f"open camera{where}", cam.init, opening_port=bool(self.port))
        self._cam = cam
        try:
            self.model = cam.get_abilities().model or self.model
            self._names = {e.name: e.kind for e in self._walk_config(self._call("read configuration",
                                                                               cam.get_config))}
            self._summary = str(self._call("read the camera summary", cam.get_summary))
            self._prepare_for_copy_stand()
        except CameraError:
            self.close()
            raise
        log.info("opened %s%s (%d config entries; quality %s, auto ISO %s, long-exposure NR %s)", self.model,
                 where, len(self._names), self.image_quality or "?", self.auto_iso, self.long_exposure_nr)

    def close(self) -> None:
        """Back from Bulb, end live view and free the USB device (safe to call twice)."""
        if self._cam is None:
            return
        gp = self._gp_module()
        with self._lock:
            try:
                self._finish_pending()
                self._restore_timed_shutter()
                self._end_live_view()
            except (gp.GPhoto2Error, CameraError) as exc:
                log.debug("closing: %s", exc)
            cam, self._cam = self._cam, None
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

    def config_summary(self) -> dict[str, object]:
        out: dict[str, object] = {"camera": self.model or "", "port": self.port or ""}
        out.update(super().config_summary())
        if "batterylevel" in self._names:
            out["battery"] = self.get_config_value("batterylevel")
        out.update({"auto ISO": self.auto_iso, "long-exposure NR": self.long_exposure_nr,
                    "latency allowance": f"{self.latency_s:g} s"})
        return out

    # ------------------------------------------------------------------------------------- capture
    @property
    def _trigger_waits(self) -> bool:
        if self.trigger_waits is not None:
            return self.trigger_waits
        name = self._first_name(TARGET_NAMES)     # libgphoto2 keeps it on the host: no USB traffic
        entry = self._entry(name) if name else None
        to_ram = entry is None or entry.value == capture_target_choice(entry.choices, RAM_TARGET)
        return trigger_waits_for_exposure(self._summary, to_ram)

    def expose(self, exposure_s: float | None = None) -> Exposure:
        """The exposure, returning once the shutter has closed; the file is fetched by :meth:`fetch`."""
        self._require_open()
        actual: float | None
        with self._lock:
            if exposure_s is not None:
                actual, bulb = self._set_shutter(float(exposure_s))
            else:
                actual, label, _ = self._shutter_now()
                bulb = is_bulb_label(label)
                if bulb and actual is None:
                    raise CameraError("capture: the shutter is on Bulb but no exposure time was given")
                if actual is None:
                    raise CameraError("capture: the camera's shutter speed is not a timed one; give an exposure")
            if bulb:
                return self._bulb_exposure(float(actual))
            return self._timed_exposure(float(actual))

    def _timed_exposure(self, exposure_s: float) -> Exposure:
        cam = self._require_open()
        gp = self._gp_module()
        self._check_raw_quality()
        self._discard_queued_files()
        started = self._clock()
        deadline = exposure_s + self.capture_timeout_s
        files: list[tuple[str, str]] = []
        try:
            self._call("capture", cam.trigger_capture, deadline_s=deadline)
        except CameraError as exc:
            if exc.code != GP_ERROR_NOT_SUPPORTED:
                raise
            log.info("trigger_capture is not supported: capturing with capture() (it returns after storing)")
            path = self._call("capture", cam.capture, gp.GP_CAPTURE_IMAGE, deadline_s=deadline)
            files.append((path.folder, path.name))
        else:
            if not self._trigger_waits:
                self._wait_until(lambda kind, data: self._capture_end(kind, data, files), deadline,
                                 "capture: wait for the end of the exposure",
                                 "the camera did not report the end of the exposure within {s:.0f} s")
        ended = self._clock()
        self._note_latency(ended - started - exposure_s, exposure_s)
        return Exposure(exposure_s=exposure_s, started=started, ended=ended, bulb=False, handle=CapturedFiles(files))

    def _capture_end(self, kind: int, data: Any, files: list[tuple[str, str]]) -> bool:
        gp = self._gp_module()
        if kind == gp.GP_EVENT_FILE_ADDED:
            files.append((data.folder, data.name))
            return True
        return kind == gp.GP_EVENT_CAPTURE_COMPLETE

    def _note_latency(self, latency_s: float, exposure_s: float) -> None:
        self.last_latency_s = max(0.0, latency_s)
        allowed = self.latency_for(exposure_s)
        if self.last_latency_s > allowed:
            log.warning("the camera reported the shutter closed %.2f s after a %s exposure, beyond its %.2f s "
                        "allowance (measure it: python -m dualrgb.drivers.camera.gphoto_latency; set %s)",
                        self.last_latency_s, format_shutter(exposure_s), allowed, LATENCY_ENV)

    def _check_raw_quality(self) -> None:
        """Before each capture: the image quality is still raw only (someone may have turned the camera's dial)."""
        if self.image_quality and not self.stores_pairs and self.expects_raw:
            name = self._first_name(("imagequality", "imageformat"))
            if name and self._entry(name).value == self.image_quality:
                return
        self.image_quality = self._force_raw_quality()

    def _end_live_view(self) -> None:
        if self._live_view and "viewfinder" in self._names:
            self._set_toggle("viewfinder", 0)
            log.info("live view switched off")
        self._live_view = False

    def _bulb_exposure(self, exposure_s: float) -> Exposure:
        self._end_live_view()               # the camera cannot take a bulb exposure from live view
        self._discard_queued_files()
        self._abort_event.clear()
        opened = False
        started = self._clock()
        try:
            self._set_toggle("bulb", 1)
            opened = True
            log.info("bulb open for %s", format_shutter(exposure_s))
            self._sleep(exposure_s)
        finally:
            # always close the shutter again, also when opening failed half-way or the wait was interrupted
            self._release_bulb(opened)
        ended = self._clock()
        if self._abort_event.is_set():
            self._abort_event.clear()
            raise CameraError(f"capture: bulb exposure aborted after {ended - started:.0f} s of "
                              f"{exposure_s:g} s (the camera may still store the short frame)", GP_ERROR_CANCEL)
        return Exposure(exposure_s=exposure_s, started=started, ended=ended, bulb=True, handle=CapturedFiles())

    def _release_bulb(self, opened: bool) -> None:
        """``bulb``=0, sent once. Returns ``bulb_release_grace_s`` after it was sent (the shutter closes on
        TerminateCapture, the call's first request), leaving libgphoto2's wait for the camera running."""
        cam = self._require_open()
        try:
            w = self._call("read bulb", cam.get_single_config, "bulb")
        except CameraError as exc:
            if opened:
                raise CameraError(f"bulb could not be ended: the shutter may still be open; switch the camera off "
                                  f"and on ({exc})", exc.code) from exc
            log.debug("releasing bulb after a failed start: %s", exc)
            return
        w.set_value(0)
        pending = PendingCall("release the bulb", lambda: cam.set_single_config("bulb", w), self._library()[1].mark(),
                              lambda p: self._release_outcome(p, opened), self._clock()).start()
        if pending.done.wait(self.bulb_release_grace_s if opened else self.call_timeout_s):
            self._release_outcome(pending, opened)
        else:
            self._pending = pending

    def _release_outcome(self, pending: PendingCall, opened: bool) -> None:
        exc = pending.error
        if exc is None:
            return
        if gphoto_error_code(exc) is None:
            raise exc
        reason = self._library()[1].reason(pending.mark)
        if gphoto_error_code(exc) in (GP_ERROR_CAMERA_BUSY, GP_ERROR) and "terminatecapture" not in reason.lower():
            log.info("bulb released; the camera is still processing the frame (%s)", reason or exc)
            return
        if not opened:
            log.debug("releasing bulb after a failed start: %s", exc)
            return
        raise CameraError("bulb could not be ended: the shutter may still be open; switch the camera off and on "
                          f"({camera_error(exc, 'release the bulb', logged=reason)})", gphoto_error_code(exc))

    def fetch(self, exposure: Exposure) -> RawCapture:
        """Wait for the exposure's raw file if the camera has not announced it yet, then download it."""
        cam = self._require_open()
        with self._lock:
            self._finish_pending()
            seen = list(exposure.handle.files) if isinstance(exposure.handle, CapturedFiles) else []
            nr = self.long_exposure_nr not in _NR_CLEAR
            timeout = self.file_timeout_s + exposure.exposure_s * (2 if exposure.bulb or nr else 1)
            folder, name = self._wait_for_raw(seen, timeout)
            data, mime = self.download(folder, name)
            extra = self._rest_of_capture(seen, (folder, name))
            if self.delete_from_card:
                try:
                    self._call(f"delete {name} from the camera", cam.file_delete, folder, name)
                except CameraError as exc:
                    log.warning("%s", exc)
            s = self.settings()             # on Bulb still: the bulb exposure (restored before live view)
            _, label, setting = self._shutter_now()
        log.info("captured %s (%d bytes, %s)", name, len(data), format_shutter(exposure.exposure_s))
        return RawCapture(data=data, filename=name, exposure_s=exposure.exposure_s, iso=s.iso,
                          aperture=s.aperture, camera=self.model or "",
                          extra={"folder": folder, "mime": mime, "bulb": exposure.bulb,
                                 "extra_files": [f"{f}/{n}" for f, n in extra],
                                 "shutter_setting": setting, "shutter_label": "Bulb" if exposure.bulb else label,
                                 "auto_iso": self.auto_iso, "long_exposure_nr": self.long_exposure_nr,
                                 "latency_s": self.last_latency_s if not exposure.bulb else None})

    def preview(self) -> np.ndarray:
        """A live-view frame. The camera refuses live view while the shutter is on Bulb ('Bulb warning'): the
        timed speed set before dualrgb's own bulb exposure is restored first; Bulb left by something else is
        reported in one line."""
        cam = self._require_open()
        with self._lock:
            self._restore_timed_shutter()
            try:
                cfile = self._call("live view", cam.capture_preview)
            except CameraError as exc:
                if "bulb" in str(exc).lower():
                    raise CameraError(f"{exc}; the shutter is on Bulb: set a timed shutter speed on the camera "
                                      "(or take one timed exposure) and start live view again", exc.code) from exc
                raise
            self._live_view = True
        data = bytes(memoryview(cfile.get_data_and_size()))
        from PIL import Image, UnidentifiedImageError
        try:
            with Image.open(BytesIO(data)) as img:
                return np.asarray(img.convert("RGB"), dtype=np.uint8)
        except (UnidentifiedImageError, OSError) as exc:
            raise CameraError(f"live view: the camera sent {len(data)} bytes that are not a JPEG ({exc})") from exc
