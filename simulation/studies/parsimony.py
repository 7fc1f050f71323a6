"""The simplest choices that cost no accuracy, per target mode (``dualrgb study parsimony``).

Three questions, each answered automatically with a tolerance (default 0.05 mean dE00), each on *training* data
only (the test target is reported beside every choice, never used to make it):

1. Spectral grid: start and step. The reference is 1 nm over 380-780 nm, the widest range the packaged data cover
   (LEDs, camera and targets all start at 380 nm; the thesis starts at 410 nm because its measured film data did,
   thesis 4.5 and Table 4.3). At each candidate grid the full-intensity exhaustive search and the default
   optimiser (successive halving over PSO + L-BFGS-B, noise-free cost: nearly seed-independent, so the
   comparison is not one PSO run's luck) pick their optimum; both optima are re-evaluated on the reference. A
   grid is acceptable when the optimum it picks is within the tolerance of the reference's optimum *on the
   reference*, and its own error estimate is within the tolerance of that re-evaluation (training errors). The
   thesis' 410-780 nm at 10 nm is kept when acceptable (it reproduces the thesis); otherwise the acceptable grid
   with the fewest wavelengths is chosen. The cost of each grid is measured beside its accuracy (CPU time, best
   of ``timing_repeats``): setting up the evaluators (resampling, per-LED responses), microseconds per evaluation
   of the noise-free and the expected-captured objectives, and one optimiser run.
2. Characterisation model (linear 6x3, dE-optimised 6x3, root-polynomial degree 2 with 21 terms): fitted on
   simulated captures (noise model of :mod:`.noise`) of the training target under the mode's light sets
   (:mod:`.lights`: the packaged presets) and judged by 5-fold cross-validation on the captured *training*
   target (simulation.cross_validation, the rule the processing chooses its delivered matrix by). The simplest
   model the processing can deliver (``DELIVERED``: least squares or dE-optimised) within the tolerance of the
   best deliverable one is chosen; root-polynomial is reported beside them (the processing does not fit it).
3. HDR exposures per light (1-4, geometric from the open-gate exposure to 100x, i.e. an ND 2.0 filter over
   half the patches as thesis 8.3): cross-validated training error of simulated captures with the filter, under
   the same light sets,
   merged with the HDR estimator ``dualrgb study hdr`` chose for the mode. The fewest exposures within the
   tolerance of the best bracket are chosen.

Each mode gets its own answers (``parsimony.json``, format ``dualrgb-parsimony/2``, one entry per mode);
:mod:`simulation.defaults` reads the user's copy (``--write-defaults`` puts it in the per-user data folder,
``resources.user_path``) when there is one, else the packaged ``resources/parsimony.json`` from the reference run.
Charts and the summary: :mod:`.parsimony_report`.
"""
from __future__ import annotations

import datetime as _dt
import logging
import time
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.halving import HalvingSettings, successive_halving
from dualrgb.simulation.hdr_estimators import default_method
from dualrgb.simulation.pso import PsoSettings
from dualrgb.simulation.search import exhaustive, group_arrays, light_pairs
from dualrgb.simulation.studies.common import SetupSpec, evaluator_for
from dualrgb.simulation.studies.lights import study_lights
from dualrgb.simulation.studies.models import MODEL_TERMS, MODELS
from dualrgb.simulation.studies.noise import CameraNoise, NoiseModel

log = logging.getLogger(__name__)

THESIS_GRID = (410.0, 10.0)          # (start nm, step nm): thesis 4.5
GRID_END_NM = 780.0
DELIVERED = ("linear", "de-optimised")     # the models app.processing.characterise fits (least squares, dE00)


@dataclass(frozen=True)
class ParsimonyConfig:
    grids: tuple[tuple[float, float], ...] = ((410.0, 10.0), (410.0, 1.0), (380.0, 20.0), (380.0, 10.0),
                                              (380.0, 5.0), (380.0, 1.0))      # (start, step), nm
    reference: tuple[float, float] = (380.0, 1.0)
    tolerance: float = 0.05
    optimiser: HalvingSettings = HalvingSettings()
    pso: PsoSettings = PsoSettings(particles=100, iterations=10)     # light sets of a user's own data (.lights)
    light_sets: int | None = None
    exposures: tuple[int, ...] = (1, 2, 3, 4)
    exposure_span: float = 100.0                 # ND 2.0
    nd_transmittance: float = 0.01
    repeats: int = 6
    folds: int = 5
    timing_batch: int = 4096                     # candidates per timed objective evaluation
    timing_repeats: int = 5                      # CPU time: the best of these (the machine is shared)
    camera: CameraNoise = CameraNoise()

    @classmethod
    def tiny(cls) -> ParsimonyConfig:
        return cls(grids=((410.0, 20.0), (410.0, 10.0)), reference=(410.0, 10.0),
                   optimiser=HalvingSettings(particles=8, min_sets=2, polish_sets=1, polish_iterations=2),
                   pso=PsoSettings(particles=8, iterations=2), light_sets=8, exposures=(1, 2), repeats=2,
                   timing_batch=256, timing_repeats=2)


def _choose(errors: list[float], tolerance: float) -> tuple[int, float]:
    """Index of the first (simplest) option within ``tolerance`` of the best error, and that best error."""
    best = float(min(errors))
    for i, e in enumerate(errors):
        if e <= best + tolerance:
            return i, best
    return int(np.argmin(errors)), best          # pragma: no cover (the best always qualifies)


def _at_grid(spec: SetupSpec, grid: tuple[float, float]) -> SetupSpec:
    """The spec on the (start, step) grid up to 780 nm (SpectralGrid stops at the last whole step)."""
    return replace(spec, start=grid[0], step=grid[1], end=GRID_END_NM)


def _grid_label(grid: tuple[float, float]) -> str:
    return f"{grid[0]:g}-{GRID_END_NM:g}/{grid[1]:g}"


def _cpu_seconds(fn, repeats: int) -> float:
    """The least CPU time (all threads of this process) of ``repeats`` calls: robust to other jobs' load."""
    best = float("inf")
    for _ in range(repeats):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def _timings(spec: SetupSpec, cfg: ParsimonyConfig) -> dict:
    """Cost of a grid: CPU time to set up both evaluators (resampling, per-LED responses) and microseconds per
    evaluation of the noise-free and expected-captured objectives on one batch of random levels (kernels warmed
    first)."""
    from dualrgb.simulation.datasets import default_setup
    from dualrgb.simulation.expected_error import ExpectedErrorEvaluator
    from dualrgb.simulation.objective import Evaluator

    capture = CaptureModel.virtual_lab(spec.mode)
    setup = default_setup(spec.mode, spec.grid)
    ev = evaluator_for(spec)
    ex = ExpectedErrorEvaluator(ev.setup, capture)
    out = {"setup_noise_free_s": _cpu_seconds(lambda: Evaluator(setup), cfg.timing_repeats),
           "setup_expected_s": _cpu_seconds(lambda: ExpectedErrorEvaluator(setup, capture), cfg.timing_repeats)}
    groups = light_pairs()
    idx, mask = group_arrays([groups[i % len(groups)] for i in range(cfg.timing_batch)])
    w = np.random.default_rng(0).random(mask.shape) * mask
    for key, evaluator in (("noise_free", ev), ("expected", ex)):
        evaluator.cost_indexed(idx[:8], w[:8])                     # compile / warm the kernels
        seconds = _cpu_seconds(lambda e=evaluator: e.cost_indexed(idx, w), cfg.timing_repeats)
        out[f"{key}_us_per_evaluation"] = 1e6 * seconds / cfg.timing_batch
    return out


def _grid_row(spec: SetupSpec, grid: tuple[float, float], ref_ev, cfg: ParsimonyConfig, groups) -> dict:
    """One grid: its exhaustive and optimiser optima (own estimate and on the reference), their CPU times."""
    gspec = _at_grid(spec, grid)
    row: dict[str, Any] = {"start_nm": grid[0], "step_nm": grid[1], "label": _grid_label(grid),
                           "thesis_grid": grid == THESIS_GRID, **_timings(gspec, cfg)}
    ev = evaluator_for(gspec)
    row.update(grid=ev.setup.grid.label(), wavelengths=len(ev.setup.grid))
    t0 = time.process_time()
    ex = exhaustive(ev, groups)
    row["exhaustive_s"] = time.process_time() - t0
    t0 = time.process_time()
    opt = successive_halving(ev, groups, cfg.optimiser, seed=0)
    row.update(optimiser_s=time.process_time() - t0, optimiser_evaluations=opt.evaluations)
    for key, cand in (("exhaustive", ex.best), ("optimiser", opt.best)):
        W = cand.weights(ev.n_leds)
        own, on_ref = ev.stats(W), ref_ev.stats(W)
        row[key] = {"pair": [list(s.leds) for s in cand.sources],
                    "levels": [[round(v, 4) for v in s.levels] for s in cand.sources],
                    "own_train": own[0].mean, "own_test": own[1].mean,
                    "ref_train": on_ref[0].mean, "ref_test": on_ref[1].mean}
    row["_costs"] = np.asarray([c.train_cost for c in sorted(ex.candidates, key=lambda c: tuple(
        tuple(s.leds) for s in c.sources))])
    return row


def spectral_grids(spec: SetupSpec, cfg: ParsimonyConfig, cancel=None, progress=None) -> dict:
    """Question 1 for ``spec.mode``: every grid of ``cfg.grids`` against ``cfg.reference`` (module docstring)."""
    grids = list(dict.fromkeys([cfg.reference, *cfg.grids]))
    ref_ev = evaluator_for(_at_grid(spec, cfg.reference))
    groups = light_pairs()[:cfg.light_sets] if cfg.light_sets else light_pairs()
    rows = []
    for i, grid in enumerate(grids):
        check(cancel)
        rows.append(_grid_row(spec, grid, ref_ev, cfg, groups))
        report(progress, 0.4 * (i + 1) / len(grids), f"parsimony ({spec.mode}): grid {_grid_label(grid)}")
    ref = rows[0]
    ref_costs = ref["_costs"]
    rb = np.argsort(np.argsort(ref_costs))
    for row in rows:
        costs = row.pop("_costs")
        ra = np.argsort(np.argsort(costs))
        row["full_intensity_vs_ref"] = {"max_abs_diff": float(np.abs(costs - ref_costs).max()),
                                        "rank_correlation": float(np.corrcoef(ra, rb)[0, 1])}
        dev = []
        for key in ("exhaustive", "optimiser"):
            dev.append(abs(row[key]["ref_train"] - ref[key]["ref_train"]))    # the choice, judged on the reference
            dev.append(abs(row[key]["own_train"] - row[key]["ref_train"]))    # the grid's own estimate
        row["deviation"] = float(max(dev))
        row["acceptable"] = bool(row["deviation"] <= cfg.tolerance)
    ok = [r for r in rows if r["acceptable"]]
    thesis = next((r for r in rows if r["thesis_grid"]), None)
    if thesis is not None and thesis["acceptable"]:
        chosen = thesis                               # accurate enough, and it reproduces the thesis
    else:
        chosen = min(ok, key=lambda r: r["wavelengths"]) if ok else ref
    return {"reference": {"start_nm": cfg.reference[0], "step_nm": cfg.reference[1], "end_nm": GRID_END_NM},
            "rows": rows, "chosen": {"start_nm": chosen["start_nm"], "step_nm": chosen["step_nm"],
                                     "end_nm": GRID_END_NM, "label": chosen["label"]},
            "thesis_grid_acceptable": bool(thesis["acceptable"]) if thesis else None,
            "criterion": f"training mean dE00 (noise-free) of the exhaustive and optimiser optima re-evaluated on "
                         f"the reference grid {_grid_label(cfg.reference)} nm; the thesis grid when within "
                         f"{cfg.tolerance}, else the coarsest grid within it"}


def _nd(n: int, transmittance: float) -> np.ndarray:
    """ND filter over the first half of the patches (thesis 8.3 covers half the chart)."""
    t = np.ones(n)
    t[: n // 2] = transmittance
    return t


def characterisation_models(spec: SetupSpec, cfg: ParsimonyConfig, lights: dict, cancel=None) -> dict:
    """Question 2: captured training CV (criterion) and test (reported) per model and light set."""
    ev = evaluator_for(spec)
    model = NoiseModel(ev.setup, cfg.camera)
    rows = {}
    for name, W in lights.items():
        check(cancel)
        cap = model.captured_errors(W, cfg.repeats, models=MODELS, folds=cfg.folds)
        rows[name] = {"captured": cap["models"], "noise_free": _noise_free_models(ev, W)}
    worst = {m: max(rows[n]["captured"][m]["cv"] for n in lights) for m in MODELS}
    test = {m: max(rows[n]["captured"][m]["test"] for n in lights) for m in MODELS}
    idx, best = _choose([worst[m] for m in DELIVERED], cfg.tolerance)
    return {"light_sets": {k: [list(np.nonzero(w)[0] + 1) for w in W] for k, W in lights.items()},
            "terms": {m: MODEL_TERMS[m](6) for m in MODELS}, "results": rows,
            "criterion": f"captured training mean dE00, {cfg.folds}-fold cross-validation (worst over the light "
                         "sets), among the models the processing delivers; the test target is reported only",
            "candidates": list(DELIVERED), "scores": worst, "test_reported": test, "best": best,
            "chosen": DELIVERED[idx]}


def hdr_exposures(spec: SetupSpec, cfg: ParsimonyConfig, lights: dict, cancel=None, progress=None) -> dict:
    """Question 3: ND 2.0 over half the patches, brackets of 1..4 exposures, captured training CV per bracket."""
    ev = evaluator_for(spec)
    model = NoiseModel(ev.setup, cfg.camera)
    nd = {key: _nd(len(t), cfg.nd_transmittance) for key, t in (("train", ev.setup.train), ("test", ev.setup.test))}
    merge = default_method(spec.mode)
    rows = []
    for k, n_exp in enumerate(cfg.exposures):
        check(cancel)
        factors = tuple(np.geomspace(1.0, cfg.exposure_span, n_exp)) if n_exp > 1 else (1.0,)
        row: dict[str, Any] = {"exposures": n_exp, "factors": [round(f, 3) for f in factors]}
        for name, W in lights.items():
            with_nd = model.captured_errors(W, cfg.repeats, factors=factors, nd=nd, hdr_method=merge,
                                            folds=cfg.folds)
            without = model.captured_errors(W, max(2, cfg.repeats // 2), factors=factors, hdr_method=merge)
            row[name] = {"nd_train": with_nd["train"], "nd_cv": with_nd["train_cv"],
                         "nd_cv_se": with_nd["train_cv_se"], "nd_test": with_nd["test"],
                         "nd_test_se": with_nd["test_se"], "plain_train": without["train"],
                         "plain_test": without["test"], "exposure_s": (model.exposures(W) * max(factors)).tolist()}
        rows.append(row)
        report(progress, 0.6 + 0.4 * (k + 1) / len(cfg.exposures), f"parsimony ({spec.mode}): {n_exp} exposure(s)")
    scores = [max(r[n]["nd_cv"] for n in lights) for r in rows]
    idx, best = _choose(scores, cfg.tolerance)
    return {"rows": rows, "scores": scores, "best": best, "chosen": rows[idx]["exposures"],
            "test_reported": [max(r[n]["nd_test"] for n in lights) for r in rows], "hdr_merge": merge,
            "criterion": f"captured training mean dE00 with ND 2.0 over half the patches, {cfg.folds}-fold "
                         "cross-validation (worst over the light sets); the test target is reported only",
            "nd_transmittance": cfg.nd_transmittance, "span": cfg.exposure_span}


def _noise_free_models(ev, W: np.ndarray) -> dict:
    from dualrgb.simulation.studies.models import fit_model, model_errors

    tr = ev.train.camera_values(W)
    te = ev.test.camera_values(W)
    out = {}
    for m in MODELS:
        fm = fit_model(m, tr, ev.train.xyz, ev.train.white)
        out[m] = {"train": float(model_errors(fm, tr, ev.train.xyz, ev.train.white).mean()),
                  "test": float(model_errors(fm, te, ev.test.xyz, ev.test.white).mean())}
    return out


@dataclass
class ParsimonyResult:
    spec: SetupSpec
    config: ParsimonyConfig
    steps: dict
    models: dict
    exposures: dict
    elapsed_s: float

    @property
    def mode(self) -> str:
        return self.spec.mode

    def defaults(self) -> dict:
        """This mode's entry of parsimony.json (simulation.defaults.save_defaults)."""
        g = self.steps["chosen"]
        return {"spectral_step_nm": g["step_nm"], "spectral_start_nm": g["start_nm"], "spectral_end_nm": g["end_nm"],
                "characterisation_model": self.models["chosen"], "hdr_exposures": self.exposures["chosen"],
                "tolerance_de00": self.config.tolerance,
                "thesis_grid_acceptable": self.steps["thesis_grid_acceptable"],
                "criteria": {"spectral_grid": self.steps["criterion"], "characterisation_model":
                             self.models["criterion"], "hdr_exposures": self.exposures["criterion"]},
                "evidence": {
                    "grid_deviation": {r["label"]: round(r["deviation"], 4) for r in self.steps["rows"]},
                    "grid_cpu_us_per_evaluation": {r["label"]: round(r["expected_us_per_evaluation"], 3)
                                                   for r in self.steps["rows"]},
                    "model_cv_de00": {k: round(v, 4) for k, v in self.models["scores"].items()},
                    "model_test_de00_reported": {k: round(v, 4) for k, v in self.models["test_reported"].items()},
                    "exposures_cv_de00": {str(r["exposures"]): round(s, 4) for r, s in
                                          zip(self.exposures["rows"], self.exposures["scores"], strict=True)},
                    "exposures_merged_with": self.exposures["hdr_merge"]},
                "setup": self.spec.to_dict(), "camera": self.config.camera.to_dict()}

    def to_json(self) -> dict:
        return {"setup": self.spec.to_dict(), "config": asdict(self.config), "elapsed_s": round(self.elapsed_s, 2),
                "spectral_grid": self.steps, "characterisation_model": self.models, "hdr_exposures": self.exposures,
                "defaults": self.defaults()}


def defaults_header() -> dict:
    """Top-level keys of a parsimony.json the study writes (format tag, versions, provenance)."""
    from dualrgb.simulation.defaults import FORMAT
    from dualrgb.simulation.versions import output_header

    return {**output_header(FORMAT), "generated_by": "dualrgb study parsimony",
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")}


def parsimony(spec: SetupSpec = SetupSpec(), cfg: ParsimonyConfig = ParsimonyConfig(), *,
              progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> ParsimonyResult:
    """The three questions for ``spec.mode`` (run once per mode: the answers may differ)."""
    if cfg.tolerance <= 0:
        raise ValueError(f"tolerance {cfg.tolerance}: expected a positive dE00")
    t0 = time.perf_counter()
    steps = spectral_grids(spec, cfg, cancel, progress)
    lights, origin = study_lights(spec, cfg.pso, cfg.light_sets)
    models = characterisation_models(spec, cfg, lights, cancel)
    models["light_sets_from"] = origin
    report(progress, 0.6, f"parsimony ({spec.mode}): characterisation models")
    exposures = hdr_exposures(spec, cfg, lights, cancel, progress)
    return ParsimonyResult(spec, cfg, steps, models, exposures, time.perf_counter() - t0)
