"""Speed against accuracy of every optimiser on the binned light sets (``dualrgb study speed-accuracy``).

Each configuration (a method with its settings) runs once per seed on the same evaluator. A run records its
wall time, its evaluations, the best training dE00 it found (float64 re-evaluation, as reports do), that
light set's test dE00, and its anytime curve (lowest cost evaluated so far against evaluations and seconds,
in the order the method spends them: PSO and GA work through the light sets 16 at a time, successive halving
visits every set first). Results are summarised per configuration as median and min-max over seeds.

Outputs: ``speed_accuracy.json``, ``pareto.png`` (median time vs median best error, train and test, with the
Pareto front), ``convergence.png`` (best-so-far error vs evaluations, median and spread over seeds) and
``SUMMARY.md``.
"""
from __future__ import annotations

import logging
import time
import warnings
from dataclasses import dataclass, field
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


def run_task(task: RunTask) -> dict:
    """One configuration, one seed (a Dask task): errors, time, evaluations and the anytime trace."""
    ev = evaluator_for(task.spec)
    groups = light_pairs()
    if task.light_sets:
        groups = groups[:task.light_sets]
    warm_up(ev)
    traced = TracedEvaluator(ev)
    fn = OPTIMISERS[task.config.method]
    n0 = ev.evaluations
    t0 = time.perf_counter()
    out = fn(traced, groups, task.config.settings, task.seed)
    seconds = time.perf_counter() - t0
    refine_top(ev, out, 1)
    best = out.best
    return {"method": task.config.method, "label": task.config.label, "seed": task.seed,
            "seconds": seconds, "evaluations": ev.evaluations - n0, "train_cost": best.train_cost,
            "train": best.train_errors.mean, "test": best.test_errors.mean,
            "best": {**best.to_dict(), "levels_exact": {str(i + 1): list(src.levels)
                                                        for i, src in enumerate(best.sources)}},
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
                     "seconds": median_spread([r["seconds"] for r in rs]),
                     "evaluations": median_spread([r["evaluations"] for r in rs]),
                     "train": median_spread([r["train"] for r in rs]),
                     "test": median_spread([r["test"] for r in rs]),
                     "distinct_best_pairs": len(pairs)})
    return rows


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
        pts = [(r["seconds"]["median"], r[key]["median"]) for r in result.summary]
        setattr(result, attr, [result.summary[i]["label"] for i in pareto_front(pts)])
    return result


# ---------------------------------------------------------------------------------------------------------
_COLOURS = {"exhaustive": "black", "pso": "tab:blue", "ga": "tab:orange", "halving": "tab:green",
            "pyswarms": "tab:purple", "de": "tab:red", "lbfgs": "tab:brown"}
_MARKERS = {"exhaustive": "s", "pso": "o", "ga": "^", "halving": "D", "pyswarms": "v", "de": "P", "lbfgs": "X"}


def pareto_chart(result: SpeedAccuracyResult):
    fig, axes = new_figure(11.0, 4.6, ncols=2)
    for ax, key, front in ((axes[0], "train", result.pareto_train), (axes[1], "test", result.pareto_test)):
        seen = set()
        for row in result.summary:
            m = row["method"]
            x, y = row["seconds"], row[key]
            ax.errorbar(x["median"], y["median"],
                        xerr=[[x["median"] - x["min"]], [x["max"] - x["median"]]],
                        yerr=[[y["median"] - y["min"]], [y["max"] - y["median"]]],
                        fmt=_MARKERS.get(m, "o"), color=_COLOURS.get(m, "grey"), ms=6, capsize=2, lw=0.8,
                        label=None if m in seen else LABELS.get(m, m))
            seen.add(m)
            if m == "pso":
                ax.annotate(row["label"].replace("pso ", "").replace(" (thesis)", "*"), (x["median"], y["median"]),
                            textcoords="offset points", xytext=(4, 3), fontsize=7, color=_COLOURS["pso"])
        rows = {r["label"]: r for r in result.summary}
        fx = [rows[label]["seconds"]["median"] for label in front]
        fy = [rows[label][key]["median"] for label in front]
        ax.step(fx, fy, where="post", color="grey", lw=1, ls="--", label="Pareto front (medians)")
        ax.set_xscale("log")
        ax.set_xlabel("wall time per run, s (median, min-max over seeds)")
        ax.set_ylabel(f"best {key} mean dE00")
        ax.set_title(f"{key}: {result.light_sets} light sets, {len(result.seeds)} seeds")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper right")
    fig.suptitle("Speed vs accuracy (* = thesis PSO 200 particles x 10 iterations)", fontsize=10)
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
             f"{result.elapsed_s:.0f} s.", "",
             "| configuration | time s (median) | evaluations | best train dE00 (median [min-max]) | "
             "test dE00 (median) | distinct best pairs |",
             "|---|---:|---:|---|---:|---:|"]
    for r in rows:
        tr = r["train"]
        lines.append(f"| {r['label']} | {r['seconds']['median']:.2f} | {r['evaluations']['median']:.0f} | "
                     f"{tr['median']:.4f} [{tr['min']:.4f}-{tr['max']:.4f}] | {r['test']['median']:.4f} | "
                     f"{r['distinct_best_pairs']} |")
    near = [r for r in rows if r["train"]["median"] <= best_train + 0.01]
    fastest = min(near, key=lambda r: r["seconds"]["median"])
    lines += ["", f"Pareto front (train): {', '.join(result.pareto_train)}.",
              f"Pareto front (test): {', '.join(result.pareto_test)}.",
              f"Lowest median training error: {best_train:.4f}; fastest configuration within 0.01 of it: "
              f"**{fastest['label']}** ({fastest['seconds']['median']:.2f} s, "
              f"{fastest['evaluations']['median']:.0f} evaluations).",
              "", "pyswarms, differential evolution and L-BFGS-B optimise one light set at a time in a Python "
              "loop over the sets (L-BFGS-B only on the best sets of a random screen); PSO, GA and "
              "successive halving are vectorised over sets. Times are wall-clock on this machine."]
    out.write_summary("Speed vs accuracy", lines)
