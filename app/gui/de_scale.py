"""The fixed ΔE00 colour scale of the Results panel (Qt-free): traffic-light bands at the grading thresholds.

A heat map scaled to its own maximum painted 0.96 and 4.28 the same yellow; here a colour means the same thing
in every report. The band edges are the colour limits of app.processing.quality.STANDARD_LIMITS (one place):

* green  below FADGI 4-star's mean limit (2): good enough for the strictest mean;
* yellow up to FADGI 4-star's 90th-percentile limit (4, ISO 19264-1 A's mean limit): a few such patches are fine;
* orange up to Metamorfoze Full's maximum (7);
* red    up to ISO 19264-1 A's maximum (10); dark red above: no standard accepts such a patch.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualrgb.app.processing.quality import STANDARD_LIMITS

SCALE_MAX = 12.0           # the heat map's fixed top (ΔE00); every value above shows the last band's colour


@dataclass(frozen=True)
class DeBand:
    low: float
    high: float                # float('inf') for the last band
    colour: str
    text_colour: str
    meaning: str

    @property
    def label(self) -> str:
        return f"< {self.high:g}" if self.low == 0 else (f"{self.low:g}–{self.high:g}" if np.isfinite(self.high)
                                                         else f"≥ {self.low:g}")


def de_bands() -> list[DeBand]:
    fadgi, iso, meta = (STANDARD_LIMITS[k] for k in ("FADGI 4-star", "ISO 19264-1:2021 A", "Metamorfoze 2.0 Full"))
    edges = [fadgi["colour_mean_de00"].value, fadgi["colour_p90_de00"].value, meta["colour_max_de00"].value,
             iso["colour_max_de00"].value]
    colours = [("#2e7d32", "white", f"below FADGI 4-star's mean limit ({edges[0]:g})"),
               ("#f9a825", "black",
                f"up to FADGI 4-star's 90th percentile / ISO 19264-1 A's mean limit ({edges[1]:g})"),
               ("#ef6c00", "black", f"up to Metamorfoze 2.0 Full's maximum ({edges[2]:g})"),
               ("#c62828", "white", f"up to ISO 19264-1 A's maximum ({edges[3]:g})"),
               ("#6d0f0f", "white", "above every standard's maximum")]
    lows = [0.0] + edges
    highs = edges + [float("inf")]
    return [DeBand(lo, hi, c, t, m) for lo, hi, (c, t, m) in zip(lows, highs, colours, strict=True)]


def de_band(value: float) -> DeBand:
    for band in de_bands():
        if value < band.high:
            return band
    return de_bands()[-1]


def lookup_table(steps: int = 240) -> np.ndarray:
    """(steps, 3) uint8 colours for values 0 .. SCALE_MAX (the bands as flat colours), for an image LUT."""
    values = (np.arange(steps) + 0.5) * SCALE_MAX / steps
    out = np.empty((steps, 3), dtype=np.uint8)
    for i, v in enumerate(values):
        c = de_band(float(v)).colour.lstrip("#")
        out[i] = [int(c[k:k + 2], 16) for k in (0, 2, 4)]
    return out
