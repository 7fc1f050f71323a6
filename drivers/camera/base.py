"""The camera interface every implementation follows (gphoto2 for a real Nikon, the virtual lab camera).

A capture has two phases, so that the light can go off as soon as the shutter has closed, before the slow
download: :meth:`Camera.expose` returns once the exposure is over (an :class:`Exposure`), :meth:`Camera.fetch`
then downloads that frame (a :class:`RawCapture`: the raw file's bytes and name; the caller, core.session, writes
them to disk first thing, so nothing downloaded is held only in memory for long). ``capture()`` does both.

Camera calls can hang (USB, a camera busy in its menus): :func:`call_with_deadline` runs one on a helper thread
and raises a one-line :class:`CameraTimeout` when it has not returned in time, so the caller (and the light) are
never held by a hung call.
"""
from __future__ import annotations

import abc
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from dualrgb.common.errors import ReportedError

log = logging.getLogger(__name__)

T = TypeVar("T")
C = TypeVar("C", bound="Camera")
GP_ERROR_TIMEOUT = -10          # libgphoto2's timeout code, also used for host-side deadlines
DEFAULT_LATENCY_S = 1.0         # a camera's latency allowance when it does not report its own


class CameraError(ReportedError, RuntimeError):
    """A camera problem, with a one-line message that says what to do about it.

    ``code`` is the libgphoto2 error code where there is one (e.g. -105 no camera, -53 USB claimed).
    """

    def __init__(self, message: str, code: int | None = None):
        super().__init__(message)
        self.code = code


class CameraTimeout(CameraError):
    """A camera call did not return within its host-side deadline. ``worker`` is the thread still inside it
    (the camera may finish later; until then it must not be called again)."""

    def __init__(self, message: str, worker: threading.Thread | None = None):
        super().__init__(message, GP_ERROR_TIMEOUT)
        self.worker = worker


def call_with_deadline(fn: Callable[[], T], deadline_s: float, action: str) -> T:
    """``fn()`` on a helper thread; its result or exception, or :class:`CameraTimeout` after ``deadline_s``.

    The helper thread of a call that timed out is left to finish on its own (a blocked C call cannot be
    interrupted; python-gphoto2 releases the GIL in its slow calls, so the rest of the program runs on)."""
    box: dict[str, Any] = {}
    done = threading.Event()

    def run() -> None:
        try:
            box["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - delivered to the caller's thread as it is
            box["error"] = exc
        finally:
            done.set()

    worker = threading.Thread(target=run, name=f"camera: {action}", daemon=True)
    worker.start()
    if not done.wait(deadline_s):
        raise CameraTimeout(f"{action}: the camera did not answer within {deadline_s:.3g} s; check the camera (USB "
                            "cable, battery, its display, menus closed), then reconnect it", worker)
    if "error" in box:
        raise box["error"]
    return box["value"]


@dataclass
class Exposure:
    """An exposure that is over (the shutter has closed) and not downloaded yet: what :meth:`Camera.fetch` needs.

    ``started``/``ended`` are on the camera's clock (``time.monotonic`` unless the camera was given another);
    ``handle`` is the implementation's own (gphoto2: the file's folder and name, or None while the camera is
    still storing it; the virtual camera: the light it saw)."""

    exposure_s: float
    started: float
    ended: float
    bulb: bool = False
    handle: Any = None


@dataclass
class CameraSettings:
    iso: int | None = None
    shutter_s: float | None = None        # exposure time in seconds (> 30 s means bulb)
    aperture: float | None = None         # f-number
    image_quality: str | None = None      # e.g. 'NEF (Raw)'
    capture_target: str | None = None     # e.g. 'Internal RAM', 'Memory card'


@dataclass
class RawCapture:
    """One exposure as downloaded: the raw file's bytes plus what was set when it was taken."""

    data: bytes
    filename: str                             # camera-side name, e.g. DSC_0001.NEF / VIRT_0001.DNG
    exposure_s: float
    iso: int | None = None
    aperture: float | None = None
    camera: str = ""
    extra: dict = field(default_factory=dict)


class Camera(abc.ABC):
    """Open/close (or use as a context manager), read/set settings, expose + fetch (= capture), preview."""

    name: str = "camera"

    @property
    def latency_s(self) -> float:
        """The camera's allowance beyond the exposure (a stand-in's default; real cameras report their own)."""
        return DEFAULT_LATENCY_S

    def latency_for(self, exposure_s: float) -> float:
        """How long after the end of an ``exposure_s`` exposure :meth:`expose` may take to return (trigger,
        shutter lag, reporting the shutter closed): the light's allowance beyond settle + exposure. Each camera
        reports its own (:attr:`latency_s`, where it does not depend on the exposure)."""
        return float(self.latency_s)

    @abc.abstractmethod
    def open(self) -> None: ...

    @abc.abstractmethod
    def close(self) -> None: ...

    def __enter__(self: C) -> C:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @abc.abstractmethod
    def settings(self) -> CameraSettings:
        """Current ISO, shutter, aperture, image quality and capture target."""

    @abc.abstractmethod
    def apply(self, settings: CameraSettings) -> CameraSettings:
        """Set every field that is not None; returns what the camera actually took (shutter snapped)."""

    @abc.abstractmethod
    def shutter_speeds(self) -> list[float]:
        """The exposure times (s) the camera offers, ascending (bulb excluded)."""

    @abc.abstractmethod
    def expose(self, exposure_s: float | None = None) -> Exposure:
        """Take one raw exposure (setting the shutter first if given; bulb above 30 s); returns as soon as the
        shutter has closed, before any download."""

    @abc.abstractmethod
    def fetch(self, exposure: Exposure) -> RawCapture:
        """Download the frame of an exposure (the light can be off by now)."""

    def capture(self, exposure_s: float | None = None) -> RawCapture:
        """``expose()`` then ``fetch()``: one raw exposure, downloaded."""
        return self.fetch(self.expose(exposure_s))

    @abc.abstractmethod
    def preview(self) -> np.ndarray:
        """A live-view frame as an (H, W, 3) uint8 RGB array."""

    def frame_bytes(self) -> int:
        """Estimated size of one raw file (for the free-space check before a sequence): a D610 14-bit NEF is
        about 30 MB; implementations that know better say so."""
        return 32 * 2**20

    def image_area(self) -> str:
        """What sets a frame's size and what part of the sensor it covers (image size, crop), as the camera says
        it ('' when it does not): part of a session's definition, so frames of another size are never mixed in."""
        return ""

    def frame_shape(self) -> tuple[int, int] | None:
        """(rows, columns) of the raw mosaic the next frame will have, when known before it is taken (None: known
        only from a frame; a real camera)."""
        return None

    def config_summary(self) -> dict[str, object]:
        """Named configuration values for display (implementations add what they know)."""
        s = self.settings()
        return {k: v for k, v in s.__dict__.items() if v is not None}
