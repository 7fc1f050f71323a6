"""Particle swarm optimisation of LED levels (thesis Algorithm 1, section 6.2), over many light sets at once.

Per light set: N particles in [0, 1]^(L*m) (the levels of each light's LEDs, eq 6.1); for L_max iterations
v <- C0 v + C1 r1 (x_best_i - x) + C2 r2 (x_best - x); x <- x + v; clip negatives (eq 6.2); divide each
light's levels by their maximum (eqs 6.3-6.4); evaluate the cost (mean training dE00, 6.2.3); update the
particle and swarm bests. The initial positions are uniform random and evaluated once; velocities start at 0.

Vectorised: a chunk of light sets x N particles is one cost batch. Random numbers come from one generator per
light set (seeded by (seed, light-set number)), so results do not depend on chunking.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.objective import Evaluator
from dualrgb.simulation.search import (
    Group,
    SearchOutcome,
    candidates_from,
    costs_checked,
    group_arrays,
    light_pairs,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PsoSettings:
    """Thesis 6.2.4: C0 = mean of 1.4 and 0.5, C1 = C2 = 2, L_max = 10, N = 200."""

    c0: float = 0.95
    c1: float = 2.0
    c2: float = 2.0
    iterations: int = 10
    particles: int = 200


def enforce_constraints(x: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Eq 6.2 (clip negatives) then eqs 6.3-6.4 (each light normalised by its maximum level), in place.

    x (..., L, m); entries where ``mask`` is False are padding and stay 0. A light whose levels are all
    clipped to 0 stays off (its channels are zero; the rank-safe fit handles it).
    """
    np.maximum(x, 0.0, out=x)
    x *= mask
    mx = x.max(axis=-1, keepdims=True)
    np.divide(x, mx, out=x, where=mx > 0)
    return x


def _rngs(seed: int, first: int, count: int) -> list[np.random.Generator]:
    return [np.random.default_rng([seed, first + i]) for i in range(count)]


def pso(evaluator: Evaluator, groups: Sequence[Group] | None = None, settings: PsoSettings = PsoSettings(),
        seed: int = 0, *, chunk: int = 32, progress: ProgressCallback | None = None,
        cancel: CancelToken | None = None) -> SearchOutcome:
    """Run PSO on every light set in ``groups`` (default: the 630 binned pairs); best first."""
    groups = list(groups) if groups is not None else light_pairs()
    t0 = time.perf_counter()
    n0 = evaluator.evaluations
    best_x, best_c, history = swarm_bests(evaluator, groups, settings, seed, chunk=chunk, progress=progress,
                                          cancel=cancel)
    outcome = SearchOutcome("pso", seed, time.perf_counter() - t0, evaluator.evaluations - n0,
                            candidates_from(groups, best_x, best_c),
                            history=[float(h) for h in history.min(axis=0)],
                            settings={**asdict(settings), "light_sets": len(groups)})
    log.info("PSO over %d light sets: %.2f s, %d evaluations, best %.4f", len(groups), outcome.elapsed_s,
             outcome.evaluations, outcome.best.train_cost)
    return outcome


def swarm_bests(evaluator: Evaluator, groups: Sequence[Group], settings: PsoSettings = PsoSettings(),
                seed: int = 0, *, chunk: int = 32, progress: ProgressCallback | None = None,
                cancel: CancelToken | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Algorithm 1 on every light set: the swarm bests' levels (G, L, m), costs (G,) and the best cost after
    each iteration per set (G, iterations + 1), as arrays (what :func:`pso` and successive halving build on)."""
    idx_all, mask_all = group_arrays(groups)
    G, L, m = idx_all.shape
    N = settings.particles
    best_x = np.empty((G, L, m))
    best_c = np.empty(G)
    history = np.full((G, settings.iterations + 1), np.inf)
    for lo in range(0, G, chunk):
        hi = min(G, lo + chunk)
        g = hi - lo
        rngs = _rngs(seed, lo, g)
        mask = mask_all[lo:hi, None].astype(float)                       # (g, 1, L, m)
        idx = np.broadcast_to(idx_all[lo:hi, None], (g, N, L, m)).reshape(g * N, L, m)
        x = np.stack([r.random((N, L, m)) for r in rngs])                # (g, N, L, m)
        enforce_constraints(x, mask)
        v = np.zeros_like(x)
        c = costs_checked(evaluator, idx, x.reshape(g * N, L, m), cancel).reshape(g, N)
        pbest_x, pbest_c = x.copy(), c.copy()
        gi = np.argmin(c, axis=1)
        gbest_x = x[np.arange(g), gi].copy()                            # (g, L, m)
        gbest_c = c[np.arange(g), gi].copy()
        history[lo:hi, 0] = gbest_c
        for it in range(1, settings.iterations + 1):
            check(cancel)
            r1 = np.stack([r.random((N, L, m)) for r in rngs])
            r2 = np.stack([r.random((N, L, m)) for r in rngs])
            v = settings.c0 * v + settings.c1 * r1 * (pbest_x - x) + settings.c2 * r2 * (gbest_x[:, None] - x)
            x = enforce_constraints(x + v, mask)
            c = costs_checked(evaluator, idx, x.reshape(g * N, L, m), cancel).reshape(g, N)
            better = c < pbest_c
            pbest_c = np.where(better, c, pbest_c)
            pbest_x = np.where(better[..., None, None], x, pbest_x)
            gi = np.argmin(pbest_c, axis=1)
            cand_c = pbest_c[np.arange(g), gi]
            improve = cand_c < gbest_c
            gbest_c = np.where(improve, cand_c, gbest_c)
            gbest_x = np.where(improve[:, None, None], pbest_x[np.arange(g), gi], gbest_x)
            history[lo:hi, it] = gbest_c
        best_x[lo:hi] = gbest_x
        best_c[lo:hi] = gbest_c
        report(progress, hi / G, f"PSO: {hi}/{G} light sets, best {best_c[:hi].min():.4f} dE00")
    return best_x, best_c, history
