"""Per-pixel colour error: a characterisation applied to single pixels of a chart, as a master is judged.

Every other figure of the calibration is a *patch mean*: the model applied to each patch's mean camera values.
A delivered image applies the model to each pixel, whose values carry the sensor's noise (photon, read, the flat
field's own) that the patch mean averages away and that the model amplifies (its noise gain,
simulation.colour_models). Here each pixel of a patch is mapped to XYZ and compared with the patch's reference
(float64 CIEDE2000); per patch the mean and the 90th percentile over its pixels; for the chart the mean over
patches of each (``mean``: the mean per-pixel dE00 of a typical patch; ``p90``: its 90th percentile).

The same figures are predicted in the simulation from the expected-captured model's prediction-error covariance
for one pixel (simulation.expected_error.ExpectedErrorModel.pixel_errors: a Monte Carlo of that Gaussian through
the exact CIEDE2000, so the p90 is not a quadratic approximation).
"""
from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab

log = logging.getLogger(__name__)

MAX_PIXELS_PER_PATCH = 4096       # a full-size frame's patch has ~10^4-10^5 superpixels: a regular subsample


@dataclass(frozen=True)
class PixelErrors:
    """Per patch: the mean and the 90th percentile of the dE00 of its pixels, and how many pixels."""

    patch_mean: np.ndarray
    patch_p90: np.ndarray
    pixels: np.ndarray

    @property
    def mean(self) -> float:
        return float(np.nanmean(self.patch_mean))

    @property
    def p90(self) -> float:
        return float(np.nanmean(self.patch_p90))

    def to_dict(self, per_patch: bool = False) -> dict:
        out: dict = {"mean": round(self.mean, 4), "p90": round(self.p90, 4),
                     "worst_patch_p90": round(float(np.nanmax(self.patch_p90)), 4),
                     "pixels_per_patch": int(np.median(self.pixels))}
        if per_patch:
            out["per_patch"] = {"mean": np.round(self.patch_mean, 4).tolist(),
                                "p90": np.round(self.patch_p90, 4).tolist()}
        return out


def subsample(pixels: np.ndarray, limit: int = MAX_PIXELS_PER_PATCH) -> np.ndarray:
    """At most ``limit`` rows of (m, C) pixels, a regular stride (deterministic)."""
    m = pixels.shape[0]
    return pixels if m <= limit else pixels[np.linspace(0, m - 1, limit).astype(int)]


def pixel_errors(predict: Callable[[np.ndarray], np.ndarray], pixels: Sequence[np.ndarray], xyz: np.ndarray,
                 white: np.ndarray) -> PixelErrors:
    """dE00 of every pixel: ``predict`` (m, C) -> (m, 3) XYZ applied to each patch's (m_k, C) pixels against the
    patch's reference ``xyz[k]``; pixels with a non-finite channel are left out (as the patch means do)."""
    xyz = np.asarray(xyz, dtype=float)
    n = len(pixels)
    if xyz.shape != (n, 3):
        raise ValueError(f"{n} patches of pixels but reference XYZ {xyz.shape}")
    sizes = [len(p) for p in pixels]
    stacked = np.concatenate([np.asarray(p, dtype=float).reshape(len(p), -1) for p in pixels]) if n else np.empty(0)
    owner = np.repeat(np.arange(n), sizes)
    ok = np.isfinite(stacked).all(axis=1)
    lab_ref = xyz_to_lab(xyz, white)
    errors = np.full(len(stacked), np.nan)
    if ok.any():
        errors[ok] = delta_e_2000(lab_ref[owner[ok]], xyz_to_lab(predict(stacked[ok]), white))
    means, p90s, counts = np.full(n, np.nan), np.full(n, np.nan), np.zeros(n, dtype=int)
    bounds = np.cumsum([0] + sizes)
    for k in range(n):
        e = errors[bounds[k]:bounds[k + 1]]
        e = e[np.isfinite(e)]
        counts[k] = e.size
        if e.size:
            means[k], p90s[k] = float(e.mean()), float(np.percentile(e, 90))
    return PixelErrors(means, p90s, counts)
