"""Wavelength grids and resampling of tabulated spectra onto them."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SpectralGrid:
    """A uniform wavelength grid in nm; the thesis uses 410-780 nm at 10 nm (section 4.5)."""

    start: float = 410.0
    end: float = 780.0
    step: float = 10.0

    def __post_init__(self) -> None:
        if self.step <= 0 or self.end < self.start:
            raise ValueError(f"invalid spectral grid {self.start}-{self.end} nm step {self.step} nm")

    @property
    def wavelengths(self) -> np.ndarray:
        """start, start + step, ... up to ``end`` (the last sample is the last one not beyond ``end``)."""
        n = int(np.floor((self.end - self.start) / self.step + 1e-9)) + 1
        return self.start + self.step * np.arange(n, dtype=float)

    def __len__(self) -> int:
        return len(self.wavelengths)

    def label(self) -> str:
        return f"{self.start:g}-{self.end:g} nm / {self.step:g} nm"


DEFAULT_GRID = SpectralGrid()


def resample(wavelengths: np.ndarray, values: np.ndarray, grid: SpectralGrid) -> np.ndarray:
    """Linear interpolation (as the thesis, section 4.5) with constant extrapolation at the ends.

    ``values`` has wavelengths along axis 0; returns an array of shape (len(grid), ...).
    """
    wl = np.asarray(wavelengths, dtype=float)
    v = np.asarray(values, dtype=float)
    target = grid.wavelengths
    flat = v.reshape(len(wl), -1)
    out = np.empty((len(target), flat.shape[1]))
    for i in range(flat.shape[1]):
        out[:, i] = np.interp(target, wl, flat[:, i])
    return out.reshape((len(target),) + v.shape[1:])
