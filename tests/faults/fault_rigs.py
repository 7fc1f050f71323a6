"""A camera and a sphere that only count what they are asked to do (the fault suite's rig): session faults
are tested without the pty emulator; the virtual-lab tests cover the real path."""
from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field
from pathlib import Path

from dualrgb.drivers.camera.base import CameraSettings, Exposure, RawCapture
from dualrgb.drivers.led_sphere import LightReport
from dualrgb.drivers.led_sphere.supervisor import LitPeriod

ROOT = Path(__file__).resolve().parents[2]


@dataclass
class CountingCamera:
    frame_size_bytes: int = 2000
    captures: int = 0

    def expose(self, exposure_s: float) -> Exposure:
        self.captures += 1
        now = time.monotonic()
        return Exposure(exposure_s=exposure_s, started=now, ended=now, handle=self.captures)

    def fetch(self, exposure: Exposure) -> RawCapture:
        n = exposure.handle
        body = hashlib.sha256(f"{n}/{exposure.exposure_s}".encode()).digest()
        data = (body * (self.frame_size_bytes // len(body) + 1))[: self.frame_size_bytes]
        return RawCapture(data=data, filename=f"DSC_{n:04d}.NEF", exposure_s=exposure.exposure_s, iso=100,
                          aperture=8.0, camera="Counting D610")

    def capture(self, exposure_s: float) -> RawCapture:
        return self.fetch(self.expose(exposure_s))

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

    def on(self, max_on_s: float = 10.0) -> LitPeriod:
        self.calls.append(("on",))
        self.lit = True
        self.period = LitPeriod(time.monotonic(), max_on_s)
        return self.period

    def exposure_done(self, period: LitPeriod) -> bool:
        period.exposure_done_at = time.monotonic()
        return True

    def tripped(self) -> bool:
        return False

    def off(self) -> None:
        self.calls.append(("off",))
        self.lit = False
        if getattr(self, "period", None) is not None:
            self.period.off_at = time.monotonic()

    def ensure_off(self) -> LightReport:
        self.off()
        return LightReport(True, "all LEDs and the light were switched off")

    def temperature_c(self) -> float:
        return 30.0
