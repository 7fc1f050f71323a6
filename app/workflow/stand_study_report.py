"""``dualrgb study stand``'s outputs (app/lab/stand_study.py), made from its JSON document so that they can be
made again from a saved ``stand.json`` (``study stand --from-json``) without running the study: the Markdown tables
(SUMMARY.md, and the docs page's generated section between ``<!-- stand:start -->`` and ``<!-- stand:end -->``), the
charts.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import numpy as np

log = logging.getLogger(__name__)

SECTION = "stand"                   # the page's generated section: <!-- stand:start --> ... <!-- stand:end -->


def section_of(doc: dict[str, Any]) -> str:
    """The page's generated section for a study's mode: ``stand`` (reflective), ``stand-transmissive`` (film)."""
    mode = doc["config"]["mode"]
    return SECTION if mode == "reflective" else f"{SECTION}-{mode}"
DOC_PAGE = "docs/explanation/stand-model.md"      # the docs page that holds it (`--doc`)
FORMATS = ("dualrgb-study-stand/2",)
PRESET, WORKFLOW = "nominal preset", "fitted, measured camera and LEDs"
REOPTIMISED = f"re-optimised: {WORKFLOW}"


def load_study(path: str | Path) -> dict[str, Any]:
    """A saved study document; ValueError (one line) naming the file when it is not one."""
    p = Path(path)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"{p}: cannot read ({exc.strerror or exc})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{p}:{exc.lineno}: not valid JSON ({exc.msg})") from None
    if not isinstance(doc, dict) or doc.get("format") not in FORMATS or not isinstance(doc.get("worlds"), dict):
        raise ValueError(f"{p}: expected a study stand document ({', '.join(FORMATS)}), found format "
                         f"{doc.get('format') if isinstance(doc, dict) else None!r}")
    return doc


def _pct(v: float) -> str:
    return f"{100 * v:+.1f} %"


def _misses(entry: dict[str, Any]) -> str:
    each = entry["miss"]["test_each"]
    return f"{_pct(entry['miss']['test'])} ({_pct(min(each))} to {_pct(max(each))})"


def workflow_table(doc: dict[str, Any]) -> list[str]:
    """One row per world: the preset's and the re-optimised lights' captured test dE00 (mean over the seeds)
    beside what each calibration's stand fit predicted (mean; the miss of the mean and each seed's range)."""
    n = len(doc["config"]["seeds"])
    lines = [f"| World | Preset: captured test dE00 | predicted | miss ({n} seeds) | Re-optimised lights: captured | "
             f"predicted | miss ({n} seeds) | captured vs the preset |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for name, w in doc["worlds"].items():
        p, r = w["workflow"]["preset"], w["workflow"]["re-optimised"]
        kept = " (the preset kept)" if r.get("preset_kept") else ""
        lines.append(f"| `{name}` | {p['captured']['test']:.3f} | {p['predicted']['test']:.3f} | {_misses(p)} | "
                     f"{r['captured']['test']:.3f}{kept} | {r['predicted']['test']:.3f} | {_misses(r)} | "
                     f"{_pct(r['captured']['test'] / p['captured']['test'] - 1)} |")
    return lines


def models_table(world: dict[str, Any]) -> list[str]:
    """Every model's R^2 and predicted test dE00 for the preset's lights (seed 0's calibration)."""
    cap = world["lights"][PRESET]["captured"]
    lines = [f"| Model | R² train (worst channel) | R² test | predicted test dE00 (captured {cap['test']:.3f}) "
             "| miss |", "| --- | ---: | ---: | ---: | ---: |"]
    for name, m in world["models"].items():
        r2_test = "-" if m["r2_test"] is None else f"{m['r2_test']:.5f}"
        lines.append(f"| {name} | {m['r2_train']:.5f} | {r2_test} | {m['predicted']['test']:.3f} | "
                     f"{_pct(m['miss']['test'])} |")
    return lines


def lights_table(world: dict[str, Any]) -> list[str]:
    """Every light set's captured dE00 against the preset's and the world's optimum (when re-optimised on it)."""
    base = world["lights"][PRESET]["captured"]
    best = world["lights"].get("re-optimised: world", {}).get("captured")
    lines = ["| Lights | captured train dE00 | captured test dE00 | train vs preset | train vs world's optimum |",
             "| --- | ---: | ---: | ---: | ---: |"]
    for name, entry in world["lights"].items():
        c = entry["captured"]
        vs_world = _pct(c["train"] / best["train"] - 1) if best else "-"
        lines.append(f"| {name} | {c['train']:.4f} | {c['test']:.4f} | {_pct(c['train'] / base['train'] - 1)} | "
                     f"{vs_world} |")
    return lines


def summary_lines(doc: dict[str, Any], source: str = "stand.json") -> list[str]:
    """The study's tables (SUMMARY.md): the workflow in every world, then each world's models and light sets
    where they were compared."""
    cfg = doc["config"]
    lines = [f"Generated from `{source}` ({doc['format']}; `dualrgb study stand`, {cfg['mode']}, "
             f"{cfg['frame_size'][0]}x{cfg['frame_size'][1]} frames, seeds {', '.join(map(str, cfg['seeds']))}; "
             f"{doc['elapsed_s'] / 60:.0f} min). Captured mean dE00 with the least-squares matrix (the objective's), "
             "averaged over the seeds; predicted: each calibration's stand fit from the measured camera and LEDs "
             "(`calibrate --camera-csv --stand-dir`) for its own lights.", "", *workflow_table(doc)]
    for name, world in doc["worlds"].items():
        if len(world["models"]) > 1:
            lines += ["", f"World `{name}`, the models (seed {cfg['seeds'][0]}'s calibration):", "",
                      *models_table(world), "", *lights_table(world)]
    return lines


def readme_section(doc: dict[str, Any], source: str) -> str:
    """The docs page's generated section: the study's tables (:func:`summary_lines`) and where they came from."""
    return "\n".join([*summary_lines(doc, source), "",
                      f"Made by `dualrgb study stand --from-json {source} --doc {DOC_PAGE}` from the study's JSON."])


# ---- charts ---------------------------------------------------------------------------------------------------
def workflow_figure(doc: dict[str, Any]) -> Any:
    """Per world: the preset's and the re-optimised lights' captured test dE00 (bars: mean over seeds; whiskers:
    their range) and what the calibrations' stand fits predicted (markers: each seed)."""
    from dualrgb.simulation.studies.common import new_figure

    worlds = list(doc["worlds"])
    fig, ax = new_figure(max(6.0, 1.6 * len(worlds) + 2.0), 4.6)
    x = np.arange(len(worlds))
    for off, key, colour, label in ((-0.2, "preset", "#90a4ae", "preset"),
                                    (0.2, "re-optimised", "#1565c0", "re-optimised")):
        entries = [doc["worlds"][w]["workflow"][key] for w in worlds]
        mean = np.array([e["captured"]["test"] for e in entries])
        lo = mean - np.array([min(e["captured"]["test_each"]) for e in entries])
        hi = np.array([max(e["captured"]["test_each"]) for e in entries]) - mean
        ax.bar(x + off, mean, width=0.38, color=colour, yerr=[lo, hi], capsize=3, label=f"{label}: captured")
        for i, e in enumerate(entries):
            ax.plot([x[i] + off] * len(e["predicted"]["test_each"]), e["predicted"]["test_each"], "D",
                    color="#c62828", ms=4, label="predicted (each seed)" if i == 0 and key == "preset" else None)
    ax.set_xticks(x, worlds, fontsize=8, rotation=12)
    ax.set_ylabel("test mean ΔE00 (least squares)")
    ax.set_title("the measurement workflow: predicted vs captured in each world")
    ax.legend(fontsize=8)
    return fig


def models_figure(world: dict[str, Any]) -> Any:
    """Left: each model's predicted test dE00 for the preset's lights against the captured one. Right: the
    captured train and test dE00 of each light set (bars: mean over seeds; whiskers: their range)."""
    from dualrgb.simulation.studies.common import new_figure

    fig, (a1, a2) = new_figure(12.0, 4.8, ncols=2)
    names = list(world["models"])
    cap = world["lights"][PRESET]["captured"]["test"]
    a1.bar(range(len(names)), [world["models"][n]["predicted"]["test"] for n in names], color="0.6")
    a1.axhline(cap, color="black", lw=1.2, label=f"captured {cap:.3f}")
    a1.set_xticks(range(len(names)), [f"{n}\nR² {world['models'][n]['r2_train']:.4f}" for n in names], fontsize=7,
                  rotation=15)
    a1.set_ylabel("test mean ΔE00 (preset's lights)")
    a1.set_title("predicted by each model vs captured")
    a1.legend(fontsize=8)
    lights = list(world["lights"])
    x = np.arange(len(lights))
    for off, which, colour in ((-0.2, "train", "#1565c0"), (0.2, "test", "#ef6c00")):
        c = [world["lights"][n]["captured"] for n in lights]
        mean = np.array([v[which] for v in c])
        lo = mean - np.array([min(v[f"{which}_each"]) for v in c])
        hi = np.array([max(v[f"{which}_each"]) for v in c]) - mean
        a2.bar(x + off, mean, width=0.4, color=colour, label=which, yerr=[lo, hi], capsize=3)
    a2.set_xticks(x, [n.replace("re-optimised: ", "re-opt.\n") for n in lights], fontsize=7, rotation=15)
    a2.set_ylabel("captured mean ΔE00 (least squares)")
    a2.set_title(f"lights captured in world {world['world']}")
    a2.legend(fontsize=8)
    return fig


def write_outputs(doc: dict[str, Any], out: Any, source: str = "stand.json") -> None:
    """``stand.json`` (unless the document came from one), ``study_stand.png``, ``study_stand_models.png`` (the
    first world compared) and ``SUMMARY.md`` into ``out`` (simulation.studies.common.StudyOutput)."""
    if source == "stand.json":
        out.write_json("stand.json", doc)
    out.save_figure(workflow_figure(doc), "study_stand.png")
    compared = [w for w in doc["worlds"].values() if len(w["models"]) > 1]
    if compared:
        out.save_figure(models_figure(compared[0]), "study_stand_models.png")
    out.write_summary("Stand model study", summary_lines(doc, source))
