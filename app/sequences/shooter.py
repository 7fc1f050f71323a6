"""Shooter: one exposure done safely, the building block of every sequence.

For each frame: skip it if the session already has its step (resume), switch on only the light it needs,
let it settle, capture, switch the light off whatever happens, write the raw file to the session first,
then log the light dose. A capture whose light would stay on longer than ``max_on_s`` (default 10 s: the
thesis found no LED drift in the first 10 s, 4.3.2) is refused before anything is switched on.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from app.light_dose import LightDose
from app.session import CaptureSession, SessionEntry
from drivers.camera.base import Camera
from drivers.raw import RawFrame, load_raw
from simulation.lightsource import LightSource

log = logging.getLogger(__name__)

Stand = Callable[[str, bool], object]     # (what, nd) -> places 'train'/'test'/'open-gate'/'lens-cap'


class LightSafetyError(RuntimeError):
    """A capture would keep the light on longer than allowed; nothing was switched on."""


@dataclass
class SafetySettings:
    max_on_s: float = 10.0          # per capture, light on (settle + exposure)
    settle_s: float = 0.2           # after switching on, before the shutter opens


class Shooter:
    def __init__(self, camera: Camera, sphere, session: CaptureSession, stand: Optional[Stand] = None,
                 safety: SafetySettings = SafetySettings(), sleep: Callable[[float], None] = time.sleep,
                 clock: Callable[[], float] = time.monotonic):
        self.camera = camera
        self.sphere = sphere
        self.session = session
        self.stand = stand
        self.safety = safety
        self.dose = LightDose()
        self._sleep = sleep
        self._clock = clock
        self.placed: Optional[tuple[str, bool]] = None
        self._frames: dict[int, RawFrame] = {}

    def place(self, what: str, nd: bool = False) -> bool:
        """Ask the stand to hold ``what``; returns False when a person must do it (no stand callback)."""
        if self.placed == (what, nd):
            return True
        if self.stand is None:
            return False
        self.stand(what, nd)
        self.placed = (what, nd)
        return True

    def check_light_time(self, exposure_s: float) -> None:
        on = exposure_s + self.safety.settle_s
        if on > self.safety.max_on_s:
            raise LightSafetyError(
                f"exposure {exposure_s:g} s would keep the light on {on:.1f} s, over the {self.safety.max_on_s:g} s "
                "limit (LEDs drift after 10 s); use a brighter light, a higher ISO or raise the limit")

    def lights_off(self) -> None:
        if self.sphere is not None:
            self.sphere.off()

    def shoot(self, role: str, light: Optional[LightSource], exposure_s: float, step_id: str,
              **meta) -> SessionEntry:
        if self.session.has_step(step_id):
            log.info("step %s already in the session: not shot again", step_id)
            return self.session.entry(step_id)
        lit = light is not None and not light.is_dark
        if lit:
            self.check_light_time(exposure_s)
            self.sphere.apply(light)
            self.sphere.on()
            t_on = self._clock()
            self._sleep(self.safety.settle_s)
        try:
            raw = self.camera.capture(exposure_s)
        finally:
            if lit:
                self.sphere.off()
                on_s = self._clock() - t_on
                self.dose.add(light, on_s)
                self.session.record_dose(light, on_s, step_id=step_id)   # in the manifest as it happens
        temperature = None
        if self.sphere is not None:
            try:
                temperature = self.sphere.temperature_c()
            except Exception as exc:  # a temperature read failure must not lose the downloaded frame
                log.warning("could not read the sphere temperature: %s", exc)
        settings = {k: v for k, v in self.camera.settings().__dict__.items() if v is not None}
        return self.session.record(raw, role, step_id=step_id, light=light if lit else None,
                                   sphere_temperature_c=temperature, settings=settings,
                                   placed=list(self.placed) if self.placed else None, **meta)

    def frame(self, entry: SessionEntry) -> RawFrame:
        """The raw frame of a session entry, read back from the session folder (cached)."""
        if entry.seq not in self._frames:
            self._frames[entry.seq] = load_raw(self.session.file_path(entry))
        return self._frames[entry.seq]

    def forget(self) -> None:
        self._frames.clear()


def channel_levels(frame: RawFrame, percentile: float = 99.5, region: float = 0.6) -> np.ndarray:
    """Per-CFA-channel bright level above black (DN) in the central ``region`` of the frame."""
    h, w = frame.mosaic.shape
    r0, r1 = int(h * (1 - region) / 2) // 2 * 2, int(h * (1 + region) / 2) // 2 * 2
    c0, c1 = int(w * (1 - region) / 2) // 2 * 2, int(w * (1 + region) / 2) // 2 * 2
    out = []
    for _name, (r, c), idx in frame.channels():
        plane = frame.mosaic[r0 + r:r1:2, c0 + c:c1:2].astype(np.float32) - frame.black_levels[idx]
        out.append(float(np.percentile(plane, percentile)))
    return np.array(out)
