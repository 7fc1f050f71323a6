"""A camera and a sphere that only count what they are asked to do (the fault suite's rig): session faults
are tested without the pty emulator; the virtual-lab tests cover the real path."""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from drivers.camera.base import CameraSettings, RawCapture

ROOT = Path(__file__).resolve().parents[2]


@dataclass
class CountingCamera:
    frame_size_bytes: int = 2000
    captures: int = 0

    def capture(self, exposure_s: float) -> RawCapture:
        self.captures += 1
        body = hashlib.sha256(f"{self.captures}/{exposure_s}".encode()).digest()
        data = (body * (self.frame_size_bytes // len(body) + 1))[: self.frame_size_bytes]
        return RawCapture(data=data, filename=f"DSC_{self.captures:04d}.NEF", exposure_s=exposure_s, iso=100,
                          aperture=8.0, camera="Counting D610")

    def settings(self) -> CameraSettings:
        return CameraSettings(iso=100, aperture=8.0, image_quality="NEF (Raw)")

    def shutter_speeds(self) -> list[float]:
        return [1 / 500, 1 / 125, 1 / 60, 1 / 30, 0.5, 1.0]

    def frame_bytes(self) -> int:
        return self.frame_size_bytes

    def config_summary(self) -> dict:
        return {"camera": "Counting D610", "serial": "0001"}


@dataclass
class CountingSphere:
    calls: list = field(default_factory=list)
    lit: bool = False

    def apply(self, light) -> None:
        self.calls.append(("apply", light.leds))

    def on(self) -> None:
        self.calls.append(("on",))
        self.lit = True

    def off(self) -> None:
        self.calls.append(("off",))
        self.lit = False

    def temperature_c(self) -> float:
        return 30.0
