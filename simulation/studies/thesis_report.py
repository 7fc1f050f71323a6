"""The thesis comparison as rows, a Markdown table, JSON and the docs page's generated section (DOC_PAGE;
``dualrgb study thesis``; the figures: :mod:`.thesis`).

Each row: the thesis table (and mode), what is compared, the thesis' value, the project's, and one line saying
why they differ. Values agree when the light pair is the same and the error is within the thesis' rounding (two
decimals: +-0.005).
"""
from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.studies.common import replace_marked, write_marked

log = logging.getLogger(__name__)

FORMAT = "dualrgb-thesis-reproduction/1"
README_START, README_END = "<!-- thesis:start -->", "<!-- thesis:end -->"
DOC_PAGE = "docs/explanation/figures.md"      # the docs page holding the generated table (`--doc`)
ROUNDING = 0.005                       # the thesis prints two decimals

FILM = "synthetic three-dye film here, not the thesis' measured films (thesis 4.4)"
DATA = "training set: rawtoaces-190 here, ColorChecker Digital SG in the thesis"
CAPTURE = ("virtual lab (model noise, level grid; no reference error, drift or stray light) vs physical capture; "
           "synthetic film; this project's optimum lights")
COLLINEAR = "; (2, 5, 9) + (2, 6, 9) share LEDs 2 and 9: collinear channels amplify the noise"
SCALE = "by construction: the model's scale is set on this row (10 500 DN at 1/60 s); auto-exposure aims at 8 800 DN"
SPECTRA = "model LED and camera spectra (Table 4.2 peaks, Nikon 5100 stand-in), not the measured ones"
BRACKET = "thesis bracket starts below its own single exposure (Table 7.1), spans {ratio:.0f}x; here: open gate to 100x"
HDR = ("simulated HDR bracket (pixel level, synthetic film) vs physical capture; the thesis' HDR errors are twice its "
       "single-exposure ones (Table 7.2), which this model does not reproduce")
COPIED = "; the thesis' levels repeat Table 6.1's (film), see below"
AGREES = "agrees within the thesis' two decimals"
SAME = "agrees"


def pair(sources: list[list[int]], levels: list[list[float]] | None = None) -> str:
    """'(1, 6, 8) + (3, 5, 9)' or with levels '(1, 6, 7) @ (0.07, 0.58, 1) + ...' (4 significant digits)."""
    levels = levels or [[1.0] * len(s) for s in sources]
    return " + ".join(LightSource(tuple(s), tuple(float(v) for v in lv)).label()
                      for s, lv in zip(sources, levels, strict=True))


def _same_pair(a: list[list[int]], b: list[list[int]]) -> bool:
    return {tuple(x) for x in a} == {tuple(x) for x in b}


def _row(table: str, mode: str, quantity: str, thesis: str, project: str, reason: str) -> dict:
    return {"table": table, "mode": mode, "quantity": quantity, "thesis": thesis, "project": project,
            "reason": reason}


def _why(agree: bool, reason: str) -> str:
    return AGREES if agree else reason


def search_rows(t: dict, f: dict, table: str, mode: str, reason: str) -> list[dict]:
    """Tables 5.1 / 9.1: the top three full-intensity pairs and the rank of the thesis' best pair here."""
    rows = []
    for i, (tr, pr) in enumerate(zip(t["rows"], f["exhaustive_top"], strict=True)):
        agree = _same_pair([tr["source1"], tr["source2"]], pr["sources"]) and abs(pr["train"] - tr["train"]) <= ROUNDING
        rows.append(_row(table, mode, f"#{i + 1} pair, training mean dE00",
                         f"{pair([tr['source1'], tr['source2']])}: {tr['train']:.2f}",
                         f"{pair(pr['sources'])}: {pr['train']:.3f}", _why(agree, reason)))
    rows.append(_row(table, mode, "rank of the thesis' #1 pair here", "1", str(f["thesis_pair_rank"]),
                     SAME if f["thesis_pair_rank"] == 1 else reason))
    return rows


def _pm(value: float, se: float) -> str:
    """'value ± se' with the digits the standard error supports (at least two decimals, at most four)."""
    decimals = 2 if not se > 0 else min(4, max(2, int(-math.floor(math.log10(se))) + 1))
    return f"{value:.{decimals}f} ± {se:.{decimals}f}"


def _errors(train: float, test: float, digits: int) -> str:
    return f"{train:.{digits}f} / {test:.{digits}f}"


def comparison_rows(t: dict, f: dict, table: str, mode: str, reason: str) -> list[dict]:
    """Tables 6.1 / 9.2: 3-channel, full intensity and PSO: lights and training / test mean dE00."""
    rows = [_row(table, mode, "3-channel (D65) train / test", _errors(t["three_channel"]["train"],
                                                                     t["three_channel"]["test"], 2),
                 _errors(f["three_channel"]["train"], f["three_channel"]["test"], 3), reason)]
    for key, label, got in (("full_intensity", "full intensity", f["exhaustive_top"][0]), ("pso", "PSO", f["pso"])):
        th = t[key]
        same = _same_pair([th["source1"], th["source2"]], got["sources"])
        close = abs(got["train"] - th["train"]) <= ROUNDING and abs(got["test"] - th["test"]) <= ROUNDING
        rows.append(_row(table, mode, f"{label}: lights, train / test",
                         f"{pair([th['source1'], th['source2']], [th['levels1'], th['levels2']])}: "
                         f"{_errors(th['train'], th['test'], 2)}",
                         f"{pair(got['sources'], got['levels'])}: {_errors(got['train'], got['test'], 3)}",
                         _why(same and close, reason)))
    return rows


def ga_rows(t: dict, f: dict) -> list[dict]:
    """Table 6.2: the PSO and GA optima (the 'second opinion'): same pair or not, and the GA's errors."""
    agree_here = _same_pair(f["pso"]["sources"], f["ga"]["sources"])
    th, got = t["ga"], f["ga"]
    return [_row("6.2", "transmissive", "PSO pair", pair([t["pso"]["source1"], t["pso"]["source2"]]),
                 pair(f["pso"]["sources"]), FILM),
            _row("6.2", "transmissive", "GA: lights, train / test",
                 f"{pair([th['source1'], th['source2']], [th['levels1'], th['levels2']])}: "
                 f"{_errors(th['train'], th['test'], 2)}",
                 f"{pair(got['sources'], got['levels'])}: {_errors(got['train'], got['test'], 3)}", FILM),
            _row("6.2", "transmissive", "PSO and GA agree on the pair", "yes", "yes" if agree_here else "no",
                 SAME if agree_here else "here the GA stops on another pair than the PSO")]


def _seconds(t: float) -> str:
    return f"1/{1 / t:.0f} s" if t < 0.5 else f"{t:.3g} s"


def exposure_rows(f: dict) -> list[dict]:
    """Table 7.1: the single exposures of the thesis' own lights."""
    return [_row("7.1", "transmissive", f"exposure, {r['light']}", _seconds(r["thesis_s"]),
                 f"{_seconds(r['model_s'])} ({r['model_s'] / r['thesis_s']:.2f}x)", SCALE if i == 0 else SPECTRA)
            for i, r in enumerate(f["7.1"])]


def bracket_rows(f: dict, key: str) -> list[dict]:
    """Tables 8.1 / 8.2: the HDR brackets of the thesis' own lights."""
    which = "full intensity" if key == "8.1" else "PSO"
    return [_row(key, "transmissive", f"HDR bracket, {light} ({which})", " + ".join(_seconds(x) for x in v["thesis_s"]),
                 " + ".join(_seconds(x) for x in v["model_s"]),
                 BRACKET.format(ratio=v["thesis_s"][1] / v["thesis_s"][0])) for light, v in f[key].items()]


def capture_rows(t: dict, f: dict) -> list[dict]:
    """Table 7.2: real captures against the project's predicted and captured errors of its own optima."""
    rows = []
    cols = t["columns"]
    names = {"three_channel": "3-channel", "full_intensity": "full intensity", "pso": "PSO"}
    for metric, values in t["rows"].items():
        cells = []
        for c in cols:
            got = f[c]
            pred = got["predicted"][metric]
            cap = got["captured"].get(metric)
            se = got["captured"].get(f"{metric}_se")
            cells.append(f"{pred:.2f}" + (f" / {_pm(cap, se)}" if cap is not None else ""))
        rows.append(_row("7.2", "transmissive", f"{metric.replace('_', ' ')}: " + " / ".join(names[c] for c in cols)
                         + (" (predicted / captured ± SE)" if metric.startswith("mean") else " (predicted)"),
                         " / ".join(f"{v:.2f}" for v in values), "; ".join(cells), CAPTURE
                         + (COLLINEAR if f["full_intensity"]["leds"] == [[2, 5, 9], [2, 6, 9]] else "")))
    return rows


def hdr_row(t: dict, f: dict, key: str) -> dict:
    """Section 8.3: the ND 2.0 chart captured as an HDR bracket, per merge (eq 8.9 and the mode's default)."""
    name = "full_intensity" if key == "8.1" else "pso"
    th = t[key]["nd_chart"]
    cells = [f"{'eq 8.9' if m == 'thesis' else m}: {_pm(v['train'], v['train_se'])} / {_pm(v['test'], v['test_se'])}"
             for m, v in f[name].items()]
    return _row(key, "transmissive", f"ND 2.0 chart, HDR captured, train / test ({name.replace('_', ' ')} lights)",
                _errors(th["train"], th["test"], 2), "; ".join(cells), HDR)


def build_rows(tables: dict, figures: dict) -> list[dict]:
    """Every comparison row, in thesis order."""
    tr, rf = figures["transmissive"], figures["reflective"]
    rows = (search_rows(tables["5.1"], tr, "5.1", "transmissive", FILM)
            + comparison_rows(tables["6.1"], tr, "6.1", "transmissive", FILM)
            + ga_rows(tables["6.2"], tr)
            + exposure_rows(tr["exposures"])
            + capture_rows(tables["7.2"], tr["captures"]))
    for key in ("8.1", "8.2"):
        rows += bracket_rows(tr["exposures"], key) + [hdr_row(tables, tr["hdr"], key)]
    rows += (search_rows(tables["9.1"], rf, "9.1", "reflective", DATA)
             + comparison_rows(tables["9.2"], rf, "9.2", "reflective", DATA))
    rows[-1]["reason"] += COPIED
    return rows


def inconsistencies(tables: dict) -> list[str]:
    """Where the thesis contradicts itself, which number is used and why (from the transcription)."""
    return [f"Table {k} ({v['section']}): {v['used']}." for k, v in tables.items() if "used" in v]


def markdown(rows: list[dict], result: dict, tables: dict) -> str:
    short = {"transmissive": "film", "reflective": "reflective"}
    lines = ["| Thesis table | Quantity | Thesis | dualrgb | Why they differ |", "| --- | --- | --- | --- | --- |"]
    lines += [f"| {r['table']} ({short[r['mode']]}) | {r['quantity']} | {r['thesis']} | {r['project']} | "
              f"{r['reason']} |" for r in rows]
    cfg = result["config"]
    lines += ["", f"Generated by `dualrgb study thesis` ({cfg['budget']} budget: PSO {cfg['pso']['particles']} "
              f"particles x {cfg['pso']['iterations']} iterations, GA mu {cfg['ga']['mu']} lambda {cfg['ga']['lam']} "
              f"x {cfg['ga']['generations']} generations, seed {cfg['seed']}; {result['elapsed_s']:.0f} s), noise-free "
              f"simulation on the thesis' grid {result['grid']} (thesis 4.5); film = transmissive mode (thesis "
              "chapters 5-8), reflective = chapter 9. Mean CIEDE2000; thesis values from "
              "`resources/thesis_tables.json`, this run's from `resources/thesis_reproduction.json`. Table 7.2 here: "
              + result["figures"]["transmissive"]["captures"]["captured_by"] + "."]
    lines += ["", "Where the thesis contradicts itself:", ""] + [f"- {s}" for s in inconsistencies(tables)]
    return "\n".join(lines)


def replace_between_markers(text: str, body: str, source: str) -> str:
    """``text`` with everything between README_START and README_END replaced by ``body``."""
    return replace_marked(text, body, "thesis", source)


def write_readme(path: str | Path, body: str) -> Path:
    return write_marked(path, body, "thesis")


def report_json(result: dict, rows: list[dict], tables: dict) -> dict[str, Any]:
    return {"format": FORMAT, **result, "rows": rows, "inconsistencies": inconsistencies(tables)}
