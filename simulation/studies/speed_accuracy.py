"""Speed against accuracy of every optimiser on the binned light sets (``dualrgb study speed-accuracy``).

Each configuration (a method with its settings) runs once per seed on the same evaluator (the thesis' noise-free
cost). A run records its cost on axes that do not move with the machine's load - the CPU seconds of the process
that ran it (``time.process_time``: every thread of that process, numba's included; a Dask worker measures its
own) and the objective evaluations - and beside them its wall time with the load average at its start and end;
the best training dE00 it found (float64 re-evaluation, as reports do), that light set's test dE00, and what the
light set is worth under capture: its expected captured figures (simulation.expected_error, the virtual lab's
capture) and per pixel (the matrix on one pixel of each patch, mean and test p90), at the levels the sphere
holds (a requested level between 0 and the sphere's minimum stable level is 0 there: such a point is marked); and
its anytime curve (lowest cost evaluated so far against evaluations and seconds, in the order the method spends
them: PSO and GA work through the light sets 16 at a time, successive halving visits every set first). Results
are summarised per configuration as median and min-max over seeds.

Outputs: ``speed_accuracy.json``, ``pareto.png`` (median CPU seconds vs median best error: training patch means
noise-free and expected captured, and per pixel, with the Pareto front of the noise-free medians and the points
below the sphere's minimum level marked), ``convergence.png`` (best-so-far error vs evaluations, median and spread
over seeds) and ``SUMMARY.md``.
"""
from __future__ import annotations

import logging
import os
import time
import warnings
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.ga import GaSettings
from dualrgb.simulation.pso import PsoSettings
from dualrgb.simulation.search import light_pairs, refine_top
from dualrgb.simulation.studies.common import (
    SetupSpec,
    StudyOutput,
    TracedEvaluator,
    evaluator_for,
    median_spread,
    new_figure,
    pareto_front,
)
from dualrgb.simulation.studies.distributed import Runner, SerialRunner
from dualrgb.simulation.studies.optimisers import (
    LABELS,
    OPTIMISERS,
    DeSettings,
    HalvingSettings,
    LbfgsSettings,
    PyswarmsSettings,
)
from dualrgb.simulation.warmup import warm_up

log = logging.getLogger(__name__)

BUDGETS = ("tiny", "small", "default")


@dataclass(frozen=True)
class Config:
    """One point of the comparison: a method and its settings (``None`` for exhaustive)."""

    method: str
    label: str
    settings: Any = None


def configs(budget: str = "default") -> list[Config]:
    """The configurations compared at a budget ('tiny' is for tests: a few evaluations per light set)."""
    if budget not in BUDGETS:
        raise ValueError(f"budget {budget!r}: expected one of {', '.join(BUDGETS)}")
    if budget == "tiny":
        sweep = [(10, 2), (20, 3)]
        ga = GaSettings(mu=6, lam=20, generations=3)
        ps = PyswarmsSettings(particles=10, iterations=3)
        de = DeSettings(popsize=3, maxiter=3)
        lb = LbfgsSettings(screen=8, top_sets=2, starts=1, maxiter=5)
        sh = HalvingSettings(particles=10, iterations=1, min_sets=2)
    elif budget == "small":
        sweep = [(20, 5), (50, 10), (200, 10)]
        ga = GaSettings()
        ps = PyswarmsSettings(particles=50, iterations=10)
        de = DeSettings(popsize=5, maxiter=10)
        lb = LbfgsSettings(top_sets=12, starts=2)
        sh = HalvingSettings()
    else:
        sweep = [(20, 5), (50, 5), (50, 10), (100, 10), (200, 10), (100, 20)]
        ga = GaSettings()
        ps = PyswarmsSettings(particles=100, iterations=10)
        de = DeSettings(popsize=10, maxiter=15)
        lb = LbfgsSettings(top_sets=24, starts=2)
        sh = HalvingSettings()
    out = [Config("exhaustive", "exhaustive")]
    for n, it in sweep:
        label = f"pso {n}x{it}" + (" (thesis)" if (n, it) == (200, 10) else "")
        out.append(Config("pso", label, PsoSettings(particles=n, iterations=it)))
    out += [Config("ga", f"ga mu{ga.mu}+lam{ga.lam} x{ga.generations}", ga),
            Config("halving", f"halving {sh.particles}p from {sh.iterations} it", sh),
            Config("pyswarms", f"pyswarms {ps.particles}x{ps.iterations}", ps),
            Config("de", f"de pop{de.popsize}x{de.maxiter}", de),
            Config("lbfgs", f"lbfgs top{lb.top_sets}x{lb.starts}", lb)]
    return out


@dataclass(frozen=True)
class RunTask:
    spec: SetupSpec
    config: Config
    seed: int
    light_sets: int | None = None


@lru_cache(maxsize=4)
def captured_judge(spec: SetupSpec) -> Any:
    """The expected-captured evaluator of the virtual lab's capture in the spec's mode (one per process): what a
    run's best light set is worth when captured, patch means and per pixel."""
    from dualrgb.simulation.capture_model import CaptureModel
    from dualrgb.simulation.expected_error import ExpectedErrorEvaluator

    return ExpectedErrorEvaluator(spec.build(), CaptureModel.virtual_lab(spec.mode))


def captured_figures(spec: SetupSpec, levels: list[list[float]], leds: list[list[int]]) -> dict:
    """The expected captured (patch means) and per-pixel figures of a light set given by its LEDs and requested
    levels, at the levels the sphere holds, and whether a requested level lies below the sphere's minimum."""
    judge = captured_judge(spec)
    W = np.zeros((len(leds), judge.n_leds))
    for li, (ls, vs) in enumerate(zip(leds, levels, strict=True)):
        W[li, np.asarray(ls) - 1] = vs
    lowest = judge.capture.sphere.min_stable_level
    below = [[int(k), float(v)] for row, ls in zip(levels, leds, strict=True) for k, v in zip(ls, row, strict=True)
             if 0.0 < v < lowest]
    tr, te = judge.expected_stats(W)
    px = judge.pixel_stats(W)
    return {"expected_train": tr.mean, "expected_test": te.mean, "per_pixel_train": px["train"]["mean"],
            "per_pixel_test": px["test"]["mean"], "per_pixel_test_p90": px["test"]["p90"],
            "below_min_level": below, "min_stable_level": lowest}


def run_task(task: RunTask) -> dict:
    """One configuration, one seed (a Dask task): errors, CPU and wall time, evaluations and the anytime trace;
    the best light set's expected captured and per-pixel figures."""
    ev = evaluator_for(task.spec)
    groups = light_pairs()
    if task.light_sets:
        groups = groups[:task.light_sets]
    warm_up(ev)
    traced = TracedEvaluator(ev)
    fn = OPTIMISERS[task.config.method]
    n0 = ev.evaluations
    load0 = os.getloadavg()[0]
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn(traced, groups, task.config.settings, task.seed)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    load = [round(load0, 2), round(os.getloadavg()[0], 2)]
    refine_top(ev, out, 1)
    best = out.best
    levels = [list(src.levels) for src in best.sources]
    return {"method": task.config.method, "label": task.config.label, "seed": task.seed,
            "cpu_seconds": cpu, "seconds": seconds, "load": load, "evaluations": ev.evaluations - n0,
            "train_cost": best.train_cost, "train": best.train_errors.mean, "test": best.test_errors.mean,
            **captured_figures(task.spec, levels, [list(src.leds) for src in best.sources]),
            "best": {**best.to_dict(), "levels_exact": {str(i + 1): lv for i, lv in enumerate(levels)}},
            "trace": traced.trace.to_dict()}


@dataclass
class SpeedAccuracyResult:
    spec: SetupSpec
    budget: str
    seeds: list[int]
    light_sets: int
    runs: list[dict]
    summary: list[dict] = field(default_factory=list)
    pareto_train: list[str] = field(default_factory=list)
    pareto_test: list[str] = field(default_factory=list)
    runner: dict = field(default_factory=dict)
    elapsed_s: float = 0.0

    def to_json(self) -> dict:
        return {"setup": self.spec.to_dict(), "budget": self.budget, "seeds": self.seeds,
                "light_sets": self.light_sets, "runner": self.runner, "elapsed_s": round(self.elapsed_s, 2),
                "configurations": self.summary, "pareto_train": self.pareto_train,
                "pareto_test": self.pareto_test, "runs": self.runs}


def summarise(runs: list[dict], order: list[str]) -> list[dict]:
    rows = []
    for label in order:
        rs = [r for r in runs if r["label"] == label]
        if not rs:
            continue
        pairs = {(tuple(r["best"]["source1"]), tuple(r["best"]["source2"])) for r in rs}
        rows.append({"label": label, "method": rs[0]["method"],
                     "cpu_seconds": median_spread([r["cpu_seconds"] for r in rs]),
                     "seconds": median_spread([r["seconds"] for r in rs]),
                     "load": median_spread([v for r in rs for v in r["load"]]),
                     "evaluations": median_spread([r["evaluations"] for r in rs]),
                     **{k: median_spread([r[k] for r in rs]) for k in FIGURES},
                     "below_min_level_runs": sum(bool(r["below_min_level"]) for r in rs),
                     "distinct_best_pairs": len(pairs)})
    return rows


FIGURES = ("train", "test", "expected_train", "expected_test", "per_pixel_train", "per_pixel_test",
           "per_pixel_test_p90")


def speed_accuracy(spec: SetupSpec = SetupSpec(), *, seeds: int = 3, budget: str = "default",
                   light_sets: int | None = None, runner: Runner | None = None,
                   progress: ProgressCallback | None = None,
                   cancel: CancelToken | None = None) -> SpeedAccuracyResult:
    """Run every configuration of ``budget`` with seeds 0..seeds-1 (exhaustive: once per seed too, for timing)."""
    if seeds < 1:
        raise ValueError(f"seeds {seeds}: expected at least 1")
    runner = runner or SerialRunner()
    cfgs = configs(budget)
    tasks = [RunTask(spec, c, s, light_sets) for s in range(seeds) for c in cfgs]
    t0 = time.perf_counter()
    if isinstance(runner, SerialRunner):
        runs = []
        for i, t in enumerate(tasks):
            check(cancel)
            runs.append(run_task(t))
            report(progress, (i + 1) / len(tasks), f"speed-accuracy: {t.config.label}, seed {t.seed}")
    else:
        runs = runner.map(run_task, tasks)
    n_sets = light_sets or len(light_pairs())
    result = SpeedAccuracyResult(spec, budget, list(range(seeds)), min(n_sets, len(light_pairs())), runs,
                                 runner=getattr(runner, "describe", dict)(),
                                 elapsed_s=time.perf_counter() - t0)
    result.summary = summarise(runs, [c.label for c in cfgs])
    for key, attr in (("train", "pareto_train"), ("test", "pareto_test")):
        pts = [(r["cpu_seconds"]["median"], r[key]["median"]) for r in result.summary]
        setattr(result, attr, [result.summary[i]["label"] for i in pareto_front(pts)])
    return result


# ---------------------------------------------------------------------------------------------------------
_COLOURS = {"exhaustive": "black", "pso": "tab:blue", "ga": "tab:orange", "halving": "tab:green",
            "pyswarms": "tab:purple", "de": "tab:red", "lbfgs": "tab:brown"}
_MARKERS = {"exhaustive": "s", "pso": "o", "ga": "^", "halving": "D", "pyswarms": "v", "de": "P", "lbfgs": "X"}


def _spread(row: dict, key: str) -> tuple[float, list[list[float]]]:
    v = row[key]
    return v["median"], [[v["median"] - v["min"]], [v["max"] - v["median"]]]


def pareto_chart(result: SpeedAccuracyResult):
    """CPU seconds (median, min-max over seeds) against the best light set's training figures: left the noise-free
    cost the search minimised (filled) beside the same light set's expected captured error (hollow, joined by a
    line), right its per-pixel error (filled: training, hollow: test); a ring marks a configuration whose best light
    set asked for a level below the sphere's minimum (what the sphere holds is scored)."""
    fig, axes = new_figure(11.0, 5.6, ncols=2)
    left, right = axes
    seen = set()
    for row in result.summary:
        m = row["method"]
        style = dict(color=_COLOURS.get(m, "grey"), ms=6, capsize=2, lw=0.8, fmt=_MARKERS.get(m, "o"))
        x, xerr = _spread(row, "cpu_seconds")
        for ax, filled, hollow in ((left, "train", "expected_train"), (right, "per_pixel_train", "per_pixel_test")):
            y, yerr = _spread(row, filled)
            ax.errorbar(x, y, xerr=xerr, yerr=yerr, label=None if m in seen else LABELS.get(m, m), **style)
            y2, yerr2 = _spread(row, hollow)
            ax.errorbar(x, y2, yerr=yerr2, mfc="none", **style)
            ax.plot([x, x], [y, y2], color=style["color"], lw=0.6, alpha=0.6)
            if row["below_min_level_runs"]:
                ax.plot([x, x], [y, y2], "o", ms=13, mfc="none", mec="red", mew=1.2)
        seen.add(m)
        if m == "pso":
            left.annotate(row["label"].replace("pso ", "").replace(" (thesis)", "*"), (x, row["train"]["median"]),
                          textcoords="offset points", xytext=(4, 3), fontsize=7, color=_COLOURS["pso"])
    rows = {r["label"]: r for r in result.summary}
    front = result.pareto_train
    left.step([rows[k]["cpu_seconds"]["median"] for k in front], [rows[k]["train"]["median"] for k in front],
              where="post", color="grey", lw=1, ls="--", label="Pareto front (noise-free medians)")
    left.plot([], [], "s", mfc="none", color="grey", label="hollow: expected captured")
    left.plot([], [], "o", ms=11, mfc="none", mec="red", label="a level below the sphere's minimum")
    right.plot([], [], "o", mfc="none", color="grey", label="hollow: test")
    left.set_ylabel("best light set: training mean dE00 (patch means)")
    right.set_ylabel("same light set: per-pixel mean dE00 (expected)")
    medians = [row[k]["median"] for row in result.summary for k in ("per_pixel_train", "per_pixel_test")]
    if medians:
        right.set_ylim(0.0, 1.35 * max(medians))             # a seed's bar may run far above: clipped, in the JSON
    load = result.summary[0]["load"]["median"] if result.summary else float("nan")
    for ax, title in ((left, "noise-free (filled) and expected captured"), (right, "per pixel: train and test")):
        ax.set_xscale("log")
        ax.set_xlabel("CPU seconds per run (median, min-max over seeds)")
        ax.set_title(f"{title}: {result.light_sets} light sets, {len(result.seeds)} seeds", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = left.get_legend_handles_labels()
    more = [(h, lab) for h, lab in zip(*right.get_legend_handles_labels(), strict=True) if lab not in labels]
    fig.legend(handles + [h for h, _ in more], labels + [lab for _, lab in more], loc="outside lower center",
               ncol=4, fontsize=7)
    fig.suptitle(f"Speed vs accuracy (* = thesis PSO 200 particles x 10 iterations; load average {load:.1f} during "
                 "the runs, wall times in the JSON)", fontsize=10)
    return fig


def _trace_band(runs: list[dict], grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    curves = []
    for r in runs:
        ev = np.asarray(r["trace"]["evaluations"], dtype=float)
        best = np.asarray(r["trace"]["best"], dtype=float)
        if ev.size == 0:
            continue
        pos = np.searchsorted(ev, grid, side="right") - 1
        curves.append(np.where(pos >= 0, best[np.clip(pos, 0, None)], np.nan))
    c = np.asarray(curves)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)     # grid points before a run's first evaluation
        return np.nanmedian(c, axis=0), np.nanmin(c, axis=0), np.nanmax(c, axis=0)


def convergence_chart(result: SpeedAccuracyResult):
    fig, axes = new_figure(8.0, 4.8)
    ax = axes
    max_ev = max(max(r["trace"]["evaluations"] or [1]) for r in result.runs)
    grid = np.geomspace(10, max(max_ev, 20), 300)
    shown = set()
    for row in result.summary:
        m, label = row["method"], row["label"]
        if m == "pso" and "(thesis)" not in label:
            continue            # the sweep's other points are on the Pareto chart
        rs = [r for r in result.runs if r["label"] == label]
        med, lo, hi = _trace_band(rs, grid)
        col = _COLOURS.get(m, "grey")
        if m == "exhaustive":
            ax.plot(row["evaluations"]["median"], row["train"]["median"], "s", color=col, label=label)
            continue
        ax.plot(grid, med, color=col, lw=1.5, label=label)
        ax.fill_between(grid, lo, hi, color=col, alpha=0.15, lw=0)
        shown.add(m)
    ax.set_xscale("log")
    finite = [r["train"]["median"] for r in result.summary]
    ax.set_ylim(min(finite) * 0.95, max(finite) * 1.6 + 0.05)
    ax.set_xlabel("cost evaluations")
    ax.set_ylabel("lowest training mean dE00 evaluated so far")
    ax.set_title("Convergence (median over seeds, band = min-max)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def write_outputs(result: SpeedAccuracyResult, out: StudyOutput) -> None:
    out.write_json("speed_accuracy.json", result.to_json())
    out.save_figure(pareto_chart(result), "pareto.png")
    out.save_figure(convergence_chart(result), "convergence.png")
    rows = result.summary
    best_train = min(r["train"]["median"] for r in rows)
    lines = [f"Setup: {result.spec.label()}; {result.light_sets} binned light sets; budget '{result.budget}'; "
             f"seeds {result.seeds}; runner {result.runner.get('runner', 'serial')}; total "
             f"{result.elapsed_s:.0f} s wall.", "",
             "| configuration | CPU s (median) | evaluations | wall s (load) | best train dE00 (median [min-max]) | "
             "test | expected captured train / test | per pixel train / test (p90) | below min. level |",
             "|---|---:|---:|---:|---|---:|---|---|---:|"]
    for r in rows:
        tr = r["train"]
        med = {k: r[k]["median"] for k in FIGURES}
        lines.append(f"| {r['label']} | {r['cpu_seconds']['median']:.2f} | {r['evaluations']['median']:.0f} | "
                     f"{r['seconds']['median']:.2f} ({r['load']['median']:.1f}) | "
                     f"{tr['median']:.4f} [{tr['min']:.4f}-{tr['max']:.4f}] | {med['test']:.4f} | "
                     f"{med['expected_train']:.3f} / {med['expected_test']:.3f} | {med['per_pixel_train']:.3f} / "
                     f"{med['per_pixel_test']:.3f} ({med['per_pixel_test_p90']:.3f}) | "
                     f"{r['below_min_level_runs']} of {len(result.seeds)} |")
    near = [r for r in rows if r["train"]["median"] <= best_train + 0.01]
    fastest = min(near, key=lambda r: r["cpu_seconds"]["median"])
    lines += ["", f"Pareto front (train, CPU seconds): {', '.join(result.pareto_train)}.",
              f"Pareto front (test, CPU seconds): {', '.join(result.pareto_test)}.",
              f"Lowest median training error: {best_train:.4f}; cheapest configuration within 0.01 of it: "
              f"**{fastest['label']}** ({fastest['cpu_seconds']['median']:.2f} CPU s, "
              f"{fastest['evaluations']['median']:.0f} evaluations).",
              "", "pyswarms, differential evolution and L-BFGS-B optimise one light set at a time in a Python "
              "loop over the sets (L-BFGS-B only on the best sets of a random screen); PSO, GA and "
              "successive halving are vectorised over sets. CPU seconds are the process's (all its threads); wall "
              "times move with the machine's load (the load average beside them)."]
    out.write_summary("Speed vs accuracy", lines)
