"""A delivered spectral cube against a per-pixel spectral ground truth: spectral RMSE per pixel (the map), its
statistics, and per material (the noise averaged out).

Ground truth comes from the virtual lab's originals (drivers/virtual/originals.py): every 2x2 Bayer cell is one
class with one measured spectrum, so on the superpixel grid the processing delivers the truth is a class map and
a palette of spectra (:class:`SpectralTruth`), exact, and no 24 MP truth cube is ever built. The comparison
reads the delivered cube in row bands (app.processing.envi.CubeFile.rows, or an in-memory (H, W, n_wl) array).

As for XYZ (app.lab.ground_truth), two figures answer two questions: per pixel (mean, p90, max, the map)
what a user of the delivered cube sees, the estimate's error *plus* the sensor noise carried through the spectral
map; per material (the mean delivered spectrum of all pixels of a class against its truth, area-weighted) the
estimate's error with the noise averaged out, comparable with the calibration's test-target RMSE.

RMSE is simulation.spectral_metrics.spectral_rmse (reflectance or transmittance factor, 0.01 = 1 %), over every
wavelength of the cube.
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dualrgb.app.processing.mosaic import row_bands
from dualrgb.simulation.spectral_metrics import spectral_rmse

log = logging.getLogger(__name__)

RMSE_MAP_MAX = 0.10       # fixed colour scale of the RMSE map figure (10 %), so figures compare at a glance
Rows = Callable[[int, int], np.ndarray]


@dataclass
class SpectralTruth:
    """The true factor spectrum of every pixel of a delivered grid: ``labels`` (H, W) index ``spectra``
    (n_classes, n_wl) on ``wavelengths``."""

    labels: np.ndarray
    spectra: np.ndarray
    wavelengths: np.ndarray

    def __post_init__(self) -> None:
        self.spectra = np.asarray(self.spectra, dtype=np.float64)
        if self.spectra.ndim != 2 or self.spectra.shape[1] != len(self.wavelengths):
            raise ValueError(f"truth spectra {self.spectra.shape} on {len(self.wavelengths)} wavelengths")
        if np.asarray(self.labels).max(initial=0) >= len(self.spectra):
            raise ValueError(f"truth labels name class {int(np.max(self.labels))} of {len(self.spectra)}")

    @property
    def shape(self) -> tuple[int, int]:
        return self.labels.shape[0], self.labels.shape[1]

    def rows(self, r0: int, r1: int) -> np.ndarray:
        """True spectra (rows, W, n_wl) of rows r0 .. r1."""
        return self.spectra[self.labels[r0:r1]]


@dataclass
class SpectralTruthComparison:
    """Spectral RMSE of a delivered cube against its truth. ``rmse_map`` (H, W) float32 is NaN where the
    delivered spectrum is not finite (no usable estimate); the statistics are over the ``n_pixels`` others."""

    mean: float
    median: float
    p90: float
    p99: float
    max: float
    n_pixels: int
    n_invalid: int
    rmse_map: np.ndarray
    material_mean: float = float("nan")
    material_max: float = float("nan")
    n_materials: int = 0

    def to_dict(self) -> dict:
        return {"rmse_mean": round(self.mean, 5), "rmse_median": round(self.median, 5), "rmse_p90": round(self.p90, 5),
                "rmse_p99": round(self.p99, 5), "rmse_max": round(self.max, 5), "n_pixels": self.n_pixels,
                "n_invalid": self.n_invalid, "material_rmse_mean": round(self.material_mean, 5),
                "material_rmse_max": round(self.material_max, 5), "n_materials": self.n_materials}


def _rows_of(cube: np.ndarray | Rows) -> Rows:
    if callable(cube):
        return cube
    arr = np.asarray(cube)
    if arr.ndim != 3:
        raise ValueError(f"delivered spectra have shape {arr.shape}; expected (H, W, n_wl)")
    return lambda r0, r1: arr[r0:r1]


class _Materials:
    """The mean delivered spectrum of every class, summed band by band."""

    def __init__(self, n_classes: int, n_wl: int):
        self.sums = np.zeros((n_classes, n_wl))
        self.counts = np.zeros(n_classes)

    def add(self, est: np.ndarray, labels: np.ndarray) -> None:
        ok = np.isfinite(est).all(axis=-1)
        lab = labels[ok]
        k = len(self.counts)
        self.counts += np.bincount(lab, minlength=k)
        for b in range(self.sums.shape[1]):
            self.sums[:, b] += np.bincount(lab, weights=est[..., b][ok], minlength=k)

    def errors(self, spectra: np.ndarray) -> tuple[float, float, int]:
        """Area-weighted mean and max RMSE of the classes' mean spectra, and how many classes were seen."""
        seen = self.counts > 0
        if not seen.any():
            return float("nan"), float("nan"), 0
        rmse = spectral_rmse(self.sums[seen] / self.counts[seen, None], spectra[seen])
        return float(np.sum(rmse * self.counts[seen]) / self.counts[seen].sum()), float(rmse.max()), int(seen.sum())


def compare_spectra_to_ground_truth(cube: np.ndarray | Rows, truth: SpectralTruth, *,
                                    band_rows: int = 256) -> SpectralTruthComparison:
    """Per-pixel spectral RMSE of the delivered spectra against ``truth``, and per material.

    Parameters
    ----------
    cube : (H, W, n_wl) delivered factor spectra (NaN: no estimate), or a function (r0, r1) -> those rows
        (e.g. app.processing.envi.CubeFile.rows of the delivered ENVI cube).
    truth : the true spectra on the same grid (H, W) and wavelengths.

    Returns
    -------
    SpectralTruthComparison : mean / median / p90 / p99 / max over the valid pixels, the map, material figures.

    References
    ----------
    Imai, Rosen & Berns (2002), Comparative study of metrics for spectral match quality, CGIV (spectral RMSE).
    """
    rows_of = _rows_of(cube)
    H, W = truth.shape
    n_wl = len(truth.wavelengths)
    rmse = np.empty((H, W), np.float32)
    materials = _Materials(len(truth.spectra), n_wl)
    for band in row_bands(H, band_rows):
        est = np.asarray(rows_of(band.start, band.stop), dtype=np.float64)
        if est.shape != (band.stop - band.start, W, n_wl):
            raise ValueError(f"delivered spectra rows {band.start}..{band.stop} have shape {est.shape}; the truth "
                             f"is {W} x {H} x {n_wl}")
        rmse[band] = spectral_rmse(est, truth.rows(band.start, band.stop))
        materials.add(est, truth.labels[band])
    valid = np.isfinite(rmse)
    values = rmse[valid].astype(np.float64)
    if values.size == 0:
        raise ValueError("no valid pixel to compare: every delivered spectrum is NaN")
    p50, p90, p99 = np.percentile(values, [50, 90, 99])
    out = SpectralTruthComparison(float(values.mean()), float(p50), float(p90), float(p99), float(values.max()),
                                  int(values.size), int((~valid).sum()), rmse, *materials.errors(truth.spectra))
    log.info("spectral RMSE against ground truth: mean %.4f, p90 %.4f, max %.4f over %d pixels (%d invalid); "
             "materials %.4f (%d)", out.mean, out.p90, out.max, out.n_pixels, out.n_invalid, out.material_mean,
             out.n_materials)
    return out


def write_rmse_map_png(path, rmse_map: np.ndarray, *, title: str = "", vmax: float = RMSE_MAP_MAX):
    """A PNG of the spectral RMSE map on a fixed 0..``vmax`` scale (app.lab.ground_truth's figure)."""
    from dualrgb.app.lab.ground_truth import write_de_map_png

    return write_de_map_png(path, rmse_map, title=title or "spectral RMSE against ground truth", vmax=vmax,
                            label="spectral RMSE (factor)")
