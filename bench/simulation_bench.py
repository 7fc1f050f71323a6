"""Simulation benchmarks: the thesis-scale PSO sweep, the exhaustive search and a naive reference (one evaluation
at a time, numpy.linalg.pinv + colour.delta_E) for issue 2; the default optimiser (successive halving over PSO +
L-BFGS-B polish) beside the thesis PSO on the noise-free objective and on the default expected-captured one, and
the L-BFGS-B cost per evaluation (float64 against the float32 kernel) for issue 12; the spectral objective's cost
per evaluation beside the expected-captured kernel's, and the default optimiser on it, for issue 21. All in the
same run."""
from __future__ import annotations

import time

import colour
import numpy as np

from dualrgb.simulation.camera_model import channel_responses
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.expected_error import ExpectedErrorEvaluator
from dualrgb.simulation.halving import HalvingSettings, successive_halving
from dualrgb.simulation.objective import Evaluator
from dualrgb.simulation.pso import PsoSettings, pso
from dualrgb.simulation.search import exhaustive, group_arrays, light_pairs, refine_top
from dualrgb.simulation.studies.optimisers import Float64Cost

DEFAULT_TARGET_S = 1.0          # issue 12: the default optimiser on this 2-core machine ...
BEST_KNOWN_TRAIN = 0.400        # ... reaching the best known optimum (reflective, noise-free)


def naive_cost(setup, sources_levels, white, xyz_true, lab_true) -> float:
    """One evaluation the straightforward way: spectra -> camera values -> pinv fit -> colour.delta_E."""
    lights = np.stack([lv @ setup.leds for lv in sources_levels])
    C = channel_responses(lights, setup.train.spectra, setup.camera)
    A = np.linalg.pinv(C) @ xyz_true
    lab_pred = colour.XYZ_to_Lab(C @ A / 100.0, colour.XYZ_to_xy(white / 100.0))
    return float(np.mean(colour.delta_E(lab_true, lab_pred, method="CIE 2000")))


def bench_simulation(mode: str = "reflective", seed: int = 0, naive_samples: int = 200) -> dict:
    setup = default_setup(mode)
    ev = Evaluator(setup)
    groups = light_pairs()
    ev.cost_indexed(np.zeros((1, 2, 3), dtype=np.int64), np.ones((1, 2, 3)))       # JIT warm-up, not timed
    pso(ev, groups[:2], PsoSettings(iterations=1, particles=8), seed=seed)

    t = time.perf_counter()
    ex = exhaustive(ev, groups)
    t_ex = time.perf_counter() - t

    settings = PsoSettings()
    t, c = time.perf_counter(), time.process_time()
    out = pso(ev, groups, settings, seed=seed)
    t_pso, cpu_pso = time.perf_counter() - t, time.process_time() - c
    evals = out.evaluations

    # naive reference on a sample of pairs x random levels, and agreement with the fast path
    rng = np.random.default_rng(seed)
    white = ev.train.white
    xyz_true = ev.train.xyz
    lab_true = colour.XYZ_to_Lab(xyz_true / 100.0, colour.XYZ_to_xy(white / 100.0))
    sample = rng.choice(len(groups), size=naive_samples, replace=True)
    levels = rng.random((naive_samples, 2, 3))
    dense = np.zeros((naive_samples, 2, 10))
    for i, gi in enumerate(sample):
        for li, light in enumerate(groups[gi]):
            dense[i, li, np.asarray(light) - 1] = levels[i, li]
    t = time.perf_counter()
    naive = np.array([naive_cost(setup, dense[i], white, xyz_true, lab_true) for i in range(naive_samples)])
    t_naive = (time.perf_counter() - t) / naive_samples
    fast = ev.cost(dense)
    per_eval_fast = t_pso / evals
    return {
        "mode": mode,
        "pso": {"pairs": len(groups), "particles": settings.particles, "iterations": settings.iterations,
                "training_patches": len(ev.train), "evaluations": evals, "elapsed_s": round(t_pso, 3),
                "evaluations_per_s": round(evals / t_pso), "best_train_de00": round(out.best.train_cost, 4),
                "cpu_s": round(cpu_pso, 3),
                "target_s": 5.0, "meets_target": t_pso <= 5.0},
        "exhaustive": {"pairs": len(groups), "elapsed_s": round(t_ex, 4),
                       "evaluations_per_s": round(len(groups) / t_ex),
                       "best": [list(s.leds) for s in ex.best.sources]},
        "naive_reference": {"samples": naive_samples, "s_per_evaluation": t_naive,
                            "evaluations_per_s": round(1.0 / t_naive, 1),
                            "max_abs_difference_vs_fast_de00": float(np.abs(naive - fast).max()),
                            "median_abs_difference_vs_fast_de00": float(np.median(np.abs(naive - fast)))},
        "speed_ratio_vs_naive": round(t_naive / per_eval_fast, 1),
        "ratio_target": 100.0,
        "default_optimiser": bench_default_optimiser(setup, ev, out, t_pso, cpu_pso, seed),
        "lbfgs_cost_per_evaluation": bench_cost_per_evaluation(ev, seed),
        "spectral_objective": bench_spectral_objective(setup, seed),
    }


def _us_per_evaluation(evaluator, idx: np.ndarray, w: np.ndarray, repeats: int = 5) -> float:
    evaluator.cost_indexed(idx, w)
    t = time.perf_counter()
    for _ in range(repeats):
        evaluator.cost_indexed(idx, w)
    return (time.perf_counter() - t) / repeats / len(w) * 1e6


def bench_spectral_objective(setup, seed: int = 0, batch: int = 6400) -> dict:
    """Issue 21: the spectral objective (expected captured spectral RMSE, numpy over the batch) per evaluation
    in PSO-sized batches beside the expected-captured kernel, and the default optimiser on it."""
    from dualrgb.simulation.spectral_objective import SpectralEvaluator

    spectral, expected = SpectralEvaluator(setup), ExpectedErrorEvaluator(setup)
    idx, mask = group_arrays(light_pairs())
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, len(idx), batch)
    w = mask[pick] * rng.random(mask[pick].shape)
    out = {"batch": batch, "spectral_us_per_evaluation": round(_us_per_evaluation(spectral, idx[pick], w), 3),
           "expected_captured_us_per_evaluation": round(_us_per_evaluation(expected, idx[pick], w), 3)}
    t, c = time.perf_counter(), time.process_time()
    best = refine_top(spectral, successive_halving(spectral, light_pairs(), HalvingSettings(), seed=seed), 1).best
    out["default_optimiser"] = {"elapsed_s": round(time.perf_counter() - t, 3),
                                "cpu_s": round(time.process_time() - c, 3), "evaluations": spectral.evaluations,
                                "leds": [list(s.leds) for s in best.sources],
                                "levels": [list(s.levels) for s in best.sources],
                                "expected_train_spectral_rmse": round(best.spectral["train"]["rmse"], 5),
                                "expected_test_spectral_rmse": round(best.spectral["test"]["rmse"], 5)}
    return out


def _row(outcome, seconds: float, objective: str, cpu_s: float | None = None) -> dict:
    b = outcome.best
    row = {"objective": objective, "elapsed_s": round(seconds, 3), "evaluations": outcome.evaluations,
           **({"cpu_s": round(cpu_s, 3)} if cpu_s is not None else {}),
           "leds": [list(s.leds) for s in b.sources], "levels": [list(s.levels) for s in b.sources],
           "train_de00": round(b.train.mean, 4), "test_de00": round(b.test.mean, 4)}
    if b.expected_train is not None:
        row.update(expected_train_de00=round(b.expected_train.mean, 4),
                   expected_test_de00=round(b.expected_test.mean, 4))
    return row


def bench_default_optimiser(setup, ev: Evaluator, thesis, t_thesis: float, cpu_thesis: float, seed: int) -> dict:
    """The default optimiser beside the thesis PSO (whose sweep ran just before, same evaluator): noise-free
    (comparable with the thesis) and on the default expected-captured objective."""
    groups = light_pairs()
    expected = ExpectedErrorEvaluator(setup)
    thesis = refine_top(ev, thesis, 1, expected)
    rows = {"thesis_pso_noise_free": _row(thesis, t_thesis, "noise-free", cpu_thesis)}
    successive_halving(ev, groups[:3], HalvingSettings(particles=4, min_sets=2, polish_sets=1), seed=seed)
    successive_halving(expected, groups[:3], HalvingSettings(particles=4, min_sets=2, polish_sets=1), seed=seed)
    for name, evaluator in (("default_noise_free", ev), ("default_expected_captured", expected)):
        t, c = time.perf_counter(), time.process_time()
        out = successive_halving(evaluator, groups, HalvingSettings(), seed=seed)
        seconds, cpu = time.perf_counter() - t, time.process_time() - c
        rows[name] = _row(refine_top(evaluator, out, 1, expected), seconds, evaluator.objective, cpu)
    t = time.perf_counter()
    out = pso(expected, groups, PsoSettings(), seed=seed)
    rows["thesis_pso_expected_captured"] = _row(refine_top(expected, out, 1), time.perf_counter() - t,
                                                "expected-captured")
    d = rows["default_noise_free"]
    rows.update(settings=HalvingSettings().__dict__, target_s=DEFAULT_TARGET_S, target_train=BEST_KNOWN_TRAIN,
                meets_target=d["elapsed_s"] <= DEFAULT_TARGET_S and d["train_de00"] <= BEST_KNOWN_TRAIN,
                speed_up_vs_thesis=round(t_thesis / d["elapsed_s"], 1))
    return rows


def bench_cost_per_evaluation(ev: Evaluator, seed: int, repeats: int = 200) -> dict:
    """What one evaluation costs L-BFGS-B: a gradient batch of one light set (D + 1 points forward, 2D + 1
    central) through the float64 numpy path (studies' multi-start L-BFGS-B) and through the float32 kernel
    (the default's polish), beside the kernel's cost in the PSO's big batches."""
    group = ((1, 6, 7), (3, 5, 9))
    idx, mask = group_arrays([group])
    rng = np.random.default_rng(seed)
    f64 = Float64Cost(ev, group)
    out = {}
    for label, points in (("forward_D+1", f64.dim + 1), ("central_2D+1", 2 * f64.dim + 1)):
        X = rng.random((points, f64.dim))
        f64(X)
        t = time.perf_counter()
        for _ in range(repeats):
            f64(X)
        t64 = (time.perf_counter() - t) / repeats / points
        w = X.reshape(points, 2, 3)
        indices = np.broadcast_to(idx, (points, 2, 3))
        ev.cost_indexed(indices, w)
        t = time.perf_counter()
        for _ in range(repeats):
            ev.cost_indexed(indices, w)
        t32 = (time.perf_counter() - t) / repeats / points
        out[label] = {"points": points, "float64_us_per_evaluation": round(t64 * 1e6, 2),
                      "float32_kernel_us_per_evaluation": round(t32 * 1e6, 2), "ratio": round(t64 / t32, 1)}
    big = rng.random((6400, 2, 3))
    indices = np.broadcast_to(idx, big.shape)
    ev.cost_indexed(indices, big)
    t = time.perf_counter()
    for _ in range(5):
        ev.cost_indexed(indices, big)
    out["float32_kernel_us_per_evaluation_in_pso_batches"] = round((time.perf_counter() - t) / 5 / 6400 * 1e6, 3)
    return out
