"""The time left of a queue of originals (Qt-free): one progress for the whole queue and its time left from the
measured costs of one original (app.workflow.phase_costs, the run ``original``: app.workflow.stand.run_phases).

Each original of the queue is timed by its own PhaseClock (metering, frames, delivery) and recorded in the same
store as a single shot's, once its delivery has ended. The queue's time left (:func:`queue_time_left`) is the
shooting still to do - the rest of the current original's and every later one's, each from its planned frames'
measured costs - plus the deliveries: pipelined (app.workflow.day.queue_run), an original is delivered while the next
is shot, so each costs the longer of its shooting and a delivery, and the last delivery, overlapped by nothing, is
added; sequentially each costs both. The costs are corrected by this queue's pace so far: its shot originals' time
against their costs, its deliveries' against theirs (clamped as a calibration's: phase_costs.SCALE_LIMITS).

A person's time is not the computer's: the operator's placements and prompts (core.stand_timeline's 'prompt' spans,
and its 'place' spans where no sample changer places) are left out of every duration measured here
(:class:`ComputerTime`).

    clock = QueueClock([original_plan(profile, i) for i in ids], settle_s=0.2)
    run = Run("3 originals", plan, work, clock=clock)        # work: capture_queue(..., clock=clock)
"""
from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from dualrgb.app.workflow.phase_costs import Phase, PhaseClock, PhaseCosts, pace_scale
from dualrgb.app.workflow.stand.run_phases import (
    DEFAULT_OVERHEAD_S,
    ORIGINAL_FRAMES,
    ORIGINAL_RUN,
    original_phases,
)
from dualrgb.core.messages import PlannedFrame

log = logging.getLogger(__name__)

SHOOTING_SHARE = 0.9          # the queue's bar: its originals' shooting fills 0..0.9, the last delivery the rest
PERSON_SPANS = ("prompt",)    # a person's time on the stand's timeline (with 'place' where a person places)


class ComputerTime:
    """A monotonic clock that stops while a person is asked (the timeline's person spans subtracted once they
    end); with no timeline attached it is ``now`` itself."""

    def __init__(self, now: Callable[[], float] = time.monotonic):
        self._now = now
        self.timeline: Any = None
        self.kinds: tuple[str, ...] = PERSON_SPANS

    def on_stand(self, stand: Any) -> None:
        """The timeline (core.stand_timeline) of ``stand`` (a CopyStand); its placements are a person's when no
        sample changer places."""
        actions = stand.engine.actions
        self.timeline = actions.shooter.timeline
        self.kinds = (*PERSON_SPANS, "place") if actions.devices.stand is None else PERSON_SPANS

    def person_s(self) -> float:
        spans = list(getattr(self.timeline, "spans", ()))
        return sum(end - start for start, end, what in spans if what in self.kinds)

    def __call__(self) -> float:
        return self._now() - self.person_s()


@dataclass
class Pace:
    """This queue's pace against the measured costs: the time its finished parts took over their costs."""

    took: float = 0.0
    cost: float = 0.0

    def add(self, took: float, cost: float | None) -> None:
        if cost is not None and cost > 0:
            self.took, self.cost = self.took + took, self.cost + cost

    def scale(self) -> float:
        return pace_scale(self.took, self.cost)


def queue_time_left(shoot_left: Sequence[float], deliver_s: float | None, deliveries: int, *,
                    pipelined: bool = True, shoot_pace: float = 1.0, deliver_pace: float = 1.0,
                    delivering_s: float = 0.0) -> float | None:
    """Seconds left of a queue (module docstring). ``shoot_left``: the shooting still to do per original not yet
    shot (the current one's rest first), measured costs; ``deliver_s``: one delivery's cost (None: unknown);
    ``deliveries``: deliveries not yet ended (those of originals shot and in flight included); ``delivering_s``:
    how long the delivery in flight has run (after the last original is shot). None when a delivery is due and
    its cost unknown."""
    shoot = [s * shoot_pace for s in shoot_left]
    if deliveries == 0:
        return float(sum(shoot))
    if deliver_s is None:
        return None
    deliver = deliver_s * deliver_pace
    if not pipelined:
        return float(sum(shoot) + deliveries * deliver - delivering_s)
    if not shoot:                                  # the last delivery (or two: N waits, then N+1)
        return max(deliveries * deliver - delivering_s, 0.0)
    # while each is shot the previous one is delivered: the longer of the two; the last delivery after them all
    return float(sum(max(s, deliver) for s in shoot) + deliver)


@dataclass
class _Original:
    clock: PhaseClock
    cost: float | None               # its shooting's measured (or planned) cost
    started: float
    shot_at: float | None = None


class QueueClock:
    """The time left of one queue run (module docstring); a core.engine.RunClock. ``plans``: each original's
    frames (app.workflow.day.queue_run.original_plan) in queue order; the queue's loop tells it what happens
    (:meth:`started`, :meth:`shot`, :meth:`delivered`, :meth:`kept`) and maps its progress (:meth:`fraction`)."""

    def __init__(self, plans: Sequence[Sequence[PlannedFrame]], costs: PhaseCosts | None = None, *,
                 settle_s: float = 0.2, overhead_s: float = DEFAULT_OVERHEAD_S, pipelined: bool = True,
                 now: Callable[[], float] = time.monotonic):
        self.costs = costs if costs is not None else PhaseCosts()
        self.time = ComputerTime(now)
        self.pipelined = pipelined
        self._phases = [original_phases(p, settle_s, overhead_s) for p in plans]
        self._measured = self.costs.load()
        self._lock = threading.Lock()
        self._originals: dict[int, _Original] = {}
        self._shot: set[int] = set()             # shot (or kept): nothing more to shoot
        self._ended: set[int] = set()            # delivered, failed or kept
        self._current: int | None = None
        self._within = 0.0                       # the current original's shooting done (0..1)
        self._fraction = 0.0
        self._last_shot_at: float | None = None
        self._delivered_s: list[float] = []
        self.shoot_pace, self.deliver_pace = Pace(), Pace()

    @property
    def total(self) -> int:
        return len(self._phases)

    def _cost(self, phase: Phase) -> float | None:
        measured = self.costs.expected(ORIGINAL_RUN, phase, self._measured)
        return measured if measured is not None else phase.plan_s

    def shoot_cost(self, i: int) -> float:
        """Original ``i``'s shooting (metering and frames): measured costs, else the plan's rough time."""
        return float(sum(self._cost(p) or 0.0 for p in self._phases[i] if p.name != "delivery"))

    def deliver_cost(self) -> float | None:
        """One delivery: the measured cost, else this queue's own deliveries' mean, else None."""
        delivery = next((p for p in self._phases[0] if p.name == "delivery"), None) if self._phases else None
        measured = self._cost(delivery) if delivery is not None else None
        if measured is not None:
            return measured
        return sum(self._delivered_s) / len(self._delivered_s) if self._delivered_s else None

    def expected_total_s(self) -> float | None:
        """The whole queue before it starts (the plan's estimate) when every phase of its originals has been
        measured; None otherwise."""
        with self._lock:
            if any(self.costs.expected(ORIGINAL_RUN, p, self._measured) is None for ps in self._phases for p in ps):
                return None
            return queue_time_left([self.shoot_cost(i) for i in range(self.total)], self.deliver_cost(), self.total,
                                   pipelined=self.pipelined)

    # ------------------------------------------------------------------ the queue's loop
    def started(self, i: int) -> None:
        """Original ``i`` starts (its checks and metering)."""
        with self._lock:
            clock = PhaseClock(ORIGINAL_RUN, self._phases[i], self.costs, now=self.time)
            clock.begin()
            self._originals[i] = _Original(clock, self.shoot_cost(i), self.time())
            self._current, self._within = i, 0.0

    def shot(self, i: int) -> None:
        """Original ``i``'s frames are all in (its delivery starts)."""
        with self._lock:
            o = self._originals.get(i)
            if o is None:
                return
            o.shot_at = self._last_shot_at = self.time()
            o.clock.time_left(ORIGINAL_FRAMES[1], now=o.shot_at)          # its delivery phase entered
            self.shoot_pace.add(o.shot_at - o.started, o.cost)
            self._shot.add(i)
            self._current = None

    def delivered(self, i: int, deliver_s: float | None) -> None:
        """Original ``i``'s delivery ended (``deliver_s``: its duration; None: it failed): its phases recorded."""
        with self._lock:
            o = self._originals.pop(i, None)
            self._ended.add(i)
            cost = self.deliver_cost()
            if deliver_s is not None:
                self.deliver_pace.add(deliver_s, cost)
                self._delivered_s.append(deliver_s)
        if o is not None and o.shot_at is not None:
            ok = deliver_s is not None
            o.clock.finish("done" if ok else "failed", now=o.shot_at + (deliver_s or 0.0))

    def kept(self, i: int) -> None:
        """Original ``i`` was delivered before and kept: nothing to shoot or deliver."""
        with self._lock:
            self._originals.pop(i, None)
            self._shot.add(i)
            self._ended.add(i)
            self._current = None

    def fraction(self, f: float) -> float:
        """The queue's progress from the current original's (its shooting: CopyStand.shoot's 0..0.8)."""
        with self._lock:
            o = self._originals.get(self._current) if self._current is not None else None
            if o is not None:
                o.clock.time_left(min(f, ORIGINAL_FRAMES[1] - 1e-6))   # metering, frames (delivery: shot())
                self._within = max(self._within, min(max(f, 0.0) / ORIGINAL_FRAMES[1], 1.0))
            n = max(self.total, 1)
            done = len(self._shot) + (self._within if self._current is not None else 0.0)
            q = 1.0 if len(self._ended) >= self.total else SHOOTING_SHARE * min(done / n, 1.0)
            self._fraction = max(self._fraction, q)
            return self._fraction

    # ------------------------------------------------------------------ core.engine.RunClock
    def begin(self) -> None:
        """The run starts (each original's clock begins when it does)."""

    def saw(self, event: Any) -> None:
        """Nothing in a run's events changes the queue's phases (metering's HDR frames show in the pace)."""

    def time_left(self, fraction: float) -> float | None:
        """Seconds left of the queue (``fraction``: the queue's own, :meth:`fraction`'s; the state is the loop's)."""
        with self._lock:
            rest = [i for i in range(self.total) if i not in self._shot]
            shoot = [self.shoot_cost(i) for i in rest]
            if shoot and self._current == rest[0]:
                shoot[0] *= 1.0 - self._within
            deliveries = sum(1 for i in range(self.total) if i not in self._ended)
            delivering = 0.0
            if not rest and self._last_shot_at is not None:
                delivering = max(self.time() - self._last_shot_at, 0.0)
            return queue_time_left(shoot, self.deliver_cost(), deliveries, pipelined=self.pipelined,
                                   shoot_pace=self.shoot_pace.scale(), deliver_pace=self.deliver_pace.scale(),
                                   delivering_s=delivering)

    def finish(self, outcome: str) -> None:
        """The run ended: originals still in flight record the phases they went through."""
        with self._lock:
            flying, self._originals = list(self._originals.values()), {}
        for o in flying:
            o.clock.finish(outcome if outcome != "done" else "failed")
