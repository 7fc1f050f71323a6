"""libgphoto2 errors as one-line, actionable :class:`CameraError` messages, with libgphoto2's own reason.

``GPhoto2Error.string`` is only the generic text for the code ("Unspecified error" for -1); the real reason
("'nikon_wait_busy(params, 100, 5000)' failed: Bulb Release Busy (0xa200)", "The property 'Image Quality' /
0x5004 was not set (0xa005: ...)", "Liveview cannot start: Bulb warning", "Could not claim interface 0 (Permission
denied)") goes to libgphoto2's log. :class:`LibraryLog` keeps the recent error lines of that log (one callback,
registered once), and :func:`camera_error` puts the line that explains the failure into the message.
"""
from __future__ import annotations

import collections
import itertools
import logging
import threading
import time
from collections.abc import Callable
from typing import Any, TypeVar

from dualrgb.drivers.camera.base import CameraError

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

# the desktop daemons that claim a PTP camera as soon as it appears: gvfs on Linux, ptpcamerad on macOS
CAMERA_DAEMONS = ("gvfs-gphoto2-volume-monitor", "ptpcamerad")
FREE_CAMERA_ADVICE = ("close photo programs and free the camera from the desktop: on Linux run "
                      "`gio mount -s gphoto2` and `pkill -f gvfs-gphoto2-volume-monitor`; on macOS quit Photos and "
                      "Image Capture and run `killall -9 ptpcamerad` (it restarts: run it just before opening the "
                      "camera)")
CLAIMED_ADVICE = FREE_CAMERA_ADVICE + ", then retry"
UDEV_ADVICE = ("this user may not open the camera's USB device: install libgphoto2's udev rules "
               "(the `libgphoto2-6` package, or `print-udev-rules` from libgphoto2's utilities), add yourself to the "
               "`plugdev` group, log in again and re-plug the camera (docs/first-session-d610.md)")

ERROR_ADVICE: dict[int, str] = {
    GP_ERROR: ("the camera refused the request: check its display (mode dial on M, menus and playback closed, "
               "card, battery) and retry"),
    GP_ERROR_MODEL_NOT_FOUND: "no camera found: connect the camera by USB and switch it on",
    GP_ERROR_IO_USB_CLAIM: ("the camera's USB interface could not be claimed: usually the desktop's "
                            "gvfs-gphoto2-volume-monitor (Linux) or ptpcamerad (macOS) holds it: " + CLAIMED_ADVICE
                            + "; if that is not it, " + UDEV_ADVICE),
    GP_ERROR_IO_LOCK: "another program holds the camera's USB device: " + CLAIMED_ADVICE,
    GP_ERROR_CAMERA_BUSY: ("the camera is busy (I/O in progress): let it finish writing, leave its menus and "
                           "playback, then retry"),
    GP_ERROR_IO_USB_FIND: ("the camera is no longer on its USB port (unplugged, or re-enumerated after "
                           "sleeping): reconnect it and reopen the camera"),
    GP_ERROR_TIMEOUT: ("the camera did not answer in time: check the USB cable, wake the camera "
                       "(half-press the shutter release) and retry"),
    GP_ERROR_NOT_SUPPORTED: ("not supported by this camera in its current mode (set the mode dial to M and "
                             "check the camera's USB/PTP setting)"),
    GP_ERROR_IO: ("USB I/O error talking to the camera: check the cable (avoid hubs), then reconnect and "
                  "reopen the camera; if it happens at once on opening, " + UDEV_ADVICE),
    GP_ERROR_BAD_PARAMETERS: ("the camera rejected the request (setting missing, read-only in this mode, value "
                              "not allowed, or the camera busy)"),
    GP_ERROR_FILE_NOT_FOUND: "the file is not on the camera (any more)",
    GP_ERROR_NO_SPACE: "the camera's memory is full: free space on the card or capture to Internal RAM",
    GP_ERROR_CAMERA_ERROR: "the camera reported an error: check its display (lens, card, battery, mode dial)",
    GP_ERROR_CANCEL: "cancelled",
}
PERMISSION_WORDS = ("permission denied", "access denied", "insufficient permissions")
CLAIMED_WORDS = ("resource busy", "device or resource busy")


def gphoto_error_code(exc: BaseException) -> int | None:
    code = getattr(exc, "code", None)
    return int(code) if isinstance(code, int) else None


def _advice(code: int | None, detail: str, logged: str, opening_port: bool) -> str | None:
    """The advice for a code, refined by libgphoto2's logged reason and by what was being done."""
    text = logged.lower()
    if code in (GP_ERROR_IO, GP_ERROR_IO_USB_CLAIM) and any(w in text for w in PERMISSION_WORDS):
        return UDEV_ADVICE
    if code == GP_ERROR_IO_USB_CLAIM and any(w in text for w in CLAIMED_WORDS):
        return "another program holds the camera's USB interface: " + CLAIMED_ADVICE
    if code == GP_ERROR_FILE_NOT_FOUND and opening_port:
        return ("no camera detected at this port (nothing answered there, or not a camera libgphoto2 knows): "
                "check that the camera is on and in PTP mode, run `dualrgb devices` and open the port it lists")
    if code is not None and code in ERROR_ADVICE:
        return ERROR_ADVICE[code]
    return f"camera error: {detail}" if detail else "camera error"


def camera_error(exc: BaseException, action: str, *, logged: str = "", opening_port: bool = False) -> CameraError:
    """A one-line :class:`CameraError` for a libgphoto2 error (anything with an int ``code``), keeping the code.

    ``action`` says what was being done ("open camera", "set shutterspeed", ...); ``logged`` is libgphoto2's own
    reason from its log (:meth:`LibraryLog.reason`), appended when there is one; ``opening_port``: the error came
    from opening a given port (-108 then means no camera there, not a missing file).
    """
    code = gphoto_error_code(exc)
    detail = " ".join(str(getattr(exc, "string", None) or exc).split())
    logged = " ".join(logged.split())
    advice = _advice(code, detail, logged, opening_port)
    reason = f" (libgphoto2: {logged})" if logged and logged not in (advice or "") else ""
    msg = f"{action}: {advice}{reason}"
    return CameraError(f"{msg} [gphoto2 {code}]" if code is not None else msg, code)


def retry_busy(fn: Callable[[], T], action: str, *, error_type: type[BaseException] = Exception, tries: int = 3,
               delay_s: float = 0.5, sleep: Callable[[float], object] = time.sleep,
               mapper: Callable[[BaseException, str], CameraError] | None = None) -> T:
    """Call ``fn``; retry on 'camera busy' (-110) up to ``tries`` times with doubling delay, map errors.

    Only exceptions of ``error_type`` that carry a libgphoto2 code are mapped to :class:`CameraError` (by
    ``mapper``, default :func:`camera_error`).
    """
    mapper = mapper or camera_error
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
            raise mapper(exc, action) from exc
    raise AssertionError("unreachable")  # pragma: no cover


class LibraryLog:
    """libgphoto2's error log lines, kept as they come (one callback per process; lines from any thread).

    ``mark()`` before a call and ``reason(mark)`` after its failure give the line that explains it: a message
    libgphoto2 addressed to the user (``gp_context_error``) if there was one, else the last error line.
    Every line also goes to this module's logger at DEBUG.
    """

    _instance: LibraryLog | None = None
    _guard = threading.Lock()

    def __init__(self, maxlen: int = 64):
        self._lines: collections.deque[tuple[int, str, str]] = collections.deque(maxlen=maxlen)
        self._counter = itertools.count(1)
        self._last = 0
        # id(gphoto2 module) -> (the module, its callback handle), both kept alive: a freed stand-in's id could
        # be reused by the next one, which would then never be registered
        self._handles: dict[int, tuple[Any, Any]] = {}

    @classmethod
    def attach(cls, gp: Any) -> LibraryLog:
        """The process' log, its callback registered with ``gp`` (python-gphoto2 or a stand-in) once."""
        with cls._guard:
            if cls._instance is None:
                cls._instance = LibraryLog()
            inst = cls._instance
            if id(gp) not in inst._handles:
                inst._register(gp)
            return inst

    def _register(self, gp: Any) -> None:
        level = gp.GP_LOG_DEBUG if logging.getLogger("gphoto2").isEnabledFor(logging.DEBUG) else gp.GP_LOG_ERROR
        try:
            result = gp.gp_log_add_func(level, self._callback)
        except Exception as exc:  # noqa: BLE001 - without the log, messages keep the generic text
            log.info("could not attach to libgphoto2's log: %s", exc)
            return
        self._handles[id(gp)] = (gp, result[-1] if isinstance(result, (list, tuple)) else result)

    def _callback(self, level: int, domain: str, text: str, *_data: Any) -> None:
        log.debug("libgphoto2 (%s) %s", domain, text)
        if level == 0:                      # GP_LOG_ERROR
            seq = next(self._counter)
            self._lines.append((seq, str(domain), str(text).strip()))
            self._last = seq

    def add(self, domain: str, text: str) -> None:
        """Record one error line (what the callback does; for stand-ins)."""
        self._callback(0, domain, text)

    def mark(self) -> int:
        return self._last

    def lines(self, since: int = 0) -> list[tuple[str, str]]:
        return [(d, t) for seq, d, t in list(self._lines) if seq > since]

    def reason(self, since: int) -> str:
        lines = self.lines(since)
        if not lines:
            return ""
        told = [t for d, t in lines if d.startswith("gp_context_error")]
        return told[-1] if told else lines[-1][1]
