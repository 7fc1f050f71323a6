"""Simulation benchmarks for issue 2: the thesis-scale PSO sweep, the exhaustive search, and a naive
reference (one evaluation at a time, numpy.linalg.pinv + colour.delta_E) measured in the same run."""
from __future__ import annotations

import time

import colour
import numpy as np

from simulation.camera_model import channel_responses
from simulation.datasets import default_setup
from simulation.objective import Evaluator
from simulation.pso import PsoSettings, pso
from simulation.search import exhaustive, light_pairs


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
    t = time.perf_counter()
    out = pso(ev, groups, settings, seed=seed)
    t_pso = time.perf_counter() - t
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
    }
