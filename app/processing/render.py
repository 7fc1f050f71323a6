"""Rendering an estimated spectral image under a light the user chooses: the colour an original would have under
CIE D65, D50, A, FL11 or a warm-white museum LED, as a 16-bit ProPhoto RGB image with its ICC profile.

Per pixel, the estimated spectrum r (app.processing.spectral_cube: the calibration's estimator, clipped to the
physical range) is seen under the light L by eq 4.2, XYZ = k sum_lambda r L xbar (CIE 1931 2 degree, the
cube's 10 nm grid, k so that a perfect white has Y = 100 under L); then the XYZ, relative to the perfect white
under L, is adapted to the RGB space's white with Bradford (a viewer adapted to the light: the perfect white
renders as RGB (1, 1, 1), and what changes from light to light is each material's colour relative to it, which is
what a spectrum gives that three channels cannot), clipped to [0, 1] and display-encoded through the space's own
encoding (app.processing.encode's colour-science tables).

The space is ProPhoto RGB (ROMM, D50 white; the same ICC profile as the ProPhoto deliverable): 16-bit and wide
enough for the saturated colours a warm light gives, where sRGB would clip them; the sRGB deliverable stays the
D65 view for screens. The lights are simulation.other_lights.OTHER_LIGHTS (colour-science data), named on the
command line by their first word (simulation.other_lights.light_key: D65, A, D50, FL11, LED).

References
----------
CIE 15:2018 (illuminants A, D50, D65, FL11; eq 4.2 of the thesis is its tristimulus sum); ANSI/I3A IT10.7666
(ROMM RGB); Lam (1985) / Luo & Hunt (1998), the Bradford chromatic adaptation transform.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from dualrgb.simulation.other_lights import REFERENCE_LIGHT, light_key

log = logging.getLogger(__name__)

RENDER_SPACE = "ProPhoto RGB"
DEFAULT_RENDER_ILLUMINANT = light_key(REFERENCE_LIGHT)


def check_illuminant(key: str) -> str:
    """``key`` (a command-line name in any case, or the light's full name) -> the command-line name
    (simulation.other_lights); anything else is a one-line ValueError naming the choices."""
    from dualrgb.simulation.other_lights import light_of_key

    return light_key(light_of_key(key))


@dataclass(frozen=True)
class Rendering:
    """How spectra (n, n_wl) on ``wavelengths`` become display RGB under one light.

    ``weights`` (n_wl, 3): XYZ = spectra @ weights (a perfect white has Y = 100); ``white_xyz``: the perfect
    white's XYZ under the light; ``rgb_matrix`` (3, 3): linear RGB = rgb_matrix @ XYZ (adapted, divided by the
    white's Y: the white gives (1, 1, 1))."""

    illuminant: str
    light: str
    space: str
    wavelengths: tuple[float, ...]
    weights: np.ndarray
    white_xyz: np.ndarray
    rgb_matrix: np.ndarray

    def xyz(self, spectra: np.ndarray) -> np.ndarray:
        """XYZ (..., 3) of spectra (..., n_wl) under the light (eq 4.2, perfect white Y = 100)."""
        return np.asarray(spectra, dtype=float) @ self.weights

    def linear_rgb(self, spectra: np.ndarray) -> np.ndarray:
        """Adapted linear RGB (..., 3), not clipped (the perfect white is (1, 1, 1))."""
        return self.xyz(spectra) @ self.rgb_matrix.T

    def rgb16(self, spectra: np.ndarray) -> np.ndarray:
        """Display-encoded 16-bit RGB (..., 3) of spectra (NaN spectra give 0): the numpy formulation of what the
        cube's kernel writes (for previews; the deliverable is streamed by app.processing.spectral_cube)."""
        from dualrgb.app.processing.encode import encoding_table

        lin = np.nan_to_num(self.linear_rgb(spectra), nan=0.0)
        lut = encoding_table(self.space)
        x = np.clip(lin, 0.0, 1.0) * (lut.size - 1)
        i0 = np.minimum(x.astype(np.int64), lut.size - 2)
        return (lut[i0] + (x - i0) * (lut[i0 + 1] - lut[i0]) + 0.5).astype(np.uint16)

    def describe(self) -> dict:
        """The sidecar's description of the rendering."""
        return {"illuminant": self.illuminant, "light": self.light, "space": self.space,
                "white_xyz": [round(float(v), 4) for v in self.white_xyz],
                "observer": "CIE 1931 2 degree", "adaptation": f"Bradford, the perfect white under {self.light} "
                                                               f"-> the {self.space} white",
                "encoding": "display-encoded, 16-bit, the perfect white = 65535"}


def rendering(illuminant: str, wavelengths: np.ndarray | tuple[float, ...],
              space: str = RENDER_SPACE) -> Rendering:
    """The :class:`Rendering` under ``illuminant`` (a command-line name: :func:`check_illuminant`) for spectra on
    ``wavelengths`` (a uniform grid, e.g. a spectral estimator's)."""
    return _rendering(check_illuminant(illuminant), tuple(float(w) for w in wavelengths), space)


@lru_cache(maxsize=16)
def _rendering(key: str, wavelengths: tuple[float, ...], space: str) -> Rendering:
    from dualrgb.app.processing.outputs import xyz_to_rgb_matrix
    from dualrgb.simulation.colorimetry import white_point
    from dualrgb.simulation.datasets import default_setup
    from dualrgb.simulation.grid import SpectralGrid
    from dualrgb.simulation.other_lights import light_keys
    from dualrgb.simulation.spectral_metrics import light_spd

    wl = np.asarray(wavelengths)
    steps = np.diff(wl)
    if len(wl) < 2 or not np.allclose(steps, steps[0]):
        raise ValueError(f"rendering: the spectra's wavelengths {wl[0]:g}-{wl[-1]:g} nm are not a uniform grid")
    grid = SpectralGrid(float(wl[0]), float(wl[-1]), float(steps[0]))
    cmfs = default_setup("reflective", grid).cmfs
    light = light_keys()[key]
    spd = light_spd(light, grid)
    weights = spd[:, None] * cmfs * (100.0 / float(spd @ cmfs[:, 1]))
    white = white_point(spd, cmfs)
    matrix = xyz_to_rgb_matrix(space, white) / float(white[1])
    for a in (weights, white, matrix):
        a.flags.writeable = False
    return Rendering(key, light, space, wavelengths, weights, white, matrix)
