"""A queue of originals captured and delivered in one run: the loop ``dualrgb capture --queue`` and the window's
Originals panel both run, and the frames an original will take, listed before anything moves.

    outcomes = capture_queue(stand, originals, profile, on_outcome=print)     # CLI: a delivered one is kept
    outcomes = capture_queue(stand, originals, profile, reshoot={"ACC-1": True, "ACC-2": False},
                             frames={"ACC-1": 2})                          # window: the technician's answers
    plan = original_plan(profile, "ACC-1", frames=2)                      # metering, then the original per light

Every original is checked first (app.workflow.stand.copystand.CopyStand.preflight: nothing is lit while one cannot be
delivered), then each is captured (metering, an HDR bracket when metering asks) and delivered in turn, all in one
run of the stand's run engine (dark at its start and end, read back). The stand's ``on_event`` hears, per
original, a progress event when it starts and one with its outcome (``data[QUEUE_EVENT]``: 'start', 'delivered'
or 'kept'; ``data['original']``: its identifier), so a window follows the queue from its worker thread.
"""
from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from dualrgb.app.workflow.delivery.delivery import Original
from dualrgb.app.workflow.delivery.delivery_folder import sidecar_identifier
from dualrgb.app.workflow.stand.copystand import CaptureReport, CopyStand
from dualrgb.core.messages import PlannedFrame, ProgressEvent
from dualrgb.core.session.paths import deliverable
from dualrgb.core.vocabulary import Role

if TYPE_CHECKING:
    from dualrgb.app.workflow.calibration.profile import CalibrationProfile
    from dualrgb.core.protocols import Session

log = logging.getLogger(__name__)

QUEUE_EVENT = "queue"          # data key of the queue's own events: 'start', 'delivered', 'kept'


@dataclass
class QueueOutcome:
    """One original of a queue: captured and delivered (``report``), or already delivered and kept (``kept``:
    its sidecar)."""

    original: Original
    report: CaptureReport | None = None
    kept: Path | None = None

    def summary(self) -> str:
        if self.report is not None:
            return self.report.summary()
        return f"{self.original.identifier}: already delivered, kept"


def delivered_sidecar(session: Session, original: Original) -> Path | None:
    """The sidecar of ``original``'s delivery in ``session`` (session.json 'originals'), when it exists and names
    the same identifier; None otherwise."""
    meta = (session.settings.get("originals") or {}).get(original.identifier) or {}
    sidecar = deliverable(Path(session.path), meta.get("sidecar"))
    if sidecar is None or not sidecar.is_file():
        return None
    try:
        return sidecar if sidecar_identifier(sidecar) == original.identifier else None
    except ValueError as exc:
        log.warning("%s: %s", original.identifier, exc)
        return None


def original_plan(profile: CalibrationProfile, identifier: str, frames: int = 1,
                  brackets: Mapping[str, Sequence[float]] | None = None) -> list[PlannedFrame]:
    """The frames of an original before anything moves: a metering frame per light, then the original under each
    light at its base exposure, or - once metering has planned how many exposures it needs (``brackets``: light
    name -> the exposures metering asked for) - the calibration's own exposures, as many as metering asks and the
    calibration covers (CopyStand.meter); ``frames`` per exposure."""
    brackets = brackets or {}
    plan = [PlannedFrame(Role.METERING.value, profile.base_exposures[nl.name], nl.light.label(),
                         f"metering {identifier}") for nl in profile.lights]
    for nl in profile.lights:
        have = profile.exposures.get(nl.name, [])
        times = have[:len(brackets[nl.name])] if nl.name in brackets else [profile.base_exposures[nl.name]]
        note = identifier + ("" if brackets else " (more exposures when metering asks for HDR)")
        plan += [PlannedFrame(Role.ORIGINAL.value, t, nl.light.label(), note) for t in times for _ in range(frames)]
    return plan


def capture_queue(stand: CopyStand, originals: Sequence[Original], profile: CalibrationProfile, *,
                  reshoot: bool | Mapping[str, bool] = False, out_dir: Path | None = None,
                  frames: Mapping[str, int] | None = None,
                  on_outcome: Callable[[QueueOutcome], None] | None = None) -> list[QueueOutcome]:
    """Capture and deliver ``originals`` in order, in one run (module docstring). ``reshoot`` True: every one is
    shot again; False: one already delivered in the session is kept and said so; a mapping (the technician's
    answers, by identifier): True shoots it again (a new take), False delivers its frames again (nothing lit for
    frames it has). ``frames``: frames per exposure by identifier (else the stand's setting)."""
    for original in originals:
        stand.preflight(original, out_dir, profile)
    stand.check_before_light(profile, out_dir, len(originals))
    return stand.engine.run(lambda: _queue(stand, originals, profile, reshoot, out_dir, frames or {}, on_outcome))


def _queue(stand: CopyStand, originals: Sequence[Original], profile: CalibrationProfile,
           reshoot: bool | Mapping[str, bool], out_dir: Path | None, frames: Mapping[str, int],
           on_outcome: Callable[[QueueOutcome], None] | None) -> list[QueueOutcome]:
    outcomes = []
    for i, original in enumerate(originals):
        stand._check_cancel()
        _say(stand, i, len(originals), original, "start", f"{original.identifier}: capturing")
        if isinstance(reshoot, Mapping):
            kept = None
            again: bool | None = reshoot.get(original.identifier)
        else:
            kept, again = (None if reshoot else delivered_sidecar(stand.session, original)), reshoot
        outcome = (QueueOutcome(original, kept=kept) if kept is not None
                   else QueueOutcome(original, report=stand.capture(original, profile, reshoot=again, out_dir=out_dir,
                                                                    frames=frames.get(original.identifier))))
        outcomes.append(outcome)
        _say(stand, i + 1, len(originals), original, "kept" if kept is not None else "delivered", outcome.summary(),
             outcome)
        if on_outcome is not None:
            on_outcome(outcome)
    return outcomes


def _say(stand: CopyStand, step: int, total: int, original: Original, what: str, line: str,
         outcome: QueueOutcome | None = None) -> None:
    if stand.on_event is not None:
        stand.on_event(ProgressEvent(step, total, line, data={QUEUE_EVENT: what, "original": original.identifier,
                                                              "outcome": outcome}))
