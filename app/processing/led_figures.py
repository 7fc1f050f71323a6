"""Figures of a stand measurement (app.workflow.calibration.led_stand): each LED's level -> output curve near the
bottom,
and its peak shift against time on (thesis Fig 4.10), measured points with the fitted models."""
from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.app.processing.figure_files import new_figure, save_tight
from dualrgb.simulation.led_fit import DriftFit
from dualrgb.simulation.sphere import LowLevelResponse

log = logging.getLogger(__name__)


def _colours(n: int) -> list[Any]:
    from matplotlib import colormaps

    cmap = colormaps["turbo"]
    return [cmap(0.1 + 0.8 * i / max(n - 1, 1)) for i in range(n)]


def levels_figure(result: Any, path: Path, max_level: float = 0.1) -> Path:
    """Relative output against level up to ``max_level`` per LED (points), the fitted response (lines), the
    proportional line and the sphere's minimum stable level."""
    fig = new_figure(7.0, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    curves = {k: r.levels for k, r in sorted(result.leds.items()) if r.levels}
    x = np.linspace(0.0, max_level, 400)
    ax.plot(100 * x, 100 * x, color="0.6", lw=1, ls="--", label="proportional")
    for (led, c), colour in zip(curves.items(), _colours(len(curves)), strict=True):
        lv, out = np.asarray(c["level"]), np.asarray(c["relative_output"])
        sel = lv <= max_level
        ax.plot(100 * lv[sel], 100 * out[sel], "o", ms=3, color=colour, label=f"LED {led}")
        fit = c.get("fit")
        if fit:
            resp = LowLevelResponse(fit["dead_band"], fit["knee"], fit["exponent"])
            ax.plot(100 * x, 100 * np.asarray(resp.output(x)), color=colour, lw=1)
    if result.min_stable_level is not None:
        ax.axvline(100 * result.min_stable_level, color="k", lw=0.8, ls=":")
        ax.text(100 * result.min_stable_level, 0.95 * 100 * max_level, " minimum stable level", fontsize=8)
    ax.set_xlabel("PWM level (%)")
    ax.set_ylabel("output (% of full level)")
    ax.set_title("LED level linearity near the bottom (points measured, lines fitted)", fontsize=10)
    ax.legend(fontsize=7, ncol=2)
    return save_tight(fig, path)


def drift_figure(result: Any, path: Path) -> Path:
    """Peak shift (nm) against minutes on per LED (points) with the fitted drift model (lines)."""
    fig = new_figure(7.0, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    series = {k: r.warmup for k, r in sorted(result.leds.items()) if r.warmup}
    for (led, w), colour in zip(series.items(), _colours(len(series)), strict=True):
        t = np.asarray(w["t_s"])
        ax.plot(t / 60, w["peak_shift_nm"], "o", ms=2.5, color=colour, label=f"LED {led}")
        if w.get("fit"):
            fit = DriftFit(**{k: w["fit"][k] for k in ("max_shift_nm", "tau_s", "onset_s", "rms_nm")})
            tt = np.linspace(0, t.max(), 300)
            ax.plot(tt / 60, fit.shift(tt), color=colour, lw=1)
    ax.set_xlabel("minutes continuously on (full level)")
    ax.set_ylabel("peak shift (nm)")
    ax.set_title("LED warm-up: peak drift (points measured, lines fitted; cf. thesis Fig 4.10)", fontsize=10)
    ax.legend(fontsize=7, ncol=2)
    return save_tight(fig, path)
