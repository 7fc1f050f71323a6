"""What a calibration profile says about its colour (``dualrgb calibration show``, ``dualrgb calibrate``): the
delivered model and why, the models' table, the per-pixel error beside the patch means, the noise gain and the
conditioning of the captured light set. Profiles made before issue 40 have only the patch means: those lines
say so instead of inventing figures."""
from __future__ import annotations

import logging
from typing import Any

log = logging.getLogger(__name__)


def _num(value: Any, spec: str = ".3f") -> str:
    if value is None:
        return "n/a"
    if isinstance(value, str):
        return value
    return format(float(value), spec)


def colour_lines(statistics: dict, method: str, channels: int) -> list[str]:
    """The matrix line, the per-pixel line and (when the profile has one) the models' table."""
    best = statistics.get("methods", {}).get(statistics.get("best", ""), {})
    sel = statistics.get("selection") or {}
    rows = statistics.get("models") or []
    terms = next((r["terms"] for r in rows if r.get("chosen")), channels)
    why = (f" by {sel.get('folds')}-fold cross-validation on the training chart, {sel.get('rule', 'lowest mean')} "
           "rule" if sel.get("folds") else "")
    lines = [f"matrix: {method} ({terms} terms of {channels} channels; chosen of "
             f"{', '.join(statistics.get('methods', {}))}{why}); train mean dE00 "
             f"{_num((best.get('train') or {}).get('mean'))}, test mean {_num((best.get('test') or {}).get('mean'))} "
             "(patch means)"]
    px = statistics.get("per_pixel_de00") or {}
    gain = (statistics.get("noise_gain") or {}).get("Y")
    if px:
        figures = "; ".join(f"{k} mean {_num(v.get('mean'))} / p90 {_num(v.get('p90'))}" for k, v in px.items())
        planned = statistics.get("condition_number_planned")
        captured = _num(statistics.get("condition_number"), ".0f")
        lines.append(f"per pixel (the model on each pixel of the charts): dE00 {figures}; noise gain (Y) "
                     f"{_num(gain, '.2f')}; condition number of the light set {captured} captured"
                     + (f", {_num(planned, '.0f')} planned from the camera model" if planned else ""))
    else:
        lines.append("per pixel: not measured (a calibration made before per-pixel figures; calibrate again)")
    if rows:
        lines.append("  model              terms  CV dE00 (SE)     train   test   per-pixel mean / p90  noise gain Y")
        for r in rows:
            cv = f"{_num(r.get('cv_mean_de00'))} ({_num(r.get('cv_se_de00'))})" if r.get("cv_mean_de00") is not None \
                else "not cross-validated"
            lines.append(f"  {r['model']:<18} {r['terms']:>5}  {cv:<15}  {_num(r.get('train_de00'))}  "
                         f"{_num(r.get('test_de00'))}  {_num(r.get('per_pixel_de00_mean')):>9} / "
                         f"{_num(r.get('per_pixel_de00_p90')):<6}  {_num(r.get('noise_gain_y'), '.2f'):>10}"
                         + ("  <- delivered" if r.get("chosen") else ""))
    return lines
