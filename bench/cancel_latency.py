"""Cancel latency of the searches (issue 30 item 4): a search checks its cancel token before every slice of
simulation.search.CANCEL_SLICE light sets, so a Cancel waits for at most one slice. This times one slice per
objective (median of repeats, kernels warm), and the default search (successive halving) and the thesis PSO with
the slicing against one unsliced batch per call (what the checks cost). The GUI tests count the work units; this
says what a unit takes on this machine."""
from __future__ import annotations

import time

import numpy as np

from dualrgb.simulation import search
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.halving import successive_halving
from dualrgb.simulation.pso import PsoSettings, pso
from dualrgb.simulation.runner import make_evaluator
from dualrgb.simulation.search import CANCEL_SLICE, group_arrays, light_pairs
from dualrgb.simulation.warmup import warm_up

OBJECTIVES = ("noise-free", "expected-captured", "robust")


def _slice_s(evaluator, repeats: int = 7) -> float:
    idx, mask = group_arrays(light_pairs())
    rows = np.resize(np.arange(len(idx)), CANCEL_SLICE)
    w = np.random.default_rng(0).random((CANCEL_SLICE, *idx.shape[1:])) * mask[rows]
    evaluator.cost_indexed(idx[rows], w)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        evaluator.cost_indexed(idx[rows], w)
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def _search_s(evaluator, sliced: bool) -> dict[str, float]:
    keep = search.CANCEL_SLICE
    search.CANCEL_SLICE = keep if sliced else 10 ** 9          # read at every call (search.costs_checked)
    try:
        out = {}
        for name, run in (("halving", lambda: successive_halving(evaluator, light_pairs(), seed=0)),
                          ("pso", lambda: pso(evaluator, light_pairs(), PsoSettings(), seed=0))):
            t = time.perf_counter()
            run()
            out[name] = round(time.perf_counter() - t, 3)
        return out
    finally:
        search.CANCEL_SLICE = keep


def bench_cancel_latency(mode: str = "reflective") -> dict:
    setup = default_setup(mode)
    per_slice = {}
    for objective in OBJECTIVES:
        evaluator = make_evaluator(setup, objective)
        warm_up(getattr(evaluator, "base", evaluator))
        if hasattr(evaluator, "warm_up_kernels"):
            evaluator.warm_up_kernels()
        per_slice[objective] = round(_slice_s(evaluator), 5)
    evaluator = make_evaluator(setup, "noise-free")
    sliced, whole = _search_s(evaluator, True), _search_s(evaluator, False)
    return {"mode": mode, "cancel_slice_light_sets": CANCEL_SLICE, "slice_s": per_slice,
            "worst_cancel_wait_s": max(per_slice.values()),
            "search_s_sliced": sliced, "search_s_one_batch": whole}
