"""Time left from measured phase costs (Qt-free): what the window's bar and the CLI's progress lines say.

A long run (a calibration: auto-exposure, darks, flats, the targets, then the processing's steps and the report)
is a row of *phases*, each filling a known share ``lo..hi`` of the run's progress. :class:`PhaseClock` notes when the
run's progress enters each phase; when the run ends, every phase it saw from start to end is recorded in
:class:`PhaseCosts` (the last :data:`KEEP` durations per run and phase, ``phase_costs.json`` in the per-user data
folder the window and the CLI share: resources.user_path; written atomically).

The time left at a fraction is the remaining phases' costs: each one's measured cost (the median of its last
durations; per frame for the phases that shoot frames, times the frames planned now), else the plan's own estimate
for it, else the run's average pace over that phase's share. It is corrected as the run goes: the remaining costs
are scaled by how long this run's finished phases took against their costs, and inside the current phase its own
pace (its sub-steps: "report: figure 3 of 11") weighs more the further it is. The plan's up-front estimate
(:meth:`PhaseClock.expected_total_s`) is the sum of the same costs.

    clock = PhaseClock("calibration", phases, PhaseCosts())
    clock.begin()
    left = clock.time_left(0.42)          # seconds, or None while nothing is known
    clock.finish("done")                  # the phases' durations recorded for the next run
"""
from __future__ import annotations

import json
import logging
import statistics
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dualrgb.common.atomic_files import atomic_write
from dualrgb.common.strict_json import dumps as strict_dumps
from dualrgb.simulation.versions import stamped

log = logging.getLogger(__name__)

FORMAT = "dualrgb-phase-costs/1"
FILE_NAME = "phase_costs.json"
KEEP = 5                           # durations kept per run and phase (the median of these is the cost)
SCALE_LIMITS = (0.25, 4.0)         # how far this run's pace may rescale the measured costs
MIN_SCALE_BASIS_S = 1.0            # finished phases worth less than this say nothing of the run's pace


@dataclass(frozen=True)
class Phase:
    """One phase of a run: its ``name``, the share ``lo..hi`` of the run's progress it fills, the frames it shoots
    (``size``: its cost is measured per frame; None: one cost) and the plan's own estimate (``plan_s``: used until
    a duration is measured)."""

    name: str
    lo: float
    hi: float
    size: int | None = None
    plan_s: float | None = None


def default_path() -> Path:
    """``phase_costs.json`` in the per-user data folder (the window's and the CLI's)."""
    from dualrgb import resources

    return resources.user_path(FILE_NAME)


def pace_scale(took: float, cost: float, min_basis_s: float = 0.0) -> float:
    """How a run's finished parts compare with their measured costs: ``took / cost`` within SCALE_LIMITS; 1 when
    the costs are nothing or worth less than ``min_basis_s`` (too little to say anything of the pace)."""
    if cost <= 0 or cost < min_basis_s:
        return 1.0
    return min(max(took / cost, SCALE_LIMITS[0]), SCALE_LIMITS[1])


class PhaseCosts:
    """The measured durations of runs' phases, kept as JSON at ``path`` (default: :func:`default_path`). A damaged
    file is said in one log line and ignored (the next record writes a sound one)."""

    def __init__(self, path: Path | None = None, keep: int = KEEP):
        self.path = Path(path) if path is not None else default_path()
        self.keep = keep
        self._lock = threading.Lock()
        self._said: set[str] = set()           # what was said of a bad file already (once per store)

    def load(self) -> dict[str, dict[str, list[dict[str, Any]]]]:
        """Run -> phase -> its last durations ({"seconds", "size"}); {} when there is no file or it is damaged."""
        try:
            text = self.path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return {}
        except OSError as exc:
            self._say(f"{self.path}: not readable ({exc}); time left from the plan's estimates")
            return {}
        try:
            data = json.loads(text)
            runs = data["runs"] if data.get("format") == FORMAT else None
            if not isinstance(runs, dict):
                raise ValueError(f"expected a {FORMAT} object with 'runs'")
            return {run: {name: [_sample(s) for s in samples] for name, samples in phases.items()}
                    for run, phases in runs.items()}
        except (ValueError, TypeError, KeyError, AttributeError) as exc:
            self._say(f"{self.path}: damaged phase costs ignored ({exc}); time left from the plan's estimates")
            return {}

    def _say(self, line: str) -> None:
        if line not in self._said:
            self._said.add(line)
            log.warning("%s", line)

    def expected(self, run: str, phase: Phase, runs: dict | None = None) -> float | None:
        """The measured cost of ``phase`` in ``run`` (seconds), or None when none is measured: the median of its
        last durations, per frame times the frames planned for a phase that shoots frames."""
        samples = (self.load() if runs is None else runs).get(run, {}).get(phase.name, [])
        if phase.size is not None:
            per_frame = [s["seconds"] / s["size"] for s in samples if s.get("size")]
            return statistics.median(per_frame) * phase.size if per_frame else None
        values = [s["seconds"] for s in samples]
        return statistics.median(values) if values else None

    def record(self, run: str, durations: Sequence[tuple[Phase, float]]) -> None:
        """Add each phase's measured duration to ``run``'s (the last :attr:`keep` kept); written atomically."""
        if not durations:
            return
        with self._lock:
            runs = self.load()
            phases = runs.setdefault(run, {})
            for phase, seconds in durations:
                sample = {"seconds": round(float(seconds), 3), **({"size": phase.size} if phase.size else {})}
                phases[phase.name] = [*phases.get(phase.name, []), sample][-self.keep:]
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                atomic_write(self.path, strict_dumps(stamped(FORMAT, {"runs": runs}), indent=1))
            except (OSError, ValueError) as exc:    # a time estimate is never worth stopping a run for
                log.warning("%s: phase costs not saved (%s)", self.path, exc)


def _sample(raw: Any) -> dict[str, Any]:
    seconds = float(raw["seconds"])
    if not seconds >= 0.0:
        raise ValueError(f"a duration of {raw['seconds']!r} s")
    size = raw.get("size")
    return {"seconds": seconds, **({"size": int(size)} if size else {})}


class PhaseClock:
    """The time left of one run from its phases' costs (see the module docstring); thread-safe (the run's worker
    updates it, the window reads the estimate). ``record``: False for a run whose durations say nothing of the
    next (a calibration computed again from kept frames); ``replan``: the phases again from a new plan (the
    'plan' event's frames)."""

    def __init__(self, run: str, phases: Sequence[Phase], costs: PhaseCosts | None = None, *,
                 record: bool = True, replan: Callable[[list], Sequence[Phase]] | None = None,
                 now: Callable[[], float] = time.monotonic):
        self.run = run
        self.costs = costs if costs is not None else PhaseCosts()
        self.record = record
        self._replan = replan
        self._now = now
        self._lock = threading.Lock()
        self._measured = self.costs.load()
        self._set_phases(phases)
        self._t0: float | None = None
        self._fraction = 0.0
        self._entered: dict[int, float] = {}          # phase index -> when the progress entered it
        self._finished = False

    def _set_phases(self, phases: Sequence[Phase]) -> None:
        self.phases = sorted(phases, key=lambda p: p.lo)
        self._cost = [self._expected(p) for p in self.phases]

    def _expected(self, phase: Phase) -> float | None:
        measured = self.costs.expected(self.run, phase, self._measured)
        return measured if measured is not None else phase.plan_s

    # ------------------------------------------------------------------ the run
    def begin(self, now: float | None = None) -> None:
        """The run starts (its first phase entered)."""
        with self._lock:
            self._t0 = self._now() if now is None else now
            self._entered = {0: self._t0} if self.phases else {}
            self._fraction = 0.0

    def saw(self, event: Any) -> None:
        """A run's event: a new plan (``data['plan']``: the frames after auto-exposure) re-plans the phases."""
        plan = getattr(event, "data", {}).get("plan")
        if plan is not None and self._replan is not None:
            with self._lock:
                self._set_phases(self._replan(list(plan)))

    def time_left(self, fraction: float, now: float | None = None) -> float | None:
        """Seconds left at ``fraction`` of the run done; None while nothing is known to say."""
        with self._lock:
            t = self._now() if now is None else now
            if self._t0 is None:
                self._t0 = t
                self._entered = {0: t} if self.phases else {}
            self._fraction = max(self._fraction, min(max(fraction, 0.0), 1.0))
            self._enter(self._fraction, t)
            return self._left(t)

    def finish(self, outcome: str, now: float | None = None) -> None:
        """The run ended: the phases it went through from start to end recorded (all of them when it is 'done')."""
        with self._lock:
            if self._finished or self._t0 is None:
                return
            self._finished = True
            t = self._now() if now is None else now
            durations = self.durations(t if outcome == "done" else None)
        if self.record:
            self.costs.record(self.run, durations)

    def durations(self, end: float | None) -> list[tuple[Phase, float]]:
        """Each phase entered and left (the last one left at ``end`` when given) with its duration."""
        out = []
        for i, phase in enumerate(self.phases):
            start = self._entered.get(i)
            stop = self._entered.get(i + 1, end if i == len(self.phases) - 1 else None)
            if start is not None and stop is not None:
                out.append((phase, max(stop - start, 0.0)))
        return out

    def expected_total_s(self) -> float | None:
        """The whole run from the phases' costs (the plan's estimate); None when a phase has none."""
        with self._lock:
            return None if any(c is None for c in self._cost) else float(sum(c or 0.0 for c in self._cost))

    # ------------------------------------------------------------------ the estimate
    def _enter(self, fraction: float, t: float) -> None:
        for i, phase in enumerate(self.phases):
            if i not in self._entered and fraction >= phase.lo:
                self._entered[i] = t

    def _current(self) -> int:
        return max(self._entered, default=0)

    def _scale(self, k: int) -> float:
        """This run's pace against the costs: its finished phases' time over their costs (clamped)."""
        took = cost = 0.0
        for i in range(k):
            c, start, stop = self._cost[i], self._entered.get(i), self._entered.get(i + 1)
            if c is not None and start is not None and stop is not None:
                took, cost = took + (stop - start), cost + c
        return pace_scale(took, cost, MIN_SCALE_BASIS_S)

    def _left(self, t: float) -> float | None:
        if not self.phases or self._t0 is None:
            return None
        f, k = self._fraction, self._current()
        pace = (t - self._t0) / f if f > 0 else None          # seconds per unit of progress, the run so far
        scale = self._scale(k)
        left = 0.0
        for i in range(k, len(self.phases)):
            phase, cost = self.phases[i], self._cost[i]
            if i == k:
                part = self._in_phase(phase, cost, scale, t - self._entered.get(k, t), pace)
            else:
                part = cost * scale if cost is not None else (pace * (phase.hi - phase.lo) if pace else None)
            if part is None:
                return None
            left += part
        return left

    def _in_phase(self, phase: Phase, cost: float | None, scale: float, spent: float, pace: float | None
                  ) -> float | None:
        """The rest of the current phase: its cost less the time spent in it, weighed with its own pace (its
        sub-steps) the further it is."""
        width = max(phase.hi - phase.lo, 1e-9)
        within = min(max((self._fraction - phase.lo) / width, 0.0), 1.0)
        own = spent * (1.0 - within) / within if within > 0 else None
        if cost is None:
            return own if own is not None else (pace * (phase.hi - self._fraction) if pace else None)
        planned = max(cost * scale - spent, 0.0)
        return planned if own is None else (1.0 - within) * planned + within * own
