"""Subject captures: a target or an original under each light of a preset, at one exposure or an HDR bracket per
light (thesis 1.4, 7, 8)."""
from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.sequences.base import Sequence as BaseSequence
from dualrgb.common.formatting import format_exposure
from dualrgb.core.light_safety import StandFacts
from dualrgb.core.messages import Place, PlanSteps, Shot
from dualrgb.core.vocabulary import EventKind, NamedLight, Subject, step_id

log = logging.getLogger(__name__)


class SubjectCapture(BaseSequence):
    """One frame per light and exposure of ``subject`` (an HDR bracket when a light has several exposures).

    ``exposures`` maps each light name to its exposure times. PlanSteps already in the session are kept (resume)
    unless ``take`` > 1, a re-shoot, which records new frames under the next take of the same steps.
    """

    name = "subject capture"

    def __init__(self, facts: StandFacts, lights: Sequence[NamedLight], exposures: Mapping[str, Sequence[float]],
                 subject: Subject, take: int = 1, meta: dict | None = None, frames: int = 1):
        super().__init__()
        self.facts = facts
        self.lights = list(lights)
        self.exposures = {k: sorted({float(t) for t in v}) for k, v in exposures.items()}
        self.subject = subject
        self.take = take
        self.meta = dict(meta or {})
        if frames < 1:
            raise ValueError(f"frames per exposure {frames}: expected at least 1")
        self.frames = frames          # > 1: frames averaged per exposure (noise / sqrt(frames), dose x frames)
        self.new = self.kept = 0
        missing = [nl.name for nl in self.lights if not self.exposures.get(nl.name)]
        if missing:
            raise ValueError(f"no exposure time for {', '.join(missing)}")
        for nl in self.lights:
            for t in self.exposures[nl.name]:
                facts.check_light_time(t)
        self.name = f"{subject.label} capture"

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame(self.subject.role.value, t, nl.light.label(), self.subject.label)
                for nl, t, _i in self._shots()]

    def _shots(self) -> list[tuple[NamedLight, float, int | None]]:
        """(light, exposure, frame index or None for a single frame) in shooting order."""
        index = (lambda i: i) if self.frames > 1 else (lambda i: None)
        return [(nl, t, index(i)) for nl in self.lights for t in self.exposures[nl.name] for i in range(self.frames)]

    def _step(self, nl: NamedLight, t: float, i: int | None) -> str:
        return step_id(self.subject.role, subject=self.subject, light=nl.name, exposure_s=t, frame=i, take=self.take)

    def steps(self) -> list[str]:
        """The step ids this capture records (the take included)."""
        return [self._step(nl, t, i) for nl, t, i in self._shots()]

    def _steps(self) -> PlanSteps:
        total = len(self.plan())
        yield Place(self.subject.place, self.subject.nd, f"Place the {self.subject.label}, then continue")
        for step, (nl, t, i) in enumerate(self._shots(), start=1):
            taken = yield Shot(self.subject.role.value, nl.light, t, self._step(nl, t, i),
                               {"light_name": nl.name, "subject": self.subject.key, "take": self.take, **self.meta})
            self.kept += taken.kind is EventKind.KEPT
            self.new += taken.kind is EventKind.FRAME
            yield ProgressEvent(step, total, f"{self.subject.label} under {nl.name} at {format_exposure(t)}",
                                kind=taken.kind, data={"entry": taken.seq, "exposure_s": t, "light": nl.name})
