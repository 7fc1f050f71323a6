"""Subject captures: a target or an original under each light of a preset, at one exposure or an HDR bracket per
light (thesis 1.4, 7, 8)."""
from __future__ import annotations

import logging
from typing import Iterator, Sequence

from app.sequences.base import PlannedFrame, ProgressEvent, Sequence as BaseSequence
from app.sequences.shooter import Shooter
from app.workflow.vocabulary import EventKind, NamedLight, Subject, step_id

log = logging.getLogger(__name__)


class SubjectCapture(BaseSequence):
    """One frame per light and exposure of ``subject`` (an HDR bracket when a light has several exposures).

    ``exposures`` maps each light name to its exposure times. Steps already in the session are kept (resume)
    unless ``take`` > 1, a re-shoot, which records new frames under the next take of the same steps.
    """

    name = "subject capture"

    def __init__(self, shooter: Shooter, lights: Sequence[NamedLight], exposures: dict[str, Sequence[float]],
                 subject: Subject, take: int = 1, meta: dict | None = None):
        super().__init__()
        self.shooter = shooter
        self.lights = list(lights)
        self.exposures = {k: sorted(set(float(t) for t in v)) for k, v in exposures.items()}
        self.subject = subject
        self.take = take
        self.meta = dict(meta or {})
        self.new = self.kept = 0
        missing = [nl.name for nl in self.lights if not self.exposures.get(nl.name)]
        if missing:
            raise ValueError(f"no exposure time for {', '.join(missing)}")
        for nl in self.lights:
            for t in self.exposures[nl.name]:
                shooter.check_light_time(t)
        self.name = f"{subject.label} capture"

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame(self.subject.role.value, t, nl.light.label(), self.subject.label)
                for nl in self.lights for t in self.exposures[nl.name]]

    def steps(self) -> list[str]:
        """The step ids this capture records (the take included)."""
        return [step_id(self.subject.role, subject=self.subject, light=nl.name, exposure_s=t, take=self.take)
                for nl in self.lights for t in self.exposures[nl.name]]

    def _steps(self) -> Iterator[ProgressEvent]:
        total = len(self.plan())
        if not self.shooter.place(self.subject.place, self.subject.nd):
            yield ProgressEvent(0, total, f"Place the {self.subject.label}, then continue",
                                kind=EventKind.PROMPT.value, data={"place": self.subject.place, "nd": self.subject.nd})
        step = 0
        for nl in self.lights:
            for t in self.exposures[nl.name]:
                sid = step_id(self.subject.role, subject=self.subject, light=nl.name, exposure_s=t, take=self.take)
                kind = EventKind.KEPT if self.shooter.session.has_step(sid) else EventKind.FRAME
                entry = self.shooter.shoot(self.subject.role.value, nl.light, t, sid, light_name=nl.name,
                                           subject=self.subject.key, take=self.take, **self.meta)
                self.kept += kind is EventKind.KEPT
                self.new += kind is EventKind.FRAME
                step += 1
                yield ProgressEvent(step, total, f"{self.subject.label} under {nl.name} at {t:g} s", kind=kind.value,
                                    data={"entry": entry.seq, "exposure_s": t, "light": nl.name})

    def _cleanup(self) -> None:
        self.shooter.lights_off()
