"""One simulation run as the CLI, the GUI and the studies request it: method in, JSON-ready result out."""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Optional, Sequence

from simulation.choices import METHODS
from simulation.datasets import SimulationSetup
from simulation.ga import GaSettings, ga
from simulation.objective import Evaluator, three_channel
from simulation.presets import Preset
from simulation.progress import CancelToken, ProgressCallback
from simulation.pso import PsoSettings, pso
from simulation.search import DEFAULT_BINS, SearchOutcome, exhaustive, light_pairs, refine_top
from simulation.warmup import warm_up

log = logging.getLogger(__name__)



@dataclass
class RunResult:
    mode: str
    method: str
    seed: Optional[int]
    elapsed_s: float
    evaluations: int
    three_channel: dict
    outcome: Optional[SearchOutcome]
    setup: SimulationSetup
    top: int = 10
    extra: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        results = [c.to_dict() for c in self.outcome.candidates[:self.top]] if self.outcome else []
        return {"mode": self.mode, "method": self.method, "seed": self.seed, "elapsed_s": round(self.elapsed_s, 4),
                "evaluations": self.evaluations, "three_channel": self.three_channel, "results": results,
                "history": self.outcome.history if self.outcome else [],
                "settings": self.outcome.settings if self.outcome else {}, "setup": self.setup.describe(),
                **self.extra}

    def preset(self, rank: int = 0, name: Optional[str] = None) -> Preset:
        if self.outcome is None:
            raise ValueError("the three-channel baseline has no light pair to save as a preset")
        cand = self.outcome.candidates[rank]
        return Preset(
            name=name or f"{self.mode} {self.method} " + " + ".join(s.label() for s in cand.sources),
            sources=tuple(type(s)(s.leds, s.levels, f"source {i}") for i, s in enumerate(cand.sources, start=1)),
            method=self.method, seed=self.seed, mode=self.mode,
            errors={"train": cand.train.to_dict() if cand.train else {"mean": cand.train_cost},
                    "test": cand.test.to_dict() if cand.test else {}},
            dataset={"train": self.setup.train.name, "test": self.setup.test.name},
            model={"grid": self.setup.grid.label(), "camera": self.setup.camera_name, "observer": "CIE 1931 2°",
                   "illuminant": "D65", **(self.outcome.settings or {})},
        )


def run(setup: SimulationSetup, method: str, seed: int = 0, top: int = 10, bins: Sequence[int] = DEFAULT_BINS,
        pso_settings: PsoSettings = PsoSettings(), ga_settings: GaSettings = GaSettings(),
        progress: Optional[ProgressCallback] = None, cancel: Optional[CancelToken] = None,
        evaluator: Optional[Evaluator] = None) -> RunResult:
    """``evaluator``: an Evaluator built on ``setup`` to use instead of a new one (the GUI passes a subclass
    that reports the best cost so far for its live convergence plot). ``elapsed_s`` excludes the kernels'
    one-off compile (``extra["kernel_warm_up_s"]``; simulation.warmup)."""
    if method not in METHODS:
        raise ValueError(f"method {method!r}: expected one of {', '.join(METHODS)}")
    t0 = time.perf_counter()
    tr, te, _ = three_channel(setup)
    baseline = {"train": round(float(tr.mean()), 4), "test": round(float(te.mean()), 4)}
    if method == "three-channel":
        return RunResult(setup.mode, method, None, time.perf_counter() - t0, 1, baseline, None, setup, top)
    evaluator = evaluator if evaluator is not None else Evaluator(setup)
    warm_s = warm_up(evaluator, progress)      # the one-off kernel compile is not part of the run's time
    groups = light_pairs(bins)
    if method == "exhaustive":
        outcome = exhaustive(evaluator, groups, progress=progress, cancel=cancel)
    elif method == "pso":
        outcome = pso(evaluator, groups, pso_settings, seed, progress=progress, cancel=cancel)
    else:
        outcome = ga(evaluator, groups, ga_settings, seed, progress=progress, cancel=cancel)
    refine_top(evaluator, outcome, max(top, 1))
    return RunResult(setup.mode, method, outcome.seed, time.perf_counter() - t0 - warm_s, outcome.evaluations,
                     baseline, outcome, setup, top, extra={"kernel_warm_up_s": round(warm_s, 3)})


def format_table(result: RunResult) -> str:
    """The CLI's table; light sources with their exact-enough levels (lightsource.format_level)."""
    lines = [f"{result.mode} / {result.method}" + (f" / seed {result.seed}" if result.seed is not None else "")
             + f": {result.evaluations} evaluations in {result.elapsed_s:.2f} s",
             f"3-channel (D65) baseline: train {result.three_channel['train']:.3f}  "
             f"test {result.three_channel['test']:.3f} mean dE00"]
    if result.outcome:
        rows = [([s.label() for s in c.sources[:2]], c) for c in result.outcome.candidates[:result.top]]
        w1 = max([len("light source 1")] + [len(r[0][0]) for r in rows])
        w2 = max([len("light source 2")] + [len(r[0][-1]) for r in rows])
        lines.append(f"{'#':>3}  {'light source 1':<{w1}} {'light source 2':<{w2}} {'train':>7} {'test':>7}")
        for i, ((s1, *rest), c) in enumerate(rows, start=1):
            s2 = rest[0] if rest else ""
            lines.append(f"{i:>3}  {s1:<{w1}} {s2:<{w2}} {c.train.mean:>7.3f} {c.test.mean:>7.3f}")
    return "\n".join(lines)
