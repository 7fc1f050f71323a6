"""More optimisers for the LED levels of each light set, beside the core's PSO (thesis Algorithm 1) and GA
(Algorithm 2), so the studies can compare them on the same cost:

* ``pyswarms``: pyswarms' ``GlobalBestPSO`` on each light set's (L*m)-D problem in [0, 1], looping over the
  light sets (one swarm per set, thesis coefficients);
* ``de``: scipy's ``differential_evolution`` per light set (vectorised: one cost batch per generation);
* ``lbfgs``: a random screen of every light set (fast kernel), then multi-start L-BFGS-B (scipy) on the best
  sets with the float64 cost and a forward-difference gradient evaluated as one batch of L*m + 1 points (the
  cost is smooth in the levels);
* ``halving``: the app's default optimiser (:mod:`simulation.halving`): successive halving over light sets
  (every set gets a short PSO, the best 1/eta survive and get eta times the iterations, and so on; a set keeps
  its best result over the rungs), then L-BFGS-B polishing of the best sets.

Every function takes the evaluator first (plain or :class:`~simulation.studies.common.TracedEvaluator`),
the light sets and a settings dataclass, and returns a :class:`~simulation.search.SearchOutcome` whose
candidates are sorted best first and whose levels are normalised like PSO's (eqs 6.2-6.4). Note that the
cost is invariant to scaling one light's levels (the least-squares fit absorbs it), so normalising never
changes a cost.
"""
from __future__ import annotations

import contextlib
import logging
import os
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab
from dualrgb.simulation.ga import GaSettings, ga
from dualrgb.simulation.halving import HalvingSettings, set_cost, successive_halving
from dualrgb.simulation.matrix_fit import solve_normal_equations
from dualrgb.simulation.pso import PsoSettings, enforce_constraints, pso
from dualrgb.simulation.search import Group, SearchOutcome, candidates_from, exhaustive, group_arrays

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PyswarmsSettings:
    """pyswarms GlobalBestPSO per light set; defaults = the thesis coefficients and budget."""

    particles: int = 200
    iterations: int = 10
    c0: float = 0.95            # pyswarms 'w'
    c1: float = 2.0
    c2: float = 2.0


@dataclass(frozen=True)
class DeSettings:
    """scipy differential_evolution per light set; population = popsize * (L*m)."""

    popsize: int = 15
    maxiter: int = 20
    mutation: tuple[float, float] = (0.5, 1.0)
    recombination: float = 0.7
    tol: float = 0.0            # 0: run every generation (a fixed budget, comparable to PSO)


@dataclass(frozen=True)
class LbfgsSettings:
    """Multi-start L-BFGS-B on the float64 cost (forward-difference gradient), after a random screen.

    Every light set is screened with ``screen`` random level vectors (fast kernel); the ``top_sets`` best sets
    get ``starts`` L-BFGS-B runs each (the best screened point, then random points).
    """

    screen: int = 64
    top_sets: int = 48
    starts: int = 3
    maxiter: int = 30
    step: float = 1e-6
    lower: float = 1e-3         # levels stay above this so no light can switch itself off


# ---------------------------------------------------------------------------------------------------------
class Float64Cost:
    """Mean training dE00 of one light set's levels in float64 (the numpy reference path), batched.

    ``__call__(X)`` takes X (B, D) with D = the light set's LED count in light order and returns (B,).
    Same fit as the fast kernel (equilibrated, ridge, rank-safe), same ground truth; no float32.
    """

    def __init__(self, evaluator, group: Group) -> None:
        ev = getattr(evaluator, "base", evaluator)
        self.group = group
        leds = [k - 1 for light in group for k in light]
        self.slices = []
        lo = 0
        for light in group:
            self.slices.append(slice(lo, lo + len(light)))
            lo += len(light)
        self.R = ev.train.R[leds]                          # (D, n, 3)
        self.xyz = ev.train.xyz
        self.lab = ev.train.lab
        self.white = ev.train.white
        self.dim = lo

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        C = np.concatenate([np.einsum("bd,dnc->bnc", X[:, s], self.R[s]) for s in self.slices], axis=2)
        CT = C.transpose(0, 2, 1)
        A = solve_normal_equations(CT @ C, CT @ self.xyz)   # LAPACK: a handful of systems per call
        lab = xyz_to_lab(C @ A, self.white)
        return delta_e_2000(self.lab, lab).mean(axis=1)


def _normalised(levels: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return enforce_constraints(np.array(levels, dtype=float), mask.astype(float))


def _outcome(method: str, groups: Sequence[Group], levels: np.ndarray, costs: np.ndarray, seed: int | None,
             t0: float, n0: int, evaluator, settings: dict, history: list[float] | None = None) -> SearchOutcome:
    return SearchOutcome(method, seed, time.perf_counter() - t0, evaluator.evaluations - n0,
                         candidates_from(list(groups), levels, costs), history=history or [],
                         settings={**settings, "light_sets": len(groups)})


# ---------------------------------------------------------------------------------------------------------
@contextlib.contextmanager
def _pyswarms_logging() -> Iterator[None]:
    """pyswarms' Reporter calls ``logging.config.dictConfig`` whenever one is built (at import and for every
    optimiser): a root handler and a ``report.log`` file in the working directory, unless LOG_CFG names a
    config file. Give it an incremental, empty config so it changes nothing."""
    previous = os.environ.get("LOG_CFG")
    with tempfile.TemporaryDirectory() as tmp:
        cfg = os.path.join(tmp, "pyswarms-logging.yaml")
        with open(cfg, "w", encoding="utf-8") as fh:
            fh.write("version: 1\nincremental: true\n")
        os.environ["LOG_CFG"] = cfg
        try:
            yield
        finally:
            if previous is None:
                os.environ.pop("LOG_CFG", None)
            else:
                os.environ["LOG_CFG"] = previous


def _set_by_set(method: str, label: str, evaluator, groups: Sequence[Group],
                settings: PyswarmsSettings | DeSettings, seed: int,
                optimise: Callable[[int, Callable[[np.ndarray], np.ndarray], int], tuple[float, np.ndarray]],
                progress: ProgressCallback | None, cancel: CancelToken | None) -> SearchOutcome:
    """Every light set optimised on its own, in turn: ``optimise(set number, cost, D)`` returns the set's best
    cost and levels (D,), ``cost`` being the set's objective of a batch of levels (B, D)."""
    groups = list(groups)
    idx_all, mask_all = group_arrays(groups)
    G, L, m = idx_all.shape
    t0, n0 = time.perf_counter(), evaluator.evaluations
    best_x = np.zeros((G, L, m))
    best_c = np.empty(G)
    for gi in range(G):
        check(cancel)
        best_c[gi], levels = optimise(gi, set_cost(evaluator, idx_all[gi], mask_all[gi]), L * m)
        best_x[gi] = _normalised(np.asarray(levels).reshape(L, m), mask_all[gi])
        if gi % 32 == 31 or gi == G - 1:
            report(progress, (gi + 1) / G, f"{label}: {gi + 1}/{G} light sets")
    return _outcome(method, groups, best_x, best_c, seed, t0, n0, evaluator, asdict(settings))


def pyswarms_search(evaluator, groups: Sequence[Group], settings: PyswarmsSettings = PyswarmsSettings(),
                    seed: int = 0, *, progress: ProgressCallback | None = None,
                    cancel: CancelToken | None = None) -> SearchOutcome:
    """pyswarms GlobalBestPSO on every light set in turn (pyswarms draws from numpy's global generator:
    it is seeded per light set with (seed, set number) and restored afterwards). One optimiser is built and
    ``reset()`` for every set (building one costs ~10 ms of logging set-up)."""
    options = {"c1": settings.c1, "c2": settings.c2, "w": settings.c0}
    swarm: list[Any] = []                              # the one optimiser, built for the first set

    def optimise(gi: int, cost: Callable[[np.ndarray], np.ndarray], D: int) -> tuple[float, np.ndarray]:
        if not swarm:
            from pyswarms.single import GlobalBestPSO  # its import configures logging too

            swarm.append(GlobalBestPSO(settings.particles, D, options, bounds=(np.zeros(D), np.ones(D)),
                                       bh_strategy="nearest"))
        np.random.seed(np.random.SeedSequence([seed, gi]).generate_state(1)[0])  # noqa: NPY002 - see below
        swarm[0].reset()
        best, pos = swarm[0].optimize(cost, iters=settings.iterations, verbose=False)
        return best, np.asarray(pos)

    state = np.random.get_state()  # noqa: NPY002 - pyswarms draws from numpy's global RNG: restored below
    try:
        with _pyswarms_logging():
            return _set_by_set("pyswarms", "pyswarms", evaluator, groups, settings, seed, optimise, progress,
                               cancel)
    finally:
        np.random.set_state(state)  # noqa: NPY002 - the caller's global RNG as it was


def _on_columns(cost: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], np.ndarray]:
    """``cost`` (points as rows) for scipy's vectorised differential evolution, which passes them as columns."""
    return lambda X: cost(X.T)


def de_search(evaluator, groups: Sequence[Group], settings: DeSettings = DeSettings(), seed: int = 0, *,
              progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> SearchOutcome:
    """scipy differential_evolution on every light set in turn, vectorised per generation, no polishing."""
    from scipy.optimize import Bounds, differential_evolution

    def optimise(gi: int, cost: Callable[[np.ndarray], np.ndarray], D: int) -> tuple[float, np.ndarray]:
        # vectorized=True: the cost returns one value per column (scipy-stubs type only the scalar form)
        res = differential_evolution(_on_columns(cost),  # type: ignore[arg-type]
                                     Bounds(np.zeros(D), np.ones(D)), maxiter=settings.maxiter,
                                     popsize=settings.popsize, mutation=settings.mutation,
                                     recombination=settings.recombination, tol=settings.tol, polish=False,
                                     vectorized=True, updating="deferred",
                                     rng=np.random.default_rng([seed, gi]))
        return float(res.fun), res.x

    return _set_by_set("de", "differential evolution", evaluator, groups, settings, seed, optimise, progress,
                       cancel)


def _random_screen(evaluator, idx_all: np.ndarray, mask_all: np.ndarray, settings: LbfgsSettings, seed: int,
                   cancel: CancelToken | None) -> tuple[np.ndarray, np.ndarray]:
    """``settings.screen`` random levels per light set, costed by the fast kernel 64 sets at a time:
    levels (G, S, L, m) and costs (G, S)."""
    G, L, m = idx_all.shape
    rng = np.random.default_rng([seed, 0x5C])
    S = settings.screen
    x = rng.uniform(settings.lower, 1.0, (G, S, L, m)) * mask_all[:, None]
    c = np.empty((G, S))
    for lo in range(0, G, 64):
        check(cancel)
        hi = min(G, lo + 64)
        idx = np.broadcast_to(idx_all[lo:hi, None], (hi - lo, S, L, m)).reshape(-1, L, m)
        c[lo:hi] = evaluator.cost_indexed(idx, x[lo:hi].reshape(-1, L, m)).reshape(hi - lo, S)
    return x, c


def _forward_difference(evaluator, f64: Float64Cost, step: float
                        ) -> Callable[[np.ndarray], tuple[float, np.ndarray]]:
    """The float64 cost and its forward-difference gradient (step ``step``) from one batch of D + 1 points,
    counted as evaluations of ``evaluator`` (recorded in a TracedEvaluator's trace)."""
    eye = np.eye(f64.dim) * step
    record = getattr(evaluator, "record_external", None)

    def fun_grad(v: np.ndarray) -> tuple[float, np.ndarray]:
        cc = f64(np.vstack([v, v + eye]))
        if record is not None:
            record(cc)
        else:
            evaluator.evaluations += len(cc)
        return float(cc[0]), (cc[1:] - cc[0]) / step

    return fun_grad


def lbfgs_search(evaluator, groups: Sequence[Group], settings: LbfgsSettings = LbfgsSettings(), seed: int = 0,
                 *, progress: ProgressCallback | None = None,
                 cancel: CancelToken | None = None) -> SearchOutcome:
    """Random screen of every light set, then multi-start L-BFGS-B on :class:`Float64Cost` for the best sets.

    Why a screen: one float64 cost + gradient batch costs ~0.5-1 ms in numpy, so L-BFGS-B on all 630 sets
    would take minutes; the screen (fast kernel) costs ``screen`` evaluations per set. Sets that are not
    refined keep their best screened point.
    """
    from scipy.optimize import minimize

    groups = list(groups)
    idx_all, mask_all = group_arrays(groups)
    G, L, m = idx_all.shape
    t0, n0 = time.perf_counter(), evaluator.evaluations
    x, c = _random_screen(evaluator, idx_all, mask_all, settings, seed, cancel)
    arg = c.argmin(axis=1)
    best_c = c[np.arange(G), arg]
    best_x = np.stack([_normalised(x[g, arg[g]], mask_all[g]) for g in range(G)])
    top = np.argsort(best_c, kind="stable")[:settings.top_sets]
    for n_done, gi in enumerate(top, start=1):
        check(cancel)
        group = groups[gi]
        f64 = Float64Cost(evaluator, group)
        D = f64.dim
        fun_grad = _forward_difference(evaluator, f64, settings.step)
        prng = np.random.default_rng([seed, int(gi)])
        first = np.concatenate([x[gi, arg[gi], li, :len(light)] for li, light in enumerate(group)])
        for start in range(settings.starts):
            x0 = first if start == 0 else prng.uniform(settings.lower, 1.0, D)
            res = minimize(fun_grad, x0, jac=True, method="L-BFGS-B", bounds=[(settings.lower, 1.0)] * D,
                           options={"maxiter": settings.maxiter})
            if res.fun < best_c[gi]:
                best_c[gi] = res.fun
                flat = np.zeros((L, m))
                for li, s in enumerate(f64.slices):
                    flat[li, :s.stop - s.start] = res.x[s]
                best_x[gi] = _normalised(flat, mask_all[gi])
        if n_done % 8 == 0 or n_done == len(top):
            report(progress, n_done / len(top), f"L-BFGS-B: {n_done}/{len(top)} light sets refined")
    return _outcome("lbfgs", groups, best_x, best_c, seed, t0, n0, evaluator, asdict(settings))


def halving_search(evaluator, groups: Sequence[Group], settings: HalvingSettings = HalvingSettings(),
                   seed: int = 0, *, progress: ProgressCallback | None = None,
                   cancel: CancelToken | None = None) -> SearchOutcome:
    """The default optimiser (simulation.halving.successive_halving)."""
    return successive_halving(evaluator, groups, settings, seed, progress=progress, cancel=cancel)


# ---------------------------------------------------------------------------------------------------------
def exhaustive_search(evaluator, groups: Sequence[Group], settings: None = None, seed: int = 0, *,
                      progress: ProgressCallback | None = None,
                      cancel: CancelToken | None = None) -> SearchOutcome:
    return exhaustive(evaluator, groups, progress=progress, cancel=cancel)


def pso_search(evaluator, groups: Sequence[Group], settings: PsoSettings = PsoSettings(), seed: int = 0, *,
               progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> SearchOutcome:
    return pso(evaluator, groups, settings, seed, progress=progress, cancel=cancel)


def ga_search(evaluator, groups: Sequence[Group], settings: GaSettings = GaSettings(), seed: int = 0, *,
              progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> SearchOutcome:
    return ga(evaluator, groups, settings, seed, progress=progress, cancel=cancel)


OPTIMISERS: dict[str, Callable[..., SearchOutcome]] = {
    "exhaustive": exhaustive_search,
    "pso": pso_search,
    "ga": ga_search,
    "pyswarms": pyswarms_search,
    "de": de_search,
    "lbfgs": lbfgs_search,
    "halving": halving_search,
}

LABELS = {
    "exhaustive": "exhaustive (full intensity)",
    "pso": "PSO (thesis Alg. 1)",
    "ga": "(mu+lambda) GA (Alg. 2)",
    "pyswarms": "pyswarms GlobalBestPSO",
    "de": "scipy differential evolution",
    "lbfgs": "multi-start L-BFGS-B",
    "halving": "successive halving (PSO) + L-BFGS-B (default)",
}
