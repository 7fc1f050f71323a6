"""The three-dye Beer-Lambert film model of the packaged film targets and the virtual lab's film originals.

T(lambda) = 10^-(base + c Dc(lambda) + m Dm(lambda) + y Dy(lambda)), with Gaussian unit dye densities (yellow absorbs
blue, magenta green, cyan red). ``tools/generate_resources.py`` builds the film targets with it; the virtual lab's
film original (drivers.virtual.originals) uses the same dyes, so its materials lie in the targets' gamut.
"""
from __future__ import annotations

import numpy as np

FILM_BASE_DENSITY = 0.05
# Dye density peaks and widths (nm): yellow absorbs blue, magenta green, cyan red.
DYES = {"cyan": (660.0, 45.0), "magenta": (545.0, 35.0), "yellow": (445.0, 30.0)}


def dye_densities(wavelengths: np.ndarray) -> np.ndarray:
    """Unit dye density spectra, shape (n_wavelengths, 3) for cyan, magenta, yellow."""
    return np.stack([np.exp(-0.5 * ((wavelengths - p) / w) ** 2) for p, w in DYES.values()], axis=1)


def film_transmittance(amounts: np.ndarray, wavelengths: np.ndarray) -> np.ndarray:
    """Beer-Lambert film: amounts (n, 3) of c, m, y -> transmittance (n_wavelengths, n)."""
    density = FILM_BASE_DENSITY + dye_densities(wavelengths) @ np.atleast_2d(amounts).T
    return np.asarray(10.0 ** (-density))
