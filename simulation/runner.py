"""One simulation run as the CLI, the GUI and the studies request it: method and objective in, JSON-ready
result out.

Defaults (issues 12 and 14): the method is successive halving over the thesis PSO with an L-BFGS-B polish
(:mod:`simulation.halving`, the fastest particle swarm that reaches the best known optimum), the objective the
expected captured training error (:mod:`simulation.expected_error`). They combine by swapping the evaluator:
every method optimises whichever objective it is handed, the polish included, and every reported candidate
carries both figures (noise-free and expected captured) whatever was optimised. ``--method pso`` with
``--objective noise-free`` is exactly the thesis' Algorithm 1 on the thesis' cost.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from dualrgb.common.progress import CancelToken, ProgressCallback, check
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.choices import DEFAULT_SPECTRAL_WEIGHT, METHODS, OBJECTIVES, SPECTRAL_OBJECTIVES
from dualrgb.simulation.datasets import SimulationSetup
from dualrgb.simulation.expected_error import ExpectedErrorEvaluator
from dualrgb.simulation.ga import GaSettings, ga
from dualrgb.simulation.halving import HalvingSettings, successive_halving
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.objective import Evaluator, three_channel
from dualrgb.simulation.presets import Preset
from dualrgb.simulation.pso import PsoSettings, pso
from dualrgb.simulation.robust import RobustEvaluator, RobustSettings
from dualrgb.simulation.search import DEFAULT_BINS, SearchOutcome, add_incumbents, exhaustive, light_pairs, refine_top
from dualrgb.simulation.warmup import warm_up

log = logging.getLogger(__name__)

DEFAULT_METHOD = METHODS[0]                 # "halving"
DEFAULT_OBJECTIVE = OBJECTIVES[0]           # "expected-captured"


def make_evaluator(setup: SimulationSetup, objective: str = DEFAULT_OBJECTIVE,
                   capture: CaptureModel | None = None, robust: RobustSettings = RobustSettings(),
                   spectral_weight: float = DEFAULT_SPECTRAL_WEIGHT, per_pixel: bool = False) -> Evaluator:
    """The evaluator of ``objective``; ``capture`` defaults to the virtual lab's capture in the setup's mode;
    ``spectral_weight``: the mixed objective's weight (simulation.spectral_objective); ``per_pixel``: the
    expected-captured and robust objectives score one pixel of each patch instead of the patch mean (the
    objective 'expected-per-pixel' is expected-captured with it)."""
    if objective not in OBJECTIVES:
        raise ValueError(f"objective {objective!r}: expected one of {', '.join(OBJECTIVES)}")
    if objective == "noise-free":
        return Evaluator(setup)
    capture = capture or CaptureModel.virtual_lab(setup.mode)
    if objective == "robust":
        return RobustEvaluator(setup, capture, robust, per_pixel=per_pixel)
    if objective in SPECTRAL_OBJECTIVES:
        from dualrgb.simulation.spectral_objective import SpectralEvaluator, SpectralObjectiveSettings

        return SpectralEvaluator(setup, capture, SpectralObjectiveSettings(spectral_weight=spectral_weight),
                                 mixed=objective == "mixed")
    return ExpectedErrorEvaluator(setup, capture, per_pixel=per_pixel or objective == "expected-per-pixel")


@dataclass
class RunResult:
    mode: str
    method: str
    seed: int | None
    elapsed_s: float
    evaluations: int
    three_channel: dict
    outcome: SearchOutcome | None
    setup: SimulationSetup
    top: int = 10
    extra: dict = field(default_factory=dict)
    objective: str = DEFAULT_OBJECTIVE
    capture: CaptureModel | None = None

    def to_json(self) -> dict:
        results = [c.to_dict() for c in self.outcome.candidates[:self.top]] if self.outcome else []
        return {"mode": self.mode, "method": self.method, "objective": self.objective, "seed": self.seed,
                "elapsed_s": round(self.elapsed_s, 4), "evaluations": self.evaluations,
                "three_channel": self.three_channel, "results": results,
                "history": self.outcome.history if self.outcome else [],
                "settings": self.outcome.settings if self.outcome else {}, "setup": self.setup.describe(),
                **({"capture": self.capture.to_dict()} if self.capture else {}), **self.extra}

    def preset(self, rank: int = 0, name: str | None = None) -> Preset:
        if self.outcome is None:
            raise ValueError("the three-channel baseline has no light pair to save as a preset")
        cand = self.outcome.candidates[rank]
        errors = {"train": cand.train.to_dict() if cand.train else {"mean": cand.train_cost},
                  "test": cand.test.to_dict() if cand.test else {}}
        if cand.expected_train is not None:
            errors["expected_captured"] = {"train": cand.expected_train.to_dict(),
                                           "test": cand.expected_test_errors.to_dict()}
        if cand.per_pixel is not None:
            errors["per_pixel"] = {k: cand.per_pixel[k] for k in ("train", "test")}
        if cand.spectral is not None:
            errors["expected_spectral_rmse"] = cand.spectral
        model = {"grid": self.setup.grid.label(), "camera": self.setup.camera_name, "observer": "CIE 1931 2°",
                 "illuminant": "D65", "objective": self.objective, **(self.outcome.settings or {})}
        if self.capture is not None:
            model["capture"] = self.capture.to_dict()
        if "spectral_objective" in self.extra:
            model["spectral_objective"] = self.extra["spectral_objective"]
        return Preset(
            name=name or f"{self.mode} {self.method} " + " + ".join(s.label() for s in cand.sources),
            sources=tuple(type(s)(s.leds, s.levels, f"source {i}") for i, s in enumerate(cand.sources, start=1)),
            method=self.method, seed=self.seed, mode=self.mode, errors=errors,
            dataset={"train": self.setup.train.name, "test": self.setup.test.name}, model=model)


def run(setup: SimulationSetup, method: str = DEFAULT_METHOD, seed: int = 0, top: int = 10,
        bins: Sequence[int] = DEFAULT_BINS, pso_settings: PsoSettings = PsoSettings(),
        ga_settings: GaSettings = GaSettings(), halving_settings: HalvingSettings = HalvingSettings(),
        progress: ProgressCallback | None = None, cancel: CancelToken | None = None,
        evaluator: Evaluator | None = None, objective: str = DEFAULT_OBJECTIVE,
        capture: CaptureModel | None = None, robust: RobustSettings = RobustSettings(),
        spectral_weight: float = DEFAULT_SPECTRAL_WEIGHT,
        incumbents: Sequence[Sequence[LightSource]] = (), per_pixel: bool = False) -> RunResult:
    """``evaluator``: one built on ``setup`` for ``objective`` (make_evaluator) to use instead of a new one (the
    GUI passes one that reports the best cost so far for its live convergence plot). ``elapsed_s`` excludes the
    kernels' one-off compile (``extra["kernel_warm_up_s"]``; simulation.warmup). ``incumbents``: light sets
    already in use, ranked among the search's candidates (simulation.search.add_incumbents)."""
    if method not in METHODS:
        raise ValueError(f"method {method!r}: expected one of {', '.join(METHODS)}")
    t0 = time.perf_counter()
    tr, te, _ = three_channel(setup)
    baseline = {"train": round(float(tr.mean()), 4), "test": round(float(te.mean()), 4)}
    if method == "three-channel":
        return RunResult(setup.mode, method, None, time.perf_counter() - t0, 1, baseline, None, setup, top,
                         objective="noise-free")
    evaluator = evaluator if evaluator is not None else make_evaluator(setup, objective, capture, robust,
                                                                       spectral_weight, per_pixel)
    objective = getattr(evaluator, "objective", objective)
    given, capture = capture, getattr(evaluator, "capture", None)
    base = getattr(evaluator, "base", evaluator)          # a GUI tap wraps the evaluator
    warm_s = warm_up(base, progress)            # the one-off kernel compile is not part of the run's time
    if hasattr(base, "warm_up_kernels"):
        warm_s += base.warm_up_kernels()
    groups = light_pairs(bins)
    if method == "exhaustive":
        outcome = exhaustive(evaluator, groups, progress=progress, cancel=cancel)
    elif method == "pso":
        outcome = pso(evaluator, groups, pso_settings, seed, progress=progress, cancel=cancel)
    elif method == "ga":
        outcome = ga(evaluator, groups, ga_settings, seed, progress=progress, cancel=cancel)
    else:
        outcome = successive_halving(evaluator, groups, halving_settings, seed, progress=progress, cancel=cancel)
    check(cancel)
    if incumbents:
        add_incumbents(evaluator, outcome, incumbents)
    expected = None
    if capture is None:          # a noise-free search: report the expected captured figures too (the sphere given)
        capture = given or CaptureModel.virtual_lab(setup.mode)
        expected = ExpectedErrorEvaluator(setup, capture)
    refine_top(evaluator, outcome, max(top, 1), expected, cancel=cancel)
    return RunResult(setup.mode, method, outcome.seed, time.perf_counter() - t0 - warm_s, outcome.evaluations,
                     baseline, outcome, setup, top, extra={"kernel_warm_up_s": round(warm_s, 3),
                                                           **_spectral_settings(base)},
                     objective=objective, capture=capture)


def _spectral_settings(evaluator: Evaluator) -> dict:
    """A spectral objective's own settings for the JSON and the preset: the estimate, its prior, the weight."""
    spectral, settings = getattr(evaluator, "spectral", None), getattr(evaluator, "settings", None)
    if spectral is None or settings is None:
        return {}
    return {"spectral_objective": {"estimate": "wiener", "prior": spectral.prior.to_dict(),
                                   "spectral_weight": settings.spectral_weight,
                                   "figure": "expected captured spectral RMSE, pooled over the target's patches "
                                             "and the grid's wavelengths"}}


SPECTRAL_LEGEND = ("sp.tr/sp.te: expected captured spectral RMSE (reflectance or transmittance factor, 0.01 = 1 %) "
                   "of the Wiener estimate, pooled over the target's patches and 410-780 nm")


def format_table(result: RunResult) -> str:
    """The CLI's table; light sources with their exact-enough levels (lightsource.format_level), the noise-free
    and the expected captured errors."""
    lines = [f"{result.mode} / {result.method} / {result.objective}"
             + (f" / seed {result.seed}" if result.seed is not None else "")
             + f": {result.evaluations} evaluations in {result.elapsed_s:.2f} s",
             f"3-channel (D65) baseline: train {result.three_channel['train']:.3f}  "
             f"test {result.three_channel['test']:.3f} mean dE00 (noise-free)"]
    if result.outcome:
        rows = [([s.label() for s in c.sources[:2]], c) for c in result.outcome.candidates[:result.top]]
        w1 = max([len("light source 1")] + [len(r[0][0]) for r in rows])
        w2 = max([len("light source 2")] + [len(r[0][-1]) for r in rows])
        spectral = any(c.spectral for _, c in rows)
        pixel = any(c.per_pixel for _, c in rows)
        lines.append(f"{'#':>3}  {'light source 1':<{w1}} {'light source 2':<{w2}} {'train':>7} {'test':>7}"
                     f" {'exp.tr':>7} {'exp.te':>7}" + (f" {'px.tr':>7} {'px.te':>7} {'px.p90':>7}" if pixel else "")
                     + (f" {'sp.tr':>7} {'sp.te':>7}" if spectral else ""))
        for i, ((s1, *rest), c) in enumerate(rows, start=1):
            s2 = rest[0] if rest else ""
            exp = (f" {c.expected_train.mean:>7.3f} {c.expected_test_errors.mean:>7.3f}" if c.expected_train else "")
            if c.per_pixel:
                exp += (f" {c.per_pixel['train']['mean']:>7.3f} {c.per_pixel['test']['mean']:>7.3f}"
                        f" {c.per_pixel['test']['p90']:>7.3f}")
            if c.spectral:
                exp += f" {c.spectral['train']['rmse']:>7.4f} {c.spectral['test']['rmse']:>7.4f}"
            lines.append(f"{i:>3}  {s1:<{w1}} {s2:<{w2}} {c.train_errors.mean:>7.3f} {c.test_errors.mean:>7.3f}{exp}")
        lines.append("train/test: noise-free simulation; exp.tr/exp.te: expected captured ("
                     + (result.capture.label() if result.capture else "") + "), patch means"
                     + ("; px.tr/px.te/px.p90: per pixel (the matrix on single pixels: mean, test 90th percentile)"
                        if pixel else ""))
        if spectral:
            lines.append(SPECTRAL_LEGEND)
    return "\n".join(lines)
