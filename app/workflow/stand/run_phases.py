"""The phases of a calibration run and of one original, in one place: the share of the run's progress each fills
(CopyStand.calibrate and CopyStand.capture report through these bands) and the frames the plan puts in each, for its
time left (app.workflow.phase_costs.PhaseClock).

    clock = calibration_clock(plan, settle_s=0.2, overhead_s=1.5)      # the window's and the CLI's calibration
    clock = original_clock(original_plan(profile, "ACC-1"), 0.2)      # one original: metering, frames, delivery
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence

from dualrgb.app.workflow.calibration.session_processing import PROCESSING_STEPS
from dualrgb.app.workflow.phase_costs import Phase, PhaseClock, PhaseCosts
from dualrgb.core.messages import PlannedFrame
from dualrgb.core.vocabulary import Role, Subject

CALIBRATION_RUN = "calibration"
# the frames' phases: the share of the calibration's progress each fills, in order (CopyStand.calibrate)
AUTO_EXPOSURE = (0.0, 0.1)
DARKS = (0.1, 0.35)
FLATS = (0.35, 0.5)
TARGET_FRAMES = {"train": (0.5, 0.55), "test": (0.55, 0.6)}
PROCESSING = (0.6, 0.95)            # app.workflow.calibration.session_processing.process_session, its steps inside
SAVING = (0.95, 1.0)
# one original's phases (CopyStand.shoot: metering, then its frames; CopyStand.capture: its delivery); the queue
# (app.workflow.day.queue_clock) records each of its originals' under the same run name
ORIGINAL_RUN = "original"
METERING = (0.0, 0.1)
ORIGINAL_FRAMES = (0.1, 0.8)
DELIVERY = (0.8, 1.0)
DEFAULT_OVERHEAD_S = 1.5            # per frame beyond the exposure (download, write) until one has been measured


def frame_seconds(frame: PlannedFrame, settle_s: float, overhead_s: float) -> float:
    """A planned frame's rough time: its exposure, the light settling before a lit frame, a per-frame overhead."""
    return frame.exposure_s + (settle_s if frame.light else 0.0) + overhead_s


def plan_seconds(plan: Sequence[PlannedFrame], settle_s: float, overhead_s: float) -> float:
    """Rough time for a plan's frames (:func:`frame_seconds` of each)."""
    return sum(frame_seconds(f, settle_s, overhead_s) for f in plan)


def _frame_phase(frame: PlannedFrame) -> str:
    if frame.role == Role.METERING.value:
        return "auto-exposure"
    if frame.role == Role.DARK.value:
        return "darks"
    if frame.role == Role.FLAT.value:
        return "flats"
    for name in TARGET_FRAMES:
        if frame.note == Subject.target(name).label:
            return f"{Subject.target(name).label} frames"
    return "darks"


def calibration_phases(plan: Sequence[PlannedFrame], settle_s: float = 0.2,
                       overhead_s: float = DEFAULT_OVERHEAD_S) -> list[Phase]:
    """The calibration's phases: the frames' (each with its planned frames and their estimated time) and the
    processing's steps (no estimate of their own until measured)."""
    frames: dict[str, list[PlannedFrame]] = {}
    for f in plan:
        frames.setdefault(_frame_phase(f), []).append(f)

    def shooting(name: str, band: tuple[float, float]) -> Phase:
        mine = frames.get(name, [])              # none planned yet (the first plan: auto-exposure's): unknown
        return Phase(name, *band, size=len(mine) or None,
                     plan_s=plan_seconds(mine, settle_s, overhead_s) if mine else None)
    lo, hi = PROCESSING
    return [shooting("auto-exposure", AUTO_EXPOSURE), shooting("darks", DARKS), shooting("flats", FLATS),
            *(shooting(f"{Subject.target(n).label} frames", band) for n, band in TARGET_FRAMES.items()),
            *(Phase(f"processing: {step}", lo + (hi - lo) * a, lo + (hi - lo) * b)
              for step, (a, b) in PROCESSING_STEPS.items()),
            Phase("saving", *SAVING)]


def calibration_clock(plan: Sequence[PlannedFrame], settle_s: float = 0.2, overhead_s: float = DEFAULT_OVERHEAD_S,
                      *, costs: PhaseCosts | None = None, record: bool = True) -> PhaseClock:
    """A calibration run's clock: its phases from ``plan`` (again from the plan the run announces after
    auto-exposure: its darks, flats and targets, the metering kept from the first), their measured costs from
    ``costs`` (default: the user's)."""
    metering = [f for f in plan if f.role == Role.METERING.value]

    def replan(frames: list[PlannedFrame]) -> list[Phase]:
        rest = [f for f in frames if f.role != Role.METERING.value]
        return calibration_phases([*metering, *rest], settle_s, overhead_s)
    return PhaseClock(CALIBRATION_RUN, calibration_phases(plan, settle_s, overhead_s), costs, record=record,
                      replan=replan)


def original_phases(plan: Sequence[PlannedFrame], settle_s: float = 0.2,
                    overhead_s: float = DEFAULT_OVERHEAD_S) -> list[Phase]:
    """One original's phases: its metering frames and its frames (each measured per frame, the plan's rough time
    until measured) and its delivery (one cost; none of its own until measured)."""
    metering = [f for f in plan if f.role == Role.METERING.value]
    frames = [f for f in plan if f.role != Role.METERING.value]

    def shooting(name: str, band: tuple[float, float], mine: list[PlannedFrame]) -> Phase:
        return Phase(name, *band, size=len(mine) or None,
                     plan_s=plan_seconds(mine, settle_s, overhead_s) if mine else None)
    return [shooting("metering", METERING, metering), shooting("frames", ORIGINAL_FRAMES, frames),
            Phase("delivery", *DELIVERY)]


def original_clock(plan: Sequence[PlannedFrame], settle_s: float = 0.2, overhead_s: float = DEFAULT_OVERHEAD_S,
                   *, costs: PhaseCosts | None = None, now: Callable[[], float] | None = None) -> PhaseClock:
    """One original's clock (a single shot: the window's and ``dualrgb capture --id``): its phases from ``plan``
    (app.workflow.day.queue_run.original_plan), their measured costs from ``costs`` (default: the user's); ``now``:
    the computer's time (app.workflow.day.queue_clock.ComputerTime: a person's placements left out)."""
    return PhaseClock(ORIGINAL_RUN, original_phases(plan, settle_s, overhead_s), costs, now=now or time.monotonic)
