"""The unbinned full-intensity search (thesis 5.3.1.1): every unordered pair of distinct non-empty LED
subsets, C(2^10 - 1, 2) = 522 753 pairs, all LEDs of a light at level 1.

Pairs are numbered as :func:`simulation.search.unbinned_pairs` lists them (subsets in bit-mask order
1..1023, pairs in ``itertools.combinations`` order), but the index arrays are built from bit masks with
numpy instead of the core's per-pair Python loop (:func:`unbinned_group_arrays`, same arrays). The search is
split into contiguous index ranges; each task keeps its ``top`` best pairs, and the merge sorts by (cost,
pair number), so serial and Dask runs give identical results.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.search import Candidate, Group
from dualrgb.simulation.studies.common import SetupSpec, evaluator_for
from dualrgb.simulation.studies.distributed import Runner, SerialRunner

log = logging.getLogger(__name__)


def pair_count(n_leds: int = 10) -> int:
    s = 2**n_leds - 1
    return s * (s - 1) // 2


@lru_cache(maxsize=4)
def _subset_tables(n_leds: int) -> tuple[np.ndarray, np.ndarray]:
    """For every bit mask 0..2^n - 1: its LED indices packed to the left (padded 0) and the valid flags."""
    masks = np.arange(2**n_leds)
    bits = (masks[:, None] >> np.arange(n_leds)) & 1 == 1                 # (2^n, n)
    order = np.argsort(~bits, axis=1, kind="stable")                        # set bits first, in LED order
    valid = np.take_along_axis(bits, order, axis=1)
    idx = np.where(valid, order, 0)
    return idx.astype(np.int64), valid


@lru_cache(maxsize=4)
def _pair_table(n_leds: int) -> tuple[np.ndarray, np.ndarray]:
    """Subset numbers (0-based positions in mask order 1..2^n-1) of every pair, combinations order."""
    i, j = np.triu_indices(2**n_leds - 1, k=1)
    return i.astype(np.int32), j.astype(np.int32)


def pair_masks(n_leds: int, lo: int = 0, hi: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Bit masks (a, b) of pairs ``lo:hi`` (LED k is bit k-1)."""
    i, j = _pair_table(n_leds)
    hi = len(i) if hi is None else hi
    return i[lo:hi].astype(np.int64) + 1, j[lo:hi].astype(np.int64) + 1


def unbinned_group_arrays(n_leds: int = 10, lo: int = 0, hi: int | None = None,
                          m: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(idx, mask) of pairs ``lo:hi`` like ``group_arrays(unbinned_pairs(n_leds))[lo:hi]``, vectorised.

    ``m`` (default ``n_leds``, which is what ``group_arrays`` pads the full space to) is the padded width.
    """
    m = n_leds if m is None else m
    a, b = pair_masks(n_leds, lo, hi)
    idx_t, valid_t = _subset_tables(n_leds)
    idx = np.stack([idx_t[a, :m], idx_t[b, :m]], axis=1)
    mask = np.stack([valid_t[a, :m], valid_t[b, :m]], axis=1)
    return idx, mask


def mask_leds(mask: int) -> tuple[int, ...]:
    return tuple(k + 1 for k in range(mask.bit_length()) if mask >> k & 1)


def pair_group(n_leds: int, number: int) -> Group:
    a, b = pair_masks(n_leds, number, number + 1)
    return (mask_leds(int(a[0])), mask_leds(int(b[0])))


@dataclass(frozen=True)
class RangeTask:
    spec: SetupSpec
    lo: int
    hi: int
    top: int = 20
    batch: int = 16384
    n_leds: int = 10


def evaluate_range(task: RangeTask) -> dict:
    """Full-intensity cost of pairs ``lo:hi``; returns the ``top`` best (number, cost) and a cost histogram."""
    ev = evaluator_for(task.spec)
    t0 = time.perf_counter()
    best_n = np.empty(0, dtype=np.int64)
    best_c = np.empty(0)
    hist = np.zeros(len(HIST_EDGES) - 1, dtype=np.int64)
    for lo in range(task.lo, task.hi, task.batch):
        hi = min(task.hi, lo + task.batch)
        idx, mask = unbinned_group_arrays(task.n_leds, lo, hi)
        c = ev.cost_indexed(idx, mask.astype(float))
        hist += np.histogram(np.clip(c, HIST_EDGES[0], HIST_EDGES[-1] - 1e-9), HIST_EDGES)[0]
        best_n = np.concatenate([best_n, np.arange(lo, hi)])
        best_c = np.concatenate([best_c, c])
        keep = np.lexsort((best_n, best_c))[:task.top]
        best_n, best_c = best_n[keep], best_c[keep]
    return {"lo": task.lo, "hi": task.hi, "numbers": best_n.tolist(), "costs": best_c.tolist(),
            "histogram": hist.tolist(), "seconds": time.perf_counter() - t0}


HIST_EDGES = np.concatenate([np.linspace(0.0, 3.0, 61), [np.inf]])


@dataclass
class UnbinnedResult:
    spec: SetupSpec
    pairs: int
    seconds: float
    numbers: list[int]
    costs: list[float]
    histogram: list[int]
    runner: dict
    tasks: int
    candidates: list[Candidate] = field(default_factory=list)
    binned_best: dict | None = None

    def to_json(self) -> dict:
        return {"setup": self.spec.to_dict(), "pairs": self.pairs, "seconds": round(self.seconds, 3),
                "pairs_per_second": round(self.pairs / self.seconds) if self.seconds > 0 else None,
                "runner": self.runner, "tasks": self.tasks,
                "top": [{"number": n, **c.to_dict(), "leds_total": sum(len(s.leds) for s in c.sources)}
                        for n, c in zip(self.numbers, self.candidates, strict=True)] if self.candidates else
                [{"number": n, "cost": c} for n, c in zip(self.numbers, self.costs, strict=True)],
                "histogram": {"edges": [float(e) for e in HIST_EDGES[:-1]] + ["inf"], "counts": self.histogram},
                "binned_best": self.binned_best}


def unbinned_search(spec: SetupSpec = SetupSpec(), runner: Runner | None = None, *, tasks: int = 8,
                    top: int = 20, n_leds: int = 10, limit: int | None = None,
                    refine: int = 10) -> UnbinnedResult:
    """Search pairs 0..``limit`` (default all) of the unbinned space, split into ``tasks`` ranges."""
    runner = runner or SerialRunner()
    total = pair_count(n_leds) if limit is None else min(limit, pair_count(n_leds))
    edges = np.linspace(0, total, tasks + 1).round().astype(int)
    work = [RangeTask(spec, int(edges[i]), int(edges[i + 1]), top, n_leds=n_leds)
            for i in range(tasks) if edges[i + 1] > edges[i]]
    t0 = time.perf_counter()
    parts = runner.map(evaluate_range, work)
    seconds = time.perf_counter() - t0
    numbers = np.concatenate([np.asarray(p["numbers"], dtype=np.int64) for p in parts])
    costs = np.concatenate([np.asarray(p["costs"], dtype=float) for p in parts])
    keep = np.lexsort((numbers, costs))[:top]
    hist = np.sum([p["histogram"] for p in parts], axis=0).astype(int).tolist()
    describe = getattr(runner, "describe", lambda: {"runner": runner.name})
    result = UnbinnedResult(spec, total, seconds, numbers[keep].tolist(), costs[keep].tolist(), hist,
                            describe(), len(work))
    if refine:
        ev = evaluator_for(spec)
        for n, c in zip(result.numbers[:refine], result.costs[:refine], strict=True):
            group = pair_group(n_leds, n)
            cand = Candidate(tuple(LightSource(light) for light in group), float(c))
            cand.train, cand.test = ev.stats(cand.weights(ev.n_leds))
            result.candidates.append(cand)
        result.numbers = result.numbers[:refine]
    log.info("unbinned search: %d pairs in %.2f s (%s)", total, seconds, result.runner)
    return result


def compare_binned(spec: SetupSpec, bins: Sequence[int] = (3, 3, 4)) -> dict:
    """The binned (630-pair) full-intensity best, for reference."""
    from dualrgb.simulation.search import exhaustive, light_pairs, refine_top

    ev = evaluator_for(spec)
    out = refine_top(ev, exhaustive(ev, light_pairs(bins)), 1)
    return out.best.to_dict()


def unbinned_chart(result: UnbinnedResult):
    from dualrgb.simulation.studies.common import new_figure

    fig, ax = new_figure(8.0, 4.6)
    edges = HIST_EDGES[:-1]
    counts = np.asarray(result.histogram[:-1])
    width = edges[1] - edges[0]
    ax.bar(edges[:-1] + width / 2, counts[:len(edges) - 1], width * 0.95, color="tab:blue", alpha=0.7,
           label=f"{result.pairs} unbinned pairs (last bin: >= {edges[-1]:g})")
    ax.bar(edges[-1] + width / 2, result.histogram[-1], width * 0.95, color="tab:grey", alpha=0.7)
    ax.set_yscale("log")
    if result.candidates:
        best = result.candidates[0]
        ax.axvline(best.train_cost, color="tab:red", ls="--",
                   label="unbinned best " + " + ".join(s.label() for s in best.sources) + f" ({best.train_cost:.3f})")
    if result.binned_best:
        b = result.binned_best
        ax.axvline(b["train_de00_mean"], color="black", ls=":",
                   label=f"binned best {tuple(b['source1'])} + {tuple(b['source2'])} ({b['train_de00_mean']:.3f})")
    ax.set_xlabel("training mean dE00 at full intensity")
    ax.set_ylabel("light-source pairs")
    ax.set_title(f"Unbinned full-intensity search: {result.seconds:.1f} s ({result.runner.get('runner')})")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    return fig


def write_outputs(result: UnbinnedResult, out) -> None:
    out.write_json("unbinned.json", result.to_json())
    out.save_figure(unbinned_chart(result), "unbinned.png")
    lines = [f"Setup: {result.spec.label()}; {result.pairs} pairs of distinct non-empty LED subsets, all LEDs "
             f"at full level; {result.tasks} tasks on {result.runner}; {result.seconds:.2f} s "
             f"({result.pairs / max(result.seconds, 1e-9):.0f} pairs/s).", "",
             "| rank | pair number | light 1 | light 2 | train dE00 | test dE00 |", "|---:|---:|---|---|---:|---:|"]
    for i, (n, c) in enumerate(zip(result.numbers, result.candidates, strict=True), start=1):
        lines.append(f"| {i} | {n} | {c.sources[0].leds} | {c.sources[1].leds} | {c.train_errors.mean:.4f} | "
                     f"{c.test_errors.mean:.4f} |")
    if result.binned_best:
        b = result.binned_best
        lines += ["", f"Binned (3/3/4) full-intensity best for comparison: {tuple(b['source1'])} + "
                      f"{tuple(b['source2'])}, train {b['train_de00_mean']:.4f}, test {b['test_de00_mean']:.4f}."]
    out.write_summary("Unbinned full-intensity search", lines)
