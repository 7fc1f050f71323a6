"""(mu + lambda) genetic algorithm on LED levels (thesis Algorithm 2, section 6.4): the "second opinion".

Per light set: mu random individuals; each generation makes lambda offspring, each by one-point crossover of
two random parents (probability p_c) or else by mutating one random parent (one random gene replaced by a
uniform random level with probability p_mutation, otherwise the child is a copy). Children identical to a
parent inherit its fitness instead of being evaluated (as Algorithm 2). The next population is the best mu
of parents and offspring. The same constraints as PSO apply (clip negatives, normalise each light by its max).
Vectorised over light sets like simulation.pso, with one random generator per light set.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.objective import Evaluator
from dualrgb.simulation.pso import _rngs, enforce_constraints
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
class GaSettings:
    """Budget comparable to the thesis PSO (~2 000 evaluations per light set)."""

    mu: int = 20
    lam: int = 200
    generations: int = 10
    p_crossover: float = 0.5
    p_mutation: float = 0.9


def _offspring(r: np.random.Generator, pop: np.ndarray, fit: np.ndarray, mask: np.ndarray, settings: GaSettings
               ) -> tuple[np.ndarray, np.ndarray]:
    """One light set's lambda children (lam, D) of its population ``pop`` (mu, D) and the fitness each inherits
    (NaN where it must be evaluated): crossover with probability p_c, else mutation (thesis Algorithm 2)."""
    mu, D = pop.shape
    lam = settings.lam
    L, m = mask.shape[-2:]
    cross = r.random(lam) <= settings.p_crossover
    pa = r.integers(0, mu, lam)
    pb = r.integers(0, mu, lam)
    cut = r.integers(1, D, lam)
    gene = r.integers(0, D, lam)
    mutate = r.random(lam) <= settings.p_mutation
    new_val = r.random(lam)
    k = pop[pa].copy()
    cols = np.arange(D)[None, :]
    k = np.where(cross[:, None] & (cols >= cut[:, None]), pop[pb], k)
    mut_rows = ~cross & mutate
    k[mut_rows, gene[mut_rows]] = new_val[mut_rows]
    k = enforce_constraints(k.reshape(lam, L, m), mask).reshape(lam, D)
    same_a = np.all(k == pop[pa], axis=1)
    same_b = cross & np.all(k == pop[pb], axis=1)
    return k, np.where(same_a, fit[pa], np.where(same_b, fit[pb], np.nan))


def _best_of(pop: np.ndarray, fit: np.ndarray, kids: np.ndarray, kid_fit: np.ndarray, mu: int
             ) -> tuple[np.ndarray, np.ndarray]:
    """The next populations (g, mu, D) and their fitness: the best mu of parents and children, per light set."""
    allx = np.concatenate([pop, kids], axis=1)
    allf = np.concatenate([fit, kid_fit], axis=1)
    order = np.argsort(allf, axis=1, kind="stable")[:, :mu]
    return np.take_along_axis(allx, order[..., None], axis=1), np.take_along_axis(allf, order, axis=1)


def ga(evaluator: Evaluator, groups: Sequence[Group] | None = None, settings: GaSettings = GaSettings(),
       seed: int = 0, *, chunk: int = 32, progress: ProgressCallback | None = None,
       cancel: CancelToken | None = None) -> SearchOutcome:
    groups = list(groups) if groups is not None else light_pairs()
    idx_all, mask_all = group_arrays(groups)
    G, L, m = idx_all.shape
    D = L * m
    mu, lam = settings.mu, settings.lam
    t0 = time.perf_counter()
    n0 = evaluator.evaluations
    best_x = np.empty((G, L, m))
    best_c = np.empty(G)
    history = np.full((G, settings.generations + 1), np.inf)
    for lo in range(0, G, chunk):
        hi = min(G, lo + chunk)
        g = hi - lo
        rngs = _rngs(seed, lo, g)
        mask = mask_all[lo:hi, None].astype(float)
        flat_mask = mask.reshape(g, 1, D)
        pop = enforce_constraints(np.stack([r.random((mu, L, m)) for r in rngs]), mask).reshape(g, mu, D)
        fit = costs_checked(evaluator, np.broadcast_to(idx_all[lo:hi, None], (g, mu, L, m)).reshape(-1, L, m),
                            pop.reshape(-1, L, m), cancel).reshape(g, mu)
        history[lo:hi, 0] = fit.min(axis=1)
        for gen in range(1, settings.generations + 1):
            check(cancel)
            kids = np.empty((g, lam, D))
            inherit = np.full((g, lam), np.nan)
            for gi, r in enumerate(rngs):
                kids[gi], inherit[gi] = _offspring(r, pop[gi], fit[gi], mask[gi], settings)
            todo = np.isnan(inherit)
            kid_fit = inherit.copy()
            if todo.any():
                sel = np.nonzero(todo)
                kid_fit[sel] = costs_checked(evaluator, idx_all[lo:hi][sel[0]], kids[sel].reshape(-1, L, m), cancel)
            pop, fit = _best_of(pop, fit, kids, kid_fit, mu)
            history[lo:hi, gen] = fit[:, 0]
        best_x[lo:hi] = pop[:, 0].reshape(g, L, m) * flat_mask.reshape(g, L, m)
        best_c[lo:hi] = fit[:, 0]
        report(progress, hi / G, f"GA: {hi}/{G} light sets, best {best_c[:hi].min():.4f} dE00")
    outcome = SearchOutcome("ga", seed, time.perf_counter() - t0, evaluator.evaluations - n0,
                            candidates_from(groups, best_x, best_c),
                            history=[float(h) for h in history.min(axis=0)],
                            settings={**asdict(settings), "light_sets": G})
    log.info("GA over %d light sets: %.2f s, %d evaluations, best %.4f", G, outcome.elapsed_s,
             outcome.evaluations, outcome.best.train_cost)
    return outcome
