"""The camera interface every implementation follows (gphoto2 for a real Nikon, the virtual lab camera).

A capture returns the raw file's bytes and name; the caller (app.session) writes them to disk first thing,
so nothing downloaded is ever held only in memory for long.
"""
from __future__ import annotations

import abc
import logging
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

log = logging.getLogger(__name__)


class CameraError(RuntimeError):
    """A camera problem, with a one-line message that says what to do about it.

    ``code`` is the libgphoto2 error code where there is one (e.g. -105 no camera, -53 USB claimed).
    """

    def __init__(self, message: str, code: Optional[int] = None):
        super().__init__(message)
        self.code = code


@dataclass
class CameraSettings:
    iso: Optional[int] = None
    shutter_s: Optional[float] = None        # exposure time in seconds (> 30 s means bulb)
    aperture: Optional[float] = None         # f-number
    image_quality: Optional[str] = None      # e.g. 'NEF (Raw)'
    capture_target: Optional[str] = None     # e.g. 'Internal RAM', 'Memory card'


@dataclass
class RawCapture:
    """One exposure as downloaded: the raw file's bytes plus what was set when it was taken."""

    data: bytes
    filename: str                             # camera-side name, e.g. DSC_0001.NEF / VIRT_0001.DNG
    exposure_s: float
    iso: Optional[int] = None
    aperture: Optional[float] = None
    camera: str = ""
    extra: dict = field(default_factory=dict)


class Camera(abc.ABC):
    """Open/close (or use as a context manager), read/set settings, capture, preview."""

    name: str = "camera"

    @abc.abstractmethod
    def open(self) -> None: ...

    @abc.abstractmethod
    def close(self) -> None: ...

    def __enter__(self) -> "Camera":
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
    def capture(self, exposure_s: Optional[float] = None) -> RawCapture:
        """Take one raw exposure (setting the shutter first if given; bulb above 30 s) and download it."""

    @abc.abstractmethod
    def preview(self) -> np.ndarray:
        """A live-view frame as an (H, W, 3) uint8 RGB array."""

    def frame_bytes(self) -> int:
        """Estimated size of one raw file (for the free-space check before a sequence): a D610 14-bit NEF is
        about 30 MB; implementations that know better say so."""
        return 32 * 2**20

    def config_summary(self) -> dict[str, object]:
        """Named configuration values for display (implementations add what they know)."""
        s = self.settings()
        return {k: v for k, v in s.__dict__.items() if v is not None}
