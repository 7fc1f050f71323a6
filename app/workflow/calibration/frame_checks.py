"""Checks on single frames that a person should see at once: a dark frame (light off, lens cap on), clipping, and
the open gate's uniformity (Qt-free; the GUI's last-frame preview and flat-field map).

* :func:`check_frame` - the brightest CFA channel's level against the linear limit (thesis 4.1), the share of
  clipped and non-linear pixels, and whether the frame is dark;
* :func:`flat_uniformity` - the open-gate flats of one light as percent of their mean over a block grid
  (app.processing.quality.shading, the illuminance non-uniformity metric the report grades).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from dualrgb.app.processing.hdr import LINEAR_LIMIT_DN
from dualrgb.app.sequences.calibration import channel_levels
from dualrgb.core.vocabulary import Role, latest_takes, light_of, role_of
from dualrgb.drivers.raw import RawFrame, load_raw

if TYPE_CHECKING:
    from dualrgb.core.protocols import Session

log = logging.getLogger(__name__)

DARK_FRACTION = 0.02      # brightest channel below 2 % of the linear range: nothing lit (or the lens cap is on)


@dataclass
class FrameCheck:
    level_dn: float           # brightest CFA channel's 99.5th percentile above black, central 60 % of the frame
    range_dn: float           # linear limit above black
    clipped_pct: float        # pixels at the white level
    nonlinear_pct: float      # pixels above the linear limit
    dark: bool

    @property
    def level_pct(self) -> float:
        return 100.0 * self.level_dn / self.range_dn if self.range_dn > 0 else 0.0

    def warning(self, light_on: bool | None = None) -> str:
        """'' for a usable frame, else one line saying what is wrong and what to check."""
        if self.dark:
            why = ("the light was off: switch it on (Light source) or use a sequence, which switches it itself"
                   if light_on is False else "is the light on and the lens cap off?")
            return f"frame is dark: the brightest channel reaches {self.level_pct:.1f} % of the linear range ({why})"
        if self.clipped_pct > 0:
            return f"{self.clipped_pct:.2f} % of the pixels are clipped: shorten the exposure"
        if self.nonlinear_pct > 0:
            return f"{self.nonlinear_pct:.2f} % of the pixels are above the linear limit: shorten the exposure"
        return ""


def check_frame(frame: RawFrame, linear_limit: float = LINEAR_LIMIT_DN) -> FrameCheck:
    black = float(np.mean(frame.black_levels))
    level = float(channel_levels(frame).max())
    m = frame.mosaic
    clipped = float(np.count_nonzero(m >= frame.white_level)) / m.size
    nonlinear = float(np.count_nonzero(m > linear_limit)) / m.size
    span = max(linear_limit - black, 1.0)
    return FrameCheck(level, span, 100.0 * clipped, 100.0 * nonlinear, level < DARK_FRACTION * span)


@dataclass
class UniformityMap:
    """The open gate under one light: block means as percent of their mean (average of R, G and B)."""

    light: str
    exposure_s: float
    frames: int
    percent: np.ndarray        # (rows, cols), 100 = the mean
    range_pct: float           # (max - min) / mean of the worst channel (FADGI's illuminance non-uniformity)


def flat_uniformity(session: Session, light: str) -> UniformityMap:
    """Uniformity of ``light``'s open-gate flats in ``session`` (the exposure with the most frames; dark level
    subtracted as the black level, which is what matters for a percent-of-mean map)."""
    from dualrgb.app.processing.mosaic import cfa_channel_index
    from dualrgb.app.processing.quality import block_means, shading

    flats: dict[float, list] = {}
    for e in latest_takes(session.entries()):
        if role_of(e) is Role.FLAT and light_of(e) == light and e.exposure_s:
            flats.setdefault(float(e.exposure_s), []).append(e)
    if not flats:
        raise ValueError(f"no open-gate flats of {light} in the session: shoot them first")
    t, entries = max(flats.items(), key=lambda kv: (len(kv[1]), -kv[0]))
    frames = [load_raw(session.file_path(e)) for e in entries]
    first = frames[0]
    mosaic = np.mean([f.mosaic.astype(np.float64) for f in frames], axis=0) - float(np.mean(first.black_levels))
    cfa = cfa_channel_index(first.cfa_pattern)
    grids = block_means(mosaic, cfa)
    percent = np.mean([100.0 * g / np.nanmean(g) for g in grids.values()], axis=0)
    worst = max(ch["range_pct"] for ch in shading(mosaic, cfa).values())
    return UniformityMap(light, t, len(frames), percent, float(worst))
