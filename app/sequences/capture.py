"""Target captures: dual-RGB / N-light with a preset's lights, and the 3-channel baseline (thesis 1.4, 7)."""
from __future__ import annotations

import logging
from typing import Iterator, Sequence

from app.sequences.base import PlannedFrame, ProgressEvent, Sequence as BaseSequence
from app.sequences.calibration import NamedLight, exposure_key
from app.sequences.shooter import Shooter

log = logging.getLogger(__name__)


class TargetCapture(BaseSequence):
    """One frame (or an exposure list for HDR) per light of the target on the stand.

    ``exposures`` maps each light name to its exposure times; ``place`` is 'train' / 'test' (or an artwork
    label when a person places it), ``nd`` adds the ND 2.0 half-filter of thesis 8.3 in the virtual lab.
    """

    name = "target capture"

    def __init__(self, shooter: Shooter, lights: Sequence[NamedLight], exposures: dict[str, Sequence[float]],
                 place: str, nd: bool = False, condition: str = "dual_rgb", role: str = "target"):
        super().__init__()
        self.shooter = shooter
        self.lights = list(lights)
        self.exposures = {k: sorted(set(float(t) for t in v)) for k, v in exposures.items()}
        self.placed = place
        self.nd = nd
        self.condition = condition
        self.role = role
        for nl in self.lights:
            for t in self.exposures[nl.name]:
                shooter.check_light_time(t)

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame(self.role, t, nl.light.label(), self.placed + (" + ND" if self.nd else ""))
                for nl in self.lights for t in self.exposures[nl.name]]

    def _steps(self) -> Iterator[ProgressEvent]:
        total = len(self.plan())
        if not self.shooter.place(self.placed, self.nd):
            yield ProgressEvent(0, total, f"Place the {self.placed} target, then continue", kind="prompt",
                                data={"place": self.placed, "nd": self.nd})
        step = 0
        nd = "nd" if self.nd else "plain"
        for nl in self.lights:
            for t in self.exposures[nl.name]:
                entry = self.shooter.shoot(
                    self.role, nl.light, t, f"{self.role}/{self.condition}/{self.placed}/{nd}/{nl.name}/{exposure_key(t)}",
                    light_name=nl.name, target=self.placed, nd=self.nd, condition=self.condition)
                step += 1
                yield ProgressEvent(step, total, f"{self.placed} under {nl.name} at {t:g} s", kind="frame",
                                    data={"entry": entry.seq, "exposure_s": t, "light": nl.name})

    def _cleanup(self) -> None:
        self.shooter.lights_off()
