"""Sequences built from a kind, and the exposures darks and flats must cover, for the GUI's calibrate & capture.

``build_sequence(SequenceKind.DARKS, ...)`` etc. make the same sequence objects the CLI and the demo run;
:class:`StandPlanner` makes them with what a CopyStand's run engine knows of the stand (``stand.planner()``: to
run through that engine) or what the camera alone says (``app.workflow.stand.copystand.plans_only``: plans, nothing
touched), so a front end never builds a sequence itself;
``calibration_exposures`` is the rule for which exposures need darks and flats: every exposure a capture uses
(the base exposures, every HDR bracket planned, and whatever the session already holds for those lights).
"""
from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

from dualrgb.app.sequences.base import Sequence as BaseSequence
from dualrgb.app.sequences.calibration import DarkSeries, FlatSeries
from dualrgb.app.sequences.capture import SubjectCapture
from dualrgb.app.sequences.crf_sweep import CrfSweep
from dualrgb.app.workflow.stand.metering import AutoExposure, Box, HdrMetering
from dualrgb.core.light_safety import StandFacts
from dualrgb.core.vocabulary import (
    NamedLight,
    Role,
    SequenceKind,
    Subject,
    latest_takes,
    light_of,
    role_of,
    split_take,
    step_id,
)

if TYPE_CHECKING:
    from dualrgb.core.protocols import Session
    from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)


def calibration_exposures(session: Session | None, base: Mapping[str, Sequence[float]],
                          planned: Mapping[str, Sequence[float]] | None = None) -> dict[str, list[float]]:
    """Per light: every exposure the captures use (base, planned HDR brackets, targets and originals already in
    the session under that light): darks and flats need all of them."""
    out = {name: {float(t) for t in ts} for name, ts in base.items()}
    for name, ts in (planned or {}).items():
        out.setdefault(name, set()).update(float(t) for t in ts)
    if session is not None:
        for e in latest_takes(session.entries()):
            name = light_of(e)
            if role_of(e) in (Role.TARGET, Role.ORIGINAL) and name in out and e.exposure_s:
                out[name].add(float(e.exposure_s))
    return {name: sorted(ts) for name, ts in out.items()}


def build_sequence(kind: SequenceKind, facts: StandFacts, lights: Sequence[NamedLight], *,
                   exposures: Mapping[str, Sequence[float]], frames: int = 1, subject: Subject | None = None,
                   take: int = 1) -> BaseSequence:
    """The sequence of ``kind``: darks at every exposure in ``exposures``, flats per light at its exposures,
    or ``subject`` under each light at its exposures (TARGET / HDR_TARGET / ORIGINAL)."""
    kind = SequenceKind(kind)
    if kind is SequenceKind.DARKS:
        return DarkSeries(facts, sorted({t for ts in exposures.values() for t in ts}), frames=frames)
    if kind is SequenceKind.FLATS:
        return FlatSeries(facts, lights, {k: list(v) for k, v in exposures.items()}, frames=frames)
    if subject is None:
        raise ValueError(f"a {kind.value} sequence needs a subject (a target or an original)")
    return SubjectCapture(facts, lights, {k: list(v) for k, v in exposures.items()}, subject, take=take)


class StandPlanner:
    """The plans a front end starts one by one (single steps), built with what is known of the stand."""

    def __init__(self, facts: StandFacts):
        self.facts = facts

    def sequence(self, kind: SequenceKind, lights: Sequence[NamedLight], *,
                 exposures: Mapping[str, Sequence[float]], frames: int = 1, subject: Subject | None = None,
                 take: int = 1) -> BaseSequence:
        """:func:`build_sequence` on this stand."""
        return build_sequence(kind, self.facts, lights, exposures=exposures, frames=frames, subject=subject,
                              take=take)

    def auto_exposure(self, lights: Sequence[NamedLight]) -> AutoExposure:
        return AutoExposure(self.facts, lights)

    def hdr_metering(self, lights: Sequence[NamedLight], base: dict[str, float], subject: Subject,
                     boxes: Sequence[Box]) -> HdrMetering:
        return HdrMetering(self.facts, lights, base, subject, boxes)

    def crf_sweep(self, light: LightSource, levels: Sequence[float], exposures: Sequence[float],
                  min_exposure_s: float) -> CrfSweep:
        """The camera response sweep (app.sequences.crf_sweep): ``light`` at ``levels`` x ``exposures``."""
        return CrfSweep(self.facts, light, levels=tuple(levels), exposures=list(exposures),
                        min_exposure_s=min_exposure_s)


def planned_steps(seq: BaseSequence) -> list[str]:
    """The manifest step id of every planned frame of a dark series, flat series or subject capture, in plan
    order (what resume and re-shoot key on); an empty list for other sequences."""
    if isinstance(seq, SubjectCapture):
        return seq.steps()
    if isinstance(seq, DarkSeries):
        return [step_id(Role.DARK, exposure_s=t, frame=i) for t in seq.exposures for i in range(seq.frames)]
    if isinstance(seq, FlatSeries):
        return [step_id(Role.FLAT, light=nl.name, exposure_s=t, frame=i) for nl in seq.lights
                for t in seq.exposures.get(nl.name, []) for i in range(seq.frames)]
    return []


def steps_done(session: Session, steps: Sequence[str]) -> list[bool]:
    """Per step: is it already in the session (kept, not shot again, unless re-shot as a new take)?"""
    return [session.has_step(s) for s in steps]


def next_take(session: Session, steps: Sequence[str]) -> int:
    """The take a re-shoot of ``steps`` records: one more than the highest take any of them has."""
    bases = {split_take(s)[0] for s in steps}
    takes = [split_take(e.step_id or "")[1] for e in session.entries(include_superseded=True)
             if split_take(e.step_id or "")[0] in bases]
    return max(takes, default=0) + 1
