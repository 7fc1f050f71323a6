"""Many setups x optimisers x seeds (``dualrgb study sweep``): the study that outgrows one machine.

Every (setup, configuration, seed) is one task (:func:`simulation.studies.speed_accuracy.run_task`), so a
sweep over targets (reflective / transmissive or users' CSVs), cameras (CSVs) and seeds spreads over a Dask
cluster as it is; results are gathered in task order and identical to a serial run.

Outputs: ``sweep.json`` (every run), ``sweep.png`` (best training dE00 per setup and configuration, median and
min-max over seeds) and ``SUMMARY.md``.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from dualrgb.simulation.studies.common import SetupSpec, StudyOutput, median_spread, new_figure
from dualrgb.simulation.studies.distributed import Runner, SerialRunner
from dualrgb.simulation.studies.speed_accuracy import Config, RunTask, configs, run_task

log = logging.getLogger(__name__)


@dataclass
class SweepResult:
    specs: list[SetupSpec]
    labels: list[str]
    seeds: int
    runs: list[dict]
    runner: dict
    elapsed_s: float
    table: list[dict] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"setups": [s.to_dict() for s in self.specs], "configurations": self.labels, "seeds": self.seeds,
                "runner": self.runner, "elapsed_s": round(self.elapsed_s, 2), "table": self.table,
                "runs": self.runs}


def _setup_label(spec: SetupSpec) -> str:
    cam = f", camera {spec.camera_csv}" if spec.camera_csv else ""
    return f"{spec.mode}{cam}"


def sweep(specs: Sequence[SetupSpec], methods: Sequence[str] = ("exhaustive", "pso", "halving"), *,
          budget: str = "small", seeds: int = 2, light_sets: int | None = None,
          runner: Runner | None = None) -> SweepResult:
    """Run the ``budget`` configurations of ``methods`` (PSO: its thesis setting only) on every setup and seed."""
    runner = runner or SerialRunner()
    chosen: list[Config] = []
    for c in configs(budget):
        if c.method not in methods:
            continue
        if c.method == "pso" and any(x.method == "pso" for x in chosen):
            continue
        chosen.append(c)
    if not chosen:
        raise ValueError(f"methods {', '.join(methods)}: none is a study optimiser")
    tasks = [RunTask(spec, c, s, light_sets) for spec in specs for c in chosen for s in range(seeds)]
    t0 = time.perf_counter()
    results = runner.map(run_task, tasks)
    for task, r in zip(tasks, results, strict=True):
        r["setup"] = _setup_label(task.spec)
        r.pop("trace", None)
    res = SweepResult(list(specs), [c.label for c in chosen], seeds, results,
                      getattr(runner, "describe", lambda: {"runner": runner.name})(), time.perf_counter() - t0)
    for spec in specs:
        for c in chosen:
            rs = [r for r in results if r["setup"] == _setup_label(spec) and r["label"] == c.label]
            res.table.append({"setup": _setup_label(spec), "label": c.label,
                              "train": median_spread([r["train"] for r in rs]),
                              "test": median_spread([r["test"] for r in rs]),
                              "seconds": median_spread([r["seconds"] for r in rs]),
                              "pairs": sorted({f"{tuple(r['best']['source1'])}+{tuple(r['best']['source2'])}"
                                               for r in rs})})
    return res


def sweep_chart(result: SweepResult):
    setups = list(dict.fromkeys(r["setup"] for r in result.table))
    fig, ax = new_figure(max(6.0, 2.2 * len(setups) + 3), 4.5)
    width = 0.8 / len(result.labels)
    for j, label in enumerate(result.labels):
        rows = [next(r for r in result.table if r["setup"] == s and r["label"] == label) for s in setups]
        x = np.arange(len(setups)) + (j - (len(result.labels) - 1) / 2) * width
        med = [r["train"]["median"] for r in rows]
        err = [[r["train"]["median"] - r["train"]["min"] for r in rows],
               [r["train"]["max"] - r["train"]["median"] for r in rows]]
        ax.bar(x, med, width * 0.95, yerr=err, capsize=2, label=label)
    ax.set_xticks(range(len(setups)), setups, fontsize=8)
    ax.set_ylabel("best training mean dE00 (median, min-max over seeds)")
    ax.set_title(f"Sweep: {len(setups)} setups x {len(result.labels)} optimisers x {result.seeds} seeds "
                 f"({result.runner.get('runner')})")
    ax.legend(fontsize=7)
    ax.grid(True, axis="y", alpha=0.3)
    return fig


def write_outputs(result: SweepResult, out: StudyOutput) -> None:
    out.write_json("sweep.json", result.to_json())
    out.save_figure(sweep_chart(result), "sweep.png")
    lines = [f"{len(result.specs)} setups x {len(result.labels)} configurations x {result.seeds} seeds = "
             f"{len(result.runs)} runs on {result.runner}, {result.elapsed_s:.0f} s.", "",
             "| setup | configuration | best train (median [min-max]) | test (median) | best pairs |",
             "|---|---|---|---:|---|"]
    for r in result.table:
        t = r["train"]
        lines.append(f"| {r['setup']} | {r['label']} | {t['median']:.4f} [{t['min']:.4f}-{t['max']:.4f}] | "
                     f"{r['test']['median']:.4f} | {', '.join(r['pairs'])} |")
    out.write_summary("Sweep over setups, optimisers and seeds", lines)
