"""Figures of the quality metrics (app.processing.quality): CIELAB components per patch, the neutral patches'
tone response and white balance, and the illuminance non-uniformity maps (matplotlib, Agg canvas)."""
from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dualrgb.app.processing.figure_files import new_figure, save_tight

log = logging.getLogger(__name__)


def _finish_bars(ax, x, labels, title: str, rotation: int) -> None:
    ax.set_xticks(x, labels, rotation=rotation, fontsize=6)
    ax.set_title(title)
    ax.legend(fontsize=7)
    ax.grid(True, axis="y", alpha=0.3)


def lab_components_figure(path: Path, names: Sequence[str], comp: dict, title: str) -> Path:
    """dL*, dC*ab, dH*ab per patch as grouped bars."""
    n = len(names)
    fig = new_figure(max(6.0, 0.32 * n + 2), 3.6)
    ax = fig.add_subplot(111)
    x = np.arange(n)
    for j, (key, label) in enumerate((("dL", "ΔL*"), ("dC", "ΔC*ab"), ("dH", "ΔH*ab"))):
        ax.bar(x + (j - 1) * 0.27, comp[key], 0.26, label=label)
    ax.axhline(0, color="0.3", lw=0.6)
    ax.set_ylabel("captured − reference")
    _finish_bars(ax, x, names, f"{title}: CIELAB differences per patch", 90)
    return save_tight(fig, path)


def tone_figure(path: Path, tone: dict, limit: float | None, title: str) -> Path:
    """Neutral patches: captured vs reference L* (tone response) and each patch's dL* and white balance error."""
    fig = new_figure(9.0, 3.6)
    a1, a2 = fig.add_subplot(121), fig.add_subplot(122)
    ref, cap = np.asarray(tone["reference_L"]), np.asarray(tone["captured_L"])
    a1.plot([0, 100], [0, 100], color="0.7", lw=0.8)
    a1.plot(ref, cap, "o-", ms=4)
    a1.set_xlabel("reference L*")
    a1.set_ylabel("captured L*")
    a1.set_title("tone response (neutral patches)")
    a1.grid(True, alpha=0.3)
    x = np.arange(len(ref))
    a2.bar(x - 0.2, tone["dL"], 0.38, label="ΔL*")
    a2.bar(x + 0.2, tone["white_balance_de00_ab"], 0.38, label="white balance ΔE00(ab)")
    if limit is not None:
        for s in (1, -1):
            a2.axhline(s * limit, color="tab:red", ls="--", lw=0.8)
    _finish_bars(a2, x, tone.get("names", [str(i) for i in x]), f"{title}: per neutral patch", 60)
    return save_tight(fig, path)


def uniformity_figure(path: Path, uniformity: dict) -> Path:
    """Per light: percent deviation of the green channel's block means, raw light field and after flat-field."""
    lights = list(uniformity)
    cols = max(len(lights), 1)
    fig = new_figure(3.6 * cols, 5.6)
    for j, light in enumerate(lights):
        for i, key in enumerate(("light_field", "after_flat_field")):
            g = uniformity[light].get(key, {}).get("G")
            ax = fig.add_subplot(2, cols, i * cols + j + 1)
            if g is None:
                ax.set_axis_off()
                continue
            dev = np.asarray(g["deviation_pct"])
            lim = max(float(np.nanmax(np.abs(dev))), 0.1)
            im = ax.imshow(dev, cmap="coolwarm", vmin=-lim, vmax=lim)
            ax.set_xticks([])
            ax.set_yticks([])
            what = "light field" if key == "light_field" else "flat-fielded white"
            ax.set_title(f"{light}: {what}\nrange {g['range_pct']:.2f} %", fontsize=8)
            fig.colorbar(im, ax=ax, label="% from mean", fraction=0.046)
    return save_tight(fig, path)
