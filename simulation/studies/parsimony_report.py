"""Outputs of ``dualrgb study parsimony``: one chart with a row per mode, the JSON, the per-mode defaults and the
Markdown summary (the computation: :mod:`.parsimony`)."""
from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dualrgb.simulation.studies.common import StudyOutput
from dualrgb.simulation.studies.models import MODELS
from dualrgb.simulation.studies.parsimony import ParsimonyResult, defaults_header

log = logging.getLogger(__name__)


def _grid_panel(ax, result: ParsimonyResult) -> None:
    rows = result.steps["rows"]
    tol = result.config.tolerance
    x = np.arange(len(rows))
    for key, mk in (("exhaustive", "s"), ("optimiser", "o")):
        ax.plot(x, [r[key]["ref_train"] for r in rows], mk + "-", label=f"{key} optimum, on the reference")
        ax.plot(x, [r[key]["own_train"] for r in rows], mk + ":", mfc="none", label=f"{key}, grid's own estimate")
        ref = rows[0][key]["ref_train"]
        ax.axhspan(ref - tol, ref + tol, alpha=0.08, color="grey")
    chosen = result.steps["chosen"]["label"]
    for i, r in enumerate(rows):
        if r["label"] == chosen:
            ax.axvline(i, color="tab:green", ls="--", label=f"chosen {chosen} nm")
    ax.set_xticks(x, [r["label"] + ("\n(thesis)" if r["thesis_grid"] else "") + ("" if r["acceptable"] else "\nmisses")
                      for r in rows], fontsize=6)
    ax.set_ylabel("training mean dE00")
    ax.set_title(f"{result.mode}: (a) spectral grid (band ±{tol} of reference)", fontsize=9)
    ax.legend(fontsize=5)
    ax.grid(True, alpha=0.3)


def _speed_panel(ax, result: ParsimonyResult) -> None:
    rows = result.steps["rows"]
    x = np.arange(len(rows))
    ax.bar(x - 0.2, [r["expected_us_per_evaluation"] for r in rows], 0.4, label="expected-captured, µs / evaluation")
    ax.bar(x + 0.2, [r["noise_free_us_per_evaluation"] for r in rows], 0.4, label="noise-free, µs / evaluation")
    ax.set_ylabel("µs per evaluation")
    ax2 = ax.twinx()
    ax2.plot(x, [r["optimiser_s"] for r in rows], "k^-", label="one run of the default optimiser, s")
    ax2.plot(x, [r["setup_noise_free_s"] + r["setup_expected_s"] for r in rows], "kv:", label="set-up, s")
    ax2.set_ylabel("seconds")
    ax.set_xticks(x, [f"{r['label']}\n{r['wavelengths']} λ" for r in rows], fontsize=6)
    ax.set_title(f"{result.mode}: (b) cost of the grid (CPU, best of {result.config.timing_repeats})", fontsize=9)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=5)
    ax.grid(True, axis="y", alpha=0.3)


def _model_panel(ax, result: ParsimonyResult) -> None:
    m = result.models
    tol = result.config.tolerance
    x = np.arange(len(MODELS))
    for j, name in enumerate(m["results"]):
        r = m["results"][name]["captured"]
        off = (j - 0.5) * 0.4
        ax.bar(x + off, [r[k]["cv"] for k in MODELS], 0.38, yerr=[r[k]["cv_se"] for k in MODELS], capsize=2,
               label=f"{name}: training, 5-fold CV (criterion)")
        ax.plot(x + off, [r[k]["test"] for k in MODELS], "kx", ms=6, label="test (reported only)" if j == 0 else None)
    ax.axhline(m["best"] + tol, color="grey", ls="--", label=f"best + {tol}")
    ax.set_xticks(x, [f"{k}\n({m['terms'][k]} terms)" + ("" if k in m["candidates"] else "\nnot delivered")
                      for k in MODELS], fontsize=6)
    ax.set_ylabel("captured mean dE00")
    ax.set_title(f"{result.mode}: (c) model: chosen {m['chosen']}", fontsize=9)
    ax.legend(fontsize=5)
    ax.grid(True, axis="y", alpha=0.3)


def _exposure_panel(ax, result: ParsimonyResult) -> None:
    e = result.exposures
    tol = result.config.tolerance
    n = [r["exposures"] for r in e["rows"]]
    for name in ("exhaustive", "pso"):
        ax.errorbar(n, [r[name]["nd_cv"] for r in e["rows"]], yerr=[r[name]["nd_cv_se"] for r in e["rows"]],
                    fmt="o-", capsize=2, label=f"{name}: ND 2.0 on half, training CV")
        ax.plot(n, [r[name]["nd_test"] for r in e["rows"]], "x:", label=f"{name}: test (reported only)")
    ax.axhline(e["best"] + tol, color="grey", ls="--", label=f"best + {tol}")
    ax.axvline(e["chosen"], color="tab:green", ls="--", label=f"chosen {e['chosen']}")
    ax.set_xticks(n)
    ax.set_xlabel(f"exposures per light (1x .. 100x), merge: {e['hdr_merge']}")
    ax.set_ylabel("captured mean dE00")
    ax.set_title(f"{result.mode}: (d) HDR exposures", fontsize=9)
    ax.legend(fontsize=5)
    ax.grid(True, alpha=0.3)


def parsimony_chart(results: Sequence[ParsimonyResult]):
    """A row per mode: grid accuracy, grid cost, characterisation model, HDR exposures."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(17.0, 4.3 * len(results)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = np.atleast_2d(fig.subplots(len(results), 4))
    for row, result in zip(axes, results, strict=True):
        _grid_panel(row[0], result)
        _speed_panel(row[1], result)
        _model_panel(row[2], result)
        _exposure_panel(row[3], result)
    return fig


def _grid_lines(result: ParsimonyResult) -> list[str]:
    s = result.steps
    lines = [f"### {result.mode}: spectral grid (reference {s['rows'][0]['label']} nm)", "",
             "| grid nm | λ | exhaustive pair | on ref. (train) | own | optimiser on ref. | own | deviation | "
             "acceptable | µs/eval expected | µs/eval noise-free | optimiser run s | set-up s |",
             "|---|---:|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|"]
    for r in s["rows"]:
        lines.append(f"| {r['label']}{' (thesis)' if r['thesis_grid'] else ''} | {r['wavelengths']} | "
                     f"{r['exhaustive']['pair']} | {r['exhaustive']['ref_train']:.4f} | "
                     f"{r['exhaustive']['own_train']:.4f} | {r['optimiser']['ref_train']:.4f} | "
                     f"{r['optimiser']['own_train']:.4f}"
                     f" | {r['deviation']:.4f} | {r['acceptable']} | {r['expected_us_per_evaluation']:.2f} | "
                     f"{r['noise_free_us_per_evaluation']:.2f} | {r['optimiser_s']:.2f} | "
                     f"{r['setup_noise_free_s'] + r['setup_expected_s']:.3f} |")
    lines += ["", f"Chosen grid: **{s['chosen']['label']} nm** (the thesis' 410-780/10 is "
              f"{'acceptable, so it is kept' if s['thesis_grid_acceptable'] else 'NOT acceptable'}; CPU times are "
              f"the best of {result.config.timing_repeats}).", ""]
    return lines


def _choice_lines(result: ParsimonyResult) -> list[str]:
    m, e = result.models, result.exposures
    lines = [f"### {result.mode}: characterisation model ({m['criterion']}; light sets: {m['light_sets_from']})", ""]
    lines += [f"- {k} ({m['terms'][k]} terms): CV {m['scores'][k]:.4f}, test {m['test_reported'][k]:.4f} (reported)"
              + ("" if k in m["candidates"] else "; not delivered by the processing") for k in MODELS]
    lines += ["", f"Chosen: **{m['chosen']}**.", "", f"### {result.mode}: HDR exposures ({e['criterion']})", ""]
    lines += [f"- {r['exposures']} exposure(s) x{', '.join(f'{f:.3g}' for f in r['factors'])}: CV {sc:.4f}, "
              f"test {te:.4f} (reported)"
              for r, sc, te in zip(e["rows"], e["scores"], e["test_reported"], strict=True)]
    return lines + ["", f"Chosen: **{e['chosen']}** exposure(s) per light.", ""]


def write_outputs(results: Sequence[ParsimonyResult], out: StudyOutput, defaults_path: str | None = None) -> None:
    """parsimony_study.json (every mode), parsimony.json (the per-mode defaults, also written into
    ``defaults_path`` when given, keeping the HDR study's keys there), parsimony.png, SUMMARY.md."""
    from dualrgb.simulation.defaults import save_defaults

    out.write_json("parsimony_study.json", {"modes": {r.mode: r.to_json() for r in results}})
    targets: list[str | Path] = [out.folder / "parsimony.json", *([defaults_path] if defaults_path else [])]
    for path in targets:
        for r in results:
            save_defaults(path, r.mode, r.defaults(), header=defaults_header())
    out.files.append(out.folder / "parsimony.json")
    out.save_figure(parsimony_chart(results), "parsimony.png")
    lines = [f"Setups: {', '.join(r.spec.label() for r in results)}; tolerance {results[0].config.tolerance} mean "
             f"dE00; total {sum(r.elapsed_s for r in results):.0f} s.", "",
             "Every choice is made on training data (the reference grid's training error, or cross-validation on "
             "the captured training target); the test target is reported beside it, never used to choose.", ""]
    for r in results:
        lines += _grid_lines(r) + _choice_lines(r)
    lines += ["Defaults written to parsimony.json, one entry per mode (`dualrgb study parsimony --write-defaults` "
              "makes them the app's defaults)."]
    out.write_summary("Parsimony", lines)
