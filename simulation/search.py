"""Candidate light sets and the exhaustive full-intensity search (thesis 5.3.1).

LEDs are split into bins (default 3/3/4, from shortest to longest wavelength); a light source takes one LED
from each bin (36 triplets) and a dual-RGB setup is an unordered pair of distinct triplets (630 pairs).
The unbinned space (every pair of distinct non-empty LED subsets, ~523 k pairs) is available too.
"""
from __future__ import annotations

import itertools
import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.objective import ErrorStats, Evaluator

# light sets costed between two checks of a search's cancel token: the unit a cancel waits for at most (the
# Simulate panel's cancel latency is measured in these; bench/cancel_latency.py times one)
CANCEL_SLICE = 512

log = logging.getLogger(__name__)

DEFAULT_BINS = (3, 3, 4)
Group = tuple[tuple[int, ...], ...]   # one tuple of 1-based LED numbers per light


def triplets(bins: Sequence[int] = DEFAULT_BINS) -> list[tuple[int, ...]]:
    """All light sources taking one LED per bin, 1-based: (1, 4, 7), (1, 4, 8), ..."""
    if any(b < 1 for b in bins):
        raise ValueError(f"bins {tuple(bins)}: every bin needs at least one LED")
    edges = np.cumsum((0,) + tuple(bins))
    return list(itertools.product(*(range(edges[i] + 1, edges[i + 1] + 1) for i in range(len(bins)))))


def light_pairs(bins: Sequence[int] = DEFAULT_BINS, n_lights: int = 2) -> list[Group]:
    """Unordered sets of ``n_lights`` distinct binned light sources (630 pairs for 3/3/4)."""
    return list(itertools.combinations(triplets(bins), n_lights))


def unbinned_pairs(n_leds: int = 10) -> list[Group]:
    """Every unordered pair of distinct non-empty LED subsets (C(2^n - 1, 2) = 522 753 for 10 LEDs)."""
    subsets = [tuple(i + 1 for i in range(n_leds) if mask >> i & 1) for mask in range(1, 2**n_leds)]
    return list(itertools.combinations(subsets, 2))


def group_arrays(groups: Sequence[Group]) -> tuple[np.ndarray, np.ndarray]:
    """(idx, mask): 0-based LED indices (G, L, m) padded with 0 and a (G, L, m) mask of real entries."""
    L = len(groups[0])
    m = max(len(light) for g in groups for light in g)
    idx = np.zeros((len(groups), L, m), dtype=np.int64)
    mask = np.zeros((len(groups), L, m), dtype=bool)
    for gi, g in enumerate(groups):
        if len(g) != L:
            raise ValueError(f"light set {g}: expected {L} lights like the others")
        for li, light in enumerate(g):
            idx[gi, li, :len(light)] = np.asarray(light) - 1
            mask[gi, li, :len(light)] = True
    return idx, mask


def _evaluated(stats: ErrorStats | None, what: str) -> ErrorStats:
    if stats is None:
        raise ValueError(f"this candidate has no {what} errors: it was not re-evaluated (refine_top)")
    return stats


@dataclass
class Candidate:
    """One light set with its optimised levels and errors."""

    sources: tuple[LightSource, ...]
    train_cost: float                       # objective value found by the search (float32 kernel)
    train: ErrorStats | None = None      # float64 noise-free re-evaluation (filled for the reported top K)
    test: ErrorStats | None = None
    expected_train: ErrorStats | None = None     # float64 expected captured errors (simulation.expected_error)
    expected_test: ErrorStats | None = None
    spectral: dict | None = None            # expected captured spectral RMSE (simulation.spectral_objective)
    objective_value: float | None = None    # float64 figure of a spectral objective (sorts the reported top K)
    per_pixel: dict | None = None           # per-pixel dE00 {train, test: {mean, p90, ...}, expected_train_mean}
    incumbent: bool = False                 # lights already in use: scored at their levels as set (add_incumbents)

    def weights(self, n_leds: int) -> np.ndarray:
        return np.stack([s.weights(n_leds) for s in self.sources])

    # the re-evaluated errors of a reported candidate (refine_top fills them; asking before is a bug)
    @property
    def train_errors(self) -> ErrorStats:
        return _evaluated(self.train, "noise-free training")

    @property
    def test_errors(self) -> ErrorStats:
        return _evaluated(self.test, "noise-free test")

    @property
    def expected_train_errors(self) -> ErrorStats:
        return _evaluated(self.expected_train, "expected captured training")

    @property
    def expected_test_errors(self) -> ErrorStats:
        return _evaluated(self.expected_test, "expected captured test")

    def to_dict(self) -> dict:
        d: dict = {}
        for i, s in enumerate(self.sources, start=1):
            d[f"source{i}"] = list(s.leds)
        for i, s in enumerate(self.sources, start=1):
            d[f"intensities{i}"] = [round(v, 4) for v in s.levels]
        d["train_de00_mean"] = round(self.train.mean if self.train else self.train_cost, 4)
        d["test_de00_mean"] = round(self.test.mean, 4) if self.test else None
        if self.train:
            d["train"] = {k: round(v, 4) for k, v in self.train.to_dict().items()}
        if self.test:
            d["test"] = {k: round(v, 4) for k, v in self.test.to_dict().items()}
        if self.expected_train:
            d["expected_train_de00_mean"] = round(self.expected_train.mean, 4)
            d["expected_test_de00_mean"] = round(self.expected_test_errors.mean, 4)
            d["expected_train"] = {k: round(v, 4) for k, v in self.expected_train.to_dict().items()}
            d["expected_test"] = {k: round(v, 4) for k, v in self.expected_test_errors.to_dict().items()}
        if self.per_pixel:
            d["per_pixel_train_de00_mean"] = self.per_pixel["train"]["mean"]
            d["per_pixel_test_de00_mean"] = self.per_pixel["test"]["mean"]
            d["per_pixel"] = {k: self.per_pixel[k] for k in ("train", "test")}
        if self.incumbent:
            d["in_use"] = True                  # the lights already in use, scored as the sphere sets them
        if self.spectral:
            d["expected_train_spectral_rmse"] = round(self.spectral["train"]["rmse"], 5)
            d["expected_test_spectral_rmse"] = round(self.spectral["test"]["rmse"], 5)
            d["expected_spectral"] = self.spectral
        return d

    def objective_mean(self, objective: str) -> float:
        """The float64 figure of ``objective`` ('noise-free' or the expected captured training error; a spectral
        objective's own figure)."""
        if self.objective_value is not None:
            return self.objective_value
        if objective.startswith("robust"):
            return self.train_cost               # the ensemble's figure (only the search computes it)
        if objective == "expected-per-pixel" and self.per_pixel is not None:
            return float(self.per_pixel["expected_train_mean"])
        if objective != "noise-free" and self.expected_train is not None:
            return self.expected_train.mean
        return self.train.mean if self.train else self.train_cost


@dataclass
class SearchOutcome:
    method: str
    seed: int | None
    elapsed_s: float
    evaluations: int
    candidates: list[Candidate]             # best first
    history: list[float] = field(default_factory=list)   # best cost after each iteration (optimisers)
    settings: dict = field(default_factory=dict)

    @property
    def best(self) -> Candidate:
        return self.candidates[0]


def candidates_from(groups: Sequence[Group], levels: np.ndarray, costs: np.ndarray) -> list[Candidate]:
    """Candidates sorted by cost; ``levels`` (G, L, m) aligned with each group's LEDs."""
    order = np.argsort(costs, kind="stable")
    out = []
    for gi in order:
        g = groups[gi]
        sources = tuple(LightSource(light, tuple(float(v) for v in levels[gi, li, :len(light)]))
                        for li, light in enumerate(g))
        out.append(Candidate(sources, float(costs[gi])))
    return out


def as_captured(evaluator: Any) -> Any:
    """``evaluator`` for lights already captured (its ``for_captured``: levels as set, none forbidden), or itself
    when it has no sphere (the noise-free objective)."""
    twin = getattr(evaluator, "for_captured", None)
    return twin() if twin is not None else evaluator


def evaluate_candidate(evaluator: Evaluator, cand: Candidate, expected: Any = None) -> Candidate:
    """Give ``cand`` its float64 reference train and test stats. An evaluator that realises levels on the sphere's
    grid (``realise``) gets the candidate's levels replaced by the realised ones first (not an incumbent's: lights
    in use are scored as the sphere sets them, :func:`as_captured`); ``expected`` (an object with
    ``expected_stats(W)``, e.g. :class:`simulation.expected_error.ExpectedErrorEvaluator`, default: the
    evaluator if it has one) adds the expected captured figures, patch means and per pixel (``pixel_stats``)."""
    if cand.incumbent:
        evaluator, expected = as_captured(evaluator), None if expected is None else as_captured(expected)
    realise = getattr(evaluator, "realise", None)
    expected = expected if expected is not None else (evaluator if hasattr(evaluator, "expected_stats") else None)
    if realise is not None and not cand.incumbent:
        cand.sources = tuple(LightSource(s.leds, tuple(float(v) for v in realise(np.array(s.levels))), s.name)
                             for s in cand.sources)
    W = cand.weights(evaluator.n_leds)
    cand.train, cand.test = evaluator.stats(W)
    if expected is not None:
        cand.expected_train, cand.expected_test = expected.expected_stats(W)
        if hasattr(expected, "pixel_stats"):
            cand.per_pixel = expected.pixel_stats(W)
    spectral, value = getattr(evaluator, "spectral_stats", None), getattr(evaluator, "objective_value", None)
    if spectral is not None and value is not None:        # a spectral objective (simulation.spectral_objective)
        cand.spectral = spectral(W)
        cand.objective_value = value(W)
    return cand


def add_incumbents(evaluator: Evaluator, outcome: SearchOutcome,
                   incumbents: Sequence[Sequence[LightSource]]) -> SearchOutcome:
    """Light sets the user already has (a calibration's lights) costed by the search's own
    objective and ranked among its candidates, so a re-optimisation never reports lights its objective rates worse
    than those (a stochastic search can miss the basin they lie in: halving, seed 0, did on a film stand, 0.2985
    where the preset scores 0.2629). They are costed at their levels as set (:func:`as_captured`): a level below
    the minimum stable level that the search itself may not choose is what the sphere emits for them. A set with
    another number of lights than the search's is left out."""
    n_lights = len(outcome.best.sources) if outcome.candidates else None
    captured = as_captured(evaluator)
    for sources in incumbents:
        if n_lights is not None and len(sources) != n_lights:
            continue
        cand = Candidate(tuple(sources), 0.0, incumbent=True)
        cand.train_cost = float(captured.cost(cand.weights(evaluator.n_leds)[None])[0])
        outcome.candidates.append(cand)
    outcome.candidates.sort(key=lambda c: c.train_cost)
    return outcome


def costs_checked(evaluator: Evaluator, idx: np.ndarray, w: np.ndarray, cancel: CancelToken | None,
                  slice_size: int | None = None) -> np.ndarray:
    """``evaluator.cost_indexed(idx, w)`` in slices of at most ``slice_size`` (default :data:`CANCEL_SLICE`) light
    sets with ``cancel`` checked before each: a search stops within one slice of a cancel (the costs are per light
    set, so slicing changes no result)."""
    n = len(w)
    slice_size = slice_size or CANCEL_SLICE
    if n <= slice_size:
        check(cancel)
        return evaluator.cost_indexed(idx, w)
    out = np.empty(n)
    for lo in range(0, n, slice_size):
        check(cancel)
        out[lo:lo + slice_size] = evaluator.cost_indexed(idx[lo:lo + slice_size], w[lo:lo + slice_size])
    return out


def refine_top(evaluator: Evaluator, outcome: SearchOutcome, top: int, expected=None,
               cancel: CancelToken | None = None) -> SearchOutcome:
    """Re-evaluate the best ``top`` candidates (:func:`evaluate_candidate`; ``cancel`` checked between them) and
    sort them by the evaluator's objective."""
    for cand in outcome.candidates[:top]:
        check(cancel)
        evaluate_candidate(evaluator, cand, expected)
    objective = getattr(evaluator, "objective", "noise-free")
    head = sorted(outcome.candidates[:top], key=lambda c: c.objective_mean(objective))
    outcome.candidates[:top] = head
    return outcome


def exhaustive(evaluator: Evaluator, groups: Sequence[Group] | None = None, *, batch: int = 20000,
               progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> SearchOutcome:
    """Full-intensity search over ``groups`` (default: the 630 binned pairs)."""
    groups = list(groups) if groups is not None else light_pairs()
    t0 = time.perf_counter()
    n0 = evaluator.evaluations
    costs = np.empty(len(groups))
    idx_all, mask_all = group_arrays(groups)
    for lo in range(0, len(groups), batch):
        hi = min(len(groups), lo + batch)
        costs[lo:hi] = costs_checked(evaluator, idx_all[lo:hi], mask_all[lo:hi].astype(float), cancel)
        report(progress, hi / len(groups), f"exhaustive: {hi}/{len(groups)} light sets")
    cands = candidates_from(groups, mask_all.astype(float), costs)
    return SearchOutcome("exhaustive", None, time.perf_counter() - t0, evaluator.evaluations - n0, cands,
                         settings={"light_sets": len(groups)})
