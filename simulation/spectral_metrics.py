"""How good an estimated spectrum is: spectral RMSE, the goodness-of-fit coefficient and its colour under other
lights, per sample (a patch or a pixel) and summarised.

* RMSE: sqrt(mean over wavelengths of (estimate - reference)^2), in reflectance (transmittance) factor units
  (0.01 = 1 %), optionally on a part of the grid (``mask``: e.g. where the camera sees anything);
* GFC (goodness-of-fit coefficient, Hernandez-Andres et al. 2001): |sum r r'| / sqrt(sum r^2 sum r'^2), 1 for
  a spectrum proportional to the reference; >= 0.99 is a "good" and >= 0.999 a "very good" (colorimetrically
  accurate) fit by their scale;
* both only where the reference was measured (:func:`spectral_figures` ``measured``): a reference file that ends
  before the grid does (BabelColor's CC24 at 730 nm on a 780 nm grid) is held at its last value there, which is
  no measurement to judge an estimate against (issue 29: 58 % of the reflective estimate's squared error lay at
  740-780 nm); the camera-seen figure is over the measured wavelengths the camera sees;
* CIEDE2000 under other lights (:data:`OTHER_LIGHTS`: CIE D65, A, D50, FL11 and a measured warm-white museum
  LED, colour-science's 'Luxeon WW 2880'): estimate and reference rendered under each light (CIE 1931 2 degree,
  eq 4.2's sum over the grid), each Lab relative to the perfect white under that same light. A spectral
  estimate that matches the reference only under D65 (a metamer) shows here.

References
----------
Hernandez-Andres, Romero & Lee (2001), Colorimetric and spectroradiometric characteristics of narrow-field-of-
view clear skylight in Granada, Spain, JOSA A 18(2) (the GFC); Imai, Rosen & Berns (2002), Comparative study of
metrics for spectral match quality, CGIV 2002 (RMSE, GFC and CIEDE2000 under several illuminants side by side);
CIE 15:2018 (illuminants A, D50, D65, FL11).
"""
from __future__ import annotations

import logging
from functools import lru_cache

import numpy as np

from dualrgb.simulation.colorimetry import delta_e_2000, tristimulus, white_point, xyz_to_lab
from dualrgb.simulation.grid import SpectralGrid
from dualrgb.simulation.objective import ErrorStats
from dualrgb.simulation.other_lights import OTHER_LIGHTS

log = logging.getLogger(__name__)

__all__ = ["GFC_GOOD", "GFC_VERY_GOOD", "OTHER_LIGHTS", "delta_e_under", "gfc", "gfc_summary", "light_spd",
           "seen_wavelengths", "spectral_figures", "spectral_rmse"]
GFC_GOOD, GFC_VERY_GOOD = 0.99, 0.999


def spectral_rmse(estimate: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """RMSE over the wavelengths (last axis; only where ``mask`` is True): (...,)."""
    d = np.asarray(estimate, dtype=float) - np.asarray(reference, dtype=float)
    if mask is not None:
        d = d[..., np.asarray(mask, dtype=bool)]
    return np.sqrt(np.mean(d * d, axis=-1))


def gfc(estimate: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Goodness-of-fit coefficient over the last axis (0 where either spectrum is all zero)."""
    e = np.asarray(estimate, dtype=float)
    r = np.asarray(reference, dtype=float)
    norm = np.sqrt(np.sum(e * e, axis=-1) * np.sum(r * r, axis=-1))
    dot = np.abs(np.sum(e * r, axis=-1))
    return np.divide(dot, norm, out=np.zeros_like(dot), where=norm > 0)


@lru_cache(maxsize=32)
def light_spd(name: str, grid: SpectralGrid) -> np.ndarray:
    """The relative SPD of one of :data:`OTHER_LIGHTS` sampled on ``grid`` (colour-science data, aligned with
    its default interpolation)."""
    import colour

    if name not in OTHER_LIGHTS:
        raise ValueError(f"light {name!r}: expected one of {', '.join(OTHER_LIGHTS)}")
    kind, key = OTHER_LIGHTS[name]
    sd = (colour.SDS_ILLUMINANTS if kind == "illuminant" else colour.SDS_LIGHT_SOURCES)[key]
    shape = colour.SpectralShape(grid.start, float(grid.wavelengths[-1]), grid.step)
    with colour.utilities.suppress_warnings(colour_runtime_warnings=True):     # extrapolation notices
        return np.asarray(sd.copy().align(shape).values, dtype=float)


def delta_e_under(estimate: np.ndarray, reference: np.ndarray, light: str, grid: SpectralGrid,
                  cmfs: np.ndarray) -> np.ndarray:
    """CIEDE2000 (...,) between estimate and reference spectra (..., n_wl) both seen under ``light``, Lab relative
    to the perfect white under it (Y = 100)."""
    spd = light_spd(light, grid)
    white = white_point(spd, cmfs)
    lab = [xyz_to_lab(tristimulus(np.asarray(s, dtype=float), spd, cmfs), white) for s in (estimate, reference)]
    return delta_e_2000(lab[1], lab[0])


def gfc_summary(values: np.ndarray) -> dict:
    g = np.asarray(values, dtype=float)
    return {"mean": float(g.mean()), "median": float(np.median(g)), "min": float(g.min()),
            "good": float(np.mean(g >= GFC_GOOD)), "very_good": float(np.mean(g >= GFC_VERY_GOOD))}


def spectral_figures(estimate: np.ndarray, reference: np.ndarray, grid: SpectralGrid, cmfs: np.ndarray,
                     mask: np.ndarray | None = None, measured: np.ndarray | None = None) -> dict:
    """Per-sample RMSE, GFC and CIEDE2000 under every light of :data:`OTHER_LIGHTS`, summarised:
    ``{"rmse": stats, "gfc": {mean, median, min, good, very_good}, "de00": {light: stats}, "wavelengths":
    {"measured": [first, last]}}`` (stats: mean / median / p90 / max); RMSE and GFC only where ``measured``
    (the grid's wavelengths the reference measured; None: all); with ``mask`` (where the camera sees) also
    ``"rmse_seen"``, the RMSE on the measured wavelengths the camera sees. The CIEDE2000 figures integrate over
    the whole grid (colorimetry holds a reference's end values beyond its range, CIE 15's practice)."""
    wl = grid.wavelengths
    keep = np.ones(len(wl), dtype=bool) if measured is None else np.asarray(measured, dtype=bool)
    if not keep.any():
        raise ValueError("spectral figures: the reference was measured at none of the grid's wavelengths")
    e, r = np.asarray(estimate, dtype=float), np.asarray(reference, dtype=float)
    out = {"rmse": ErrorStats.of(spectral_rmse(e, r, keep)).to_dict(),
           "gfc": gfc_summary(gfc(e[..., keep], r[..., keep])),
           "de00": {light: ErrorStats.of(delta_e_under(e, r, light, grid, cmfs)).to_dict() for light in OTHER_LIGHTS},
           "wavelengths": {"measured": [float(wl[keep][0]), float(wl[keep][-1])]}}
    seen = None if mask is None else keep & np.asarray(mask, dtype=bool)
    if seen is not None and seen.any():
        out["rmse_seen"] = ErrorStats.of(spectral_rmse(e, r, seen)).to_dict()
        out["wavelengths"]["seen"] = [float(wl[seen][0]), float(wl[seen][-1])]
    return out


def seen_wavelengths(sensitivities: np.ndarray, fraction: float = 0.01) -> np.ndarray:
    """Where the system sees anything: any channel's sensitivity (n_wl, C) above ``fraction`` of its peak."""
    S = np.abs(np.asarray(sensitivities, dtype=float))
    peak = S.max(axis=0)
    return (S > fraction * np.where(peak > 0, peak, np.inf)).any(axis=1)
