"""The default optimiser: successive halving over the thesis' particle swarm, then an L-BFGS-B polish.

Successive halving (Jamieson & Talwalkar 2016; Li et al. 2018, "Hyperband") spends little on the many light
sets that cannot win: every set gets a short PSO (thesis Algorithm 1, same coefficients C0 = 0.95, C1 = C2 = 2),
the best 1/eta of the sets survive and get a PSO with eta times the iterations, and so on until ``min_sets``
remain; a set keeps its best result over the rungs. The best ``polish_sets`` sets are then polished by
L-BFGS-B (scipy) from their swarm best, with a central-difference gradient evaluated as one batch through the
same objective (the fast kernel: a batch of 2D + 1 points costs about as much as one float64 evaluation, see
``make bench``). A polished point replaces the swarm's only if its (realised) cost is lower, so the polish never
makes a result worse. The objective is whatever evaluator is passed: noise-free or expected-captured.

The speed-accuracy study shows why: the thesis PSO spends 1.39 M evaluations and ends at 0.409 (reflective,
noise-free); halving with 20 particles from one iteration reaches the best known optimum, 0.399 at
(1, 6, 7) + (3, 5, 9), with ~0.1 M.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.pso import PsoSettings, enforce_constraints, swarm_bests
from dualrgb.simulation.search import Group, SearchOutcome, candidates_from, costs_checked, group_arrays, light_pairs

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class HalvingSettings:
    """Rung r runs PSO with ``iterations * eta**r`` iterations and ``particles`` particles on 1/eta**r of the
    sets (at least ``min_sets``); then L-BFGS-B on the best ``polish_sets`` (0: no polish)."""

    particles: int = 20
    iterations: int = 1
    eta: int = 3
    min_sets: int = 4
    c0: float = 0.95
    c1: float = 2.0
    c2: float = 2.0
    polish_sets: int = 2
    polish_iterations: int = 30
    polish_step: float = 1e-3       # central differences: well above float32 noise and the PWM step


def successive_halving(evaluator, groups: Sequence[Group] | None = None,
                       settings: HalvingSettings = HalvingSettings(), seed: int = 0, *,
                       progress: ProgressCallback | None = None,
                       cancel: CancelToken | None = None) -> SearchOutcome:
    """Successive halving with the thesis PSO as the inner optimiser (each rung restarts PSO, seeded by rung),
    then the L-BFGS-B polish of the best sets. Best first."""
    groups = list(groups) if groups is not None else light_pairs()
    _, mask_all = group_arrays(groups)
    G, L, m = mask_all.shape
    t0, n0 = time.perf_counter(), evaluator.evaluations
    best_x = np.zeros((G, L, m))
    best_c = np.full(G, np.inf)
    alive = np.arange(G)
    iterations = settings.iterations
    rungs: list[dict[str, float]] = []
    while True:
        check(cancel)
        ps = PsoSettings(settings.c0, settings.c1, settings.c2, iterations, settings.particles)
        # one chunk per rung: a rung is one batch per iteration (big batches use both cores; results do not depend
        # on chunking)
        x, c, _ = swarm_bests(evaluator, [groups[i] for i in alive], ps, seed=seed * 1000 + len(rungs),
                              chunk=len(alive), cancel=cancel)
        better = c < best_c[alive]
        best_c[alive[better]] = c[better]
        best_x[alive[better]] = x[better]
        rungs.append({"rung": len(rungs), "light_sets": int(len(alive)), "iterations": iterations,
                      "best": float(best_c[alive].min())})
        report(progress, min(0.9, 0.3 * len(rungs)), f"halving: rung {len(rungs) - 1}, {len(alive)} light sets")
        if len(alive) <= settings.min_sets:
            break
        keep = max(settings.min_sets, len(alive) // settings.eta)
        alive = alive[np.argsort(best_c[alive], kind="stable")[:keep]]
        iterations *= settings.eta
    polished = polish(evaluator, groups, best_x, best_c, settings, cancel=cancel)
    report(progress, 1.0, f"halving: best {best_c.min():.4f}")
    return SearchOutcome("halving", seed, time.perf_counter() - t0, evaluator.evaluations - n0,
                         candidates_from(groups, best_x, best_c),
                         history=[r["best"] for r in rungs] + ([float(best_c.min())] if polished else []),
                         settings={**asdict(settings), "rungs": rungs, "polished": polished, "light_sets": G})


def set_cost(evaluator, idx_row: np.ndarray, mask_row: np.ndarray, cancel: CancelToken | None = None
             ) -> Callable[[np.ndarray], np.ndarray]:
    """Objective of one light set's levels X (B, L*m) (padding masked out), one batch per call; ``cancel`` is
    checked before each (an L-BFGS-B polish stops within one gradient batch of a cancel)."""
    L, m = idx_row.shape

    def cost(X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(X).reshape(-1, L, m) * mask_row
        return costs_checked(evaluator, np.broadcast_to(idx_row, (X.shape[0], L, m)), X, cancel)

    return cost


def _central_difference(cost: Callable[[np.ndarray], np.ndarray], live: np.ndarray, h: float
                        ) -> Callable[[np.ndarray], tuple[float, np.ndarray]]:
    """The cost of the ``live`` levels and its central-difference gradient (step ``h``, levels clipped to
    [0, 1]), from one batch of 2D + 1 points."""
    D = int(live.sum())
    steps = np.vstack([np.zeros(D), np.eye(D) * h, -np.eye(D) * h])

    def fun_grad(v: np.ndarray) -> tuple[float, np.ndarray]:
        X = np.zeros((len(steps), live.size))
        X[:, live] = np.clip(v + steps, 0.0, 1.0)
        c = cost(X)
        return float(c[0]), (c[1:D + 1] - c[D + 1:]) / (2 * h)

    return fun_grad


def polish(evaluator, groups: Sequence[Group], best_x: np.ndarray, best_c: np.ndarray,
           settings: HalvingSettings, *, cancel: CancelToken | None = None) -> list[dict]:
    """L-BFGS-B from the best ``settings.polish_sets`` sets' levels, in place where it improves (levels
    normalised as PSO's, eqs 6.2-6.4). Returns what it did per set."""
    from scipy.optimize import minimize

    idx_all, mask_all = group_arrays(list(groups))
    h = settings.polish_step
    done = []
    for gi in np.argsort(best_c, kind="stable")[:settings.polish_sets]:
        check(cancel)
        mask = mask_all[gi].astype(float)
        live = mask.reshape(-1) > 0
        cost = set_cost(evaluator, idx_all[gi], mask, cancel)
        D = int(live.sum())
        res = minimize(_central_difference(cost, live, h), best_x[gi].reshape(-1)[live], jac=True, method="L-BFGS-B",
                       bounds=[(0.0, 1.0)] * D, options={"maxiter": settings.polish_iterations, "ftol": 1e-7})
        x = np.zeros(live.size)
        x[live] = res.x
        x = enforce_constraints(x.reshape(mask.shape), mask)
        c = float(cost(x.reshape(1, -1))[0])
        improved = c < best_c[gi]
        done.append({"light_set": [list(light) for light in groups[gi]], "from": float(best_c[gi]), "to": c,
                     "iterations": int(res.nit), "kept": bool(improved)})
        if improved:
            best_x[gi], best_c[gi] = x, c
    return done
