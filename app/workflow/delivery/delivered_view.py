"""What the GUI shows of a delivered original, Qt-free: a screen-sized rendering of its spectral cube under a
chosen light, and the spectrum of any pixel, read from the delivered cube (app.processing.envi), or for a
full-resolution delivery (its cube made on demand) computed from its camera-RGB TIFFs through the map its sidecar
states (app.processing.cube_map.MappedCube).

    view = open_delivered(sidecar_path)               # reads the sidecar, memory-maps the cube, decimates it
    image = view.render("A")                          # (h, w, 3) uint8 sRGB for the screen, seen under A
    wl, spectrum = view.spectrum(row, col)            # one pixel of the full cube (preview coordinates)

The preview is the cube decimated to at most ``max_side`` pixels a side (every n-th row and column), so switching
the light re-renders a few hundred thousand spectra, not 6 M; a clicked pixel's spectrum comes from the cube
itself at full resolution. The screen image is sRGB (app.processing.render with the sRGB space, adapted from
the light's white like the delivered ProPhoto rendering). Loading and rendering belong off the GUI thread.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualrgb.app.processing.cube_map import MappedCube, estimator_of_map
from dualrgb.app.processing.envi import CubeFile, open_cube
from dualrgb.app.processing.render import rendering

log = logging.getLogger(__name__)

PREVIEW_MAX_SIDE = 800
SCREEN_SPACE = "sRGB"


@dataclass
class DeliveredView:
    """A delivered original's cube, memory-mapped, with its decimated spectra for the preview."""

    identifier: str
    cube: CubeFile | MappedCube
    step: int
    spectra: np.ndarray           # (h, w, n_wl) float32 factors of the preview (NaN: no estimate)
    quantity: str
    method: str

    @property
    def wavelengths(self) -> np.ndarray:
        return self.cube.wavelengths

    @property
    def preview_shape(self) -> tuple[int, int]:
        return self.spectra.shape[0], self.spectra.shape[1]

    def render(self, illuminant: str) -> np.ndarray:
        """(h, w, 3) uint8 sRGB of the preview seen under ``illuminant`` (a command-line light name)."""
        r = rendering(illuminant, self.wavelengths, SCREEN_SPACE)
        return (r.rgb16(self.spectra) >> 8).astype(np.uint8)

    def full_pixel(self, row: int, col: int) -> tuple[int, int]:
        """The cube's pixel under preview pixel (row, col)."""
        h, w = self.preview_shape
        if not (0 <= row < h and 0 <= col < w):
            raise ValueError(f"{self.identifier}: preview pixel ({row}, {col}) outside {w} x {h}")
        return row * self.step, col * self.step

    def spectrum(self, row: int, col: int) -> tuple[np.ndarray, np.ndarray]:
        """(wavelengths, factors) of the cube's pixel under preview pixel (row, col), from the delivered file."""
        return self.wavelengths, self.cube.pixel(*self.full_pixel(row, col))


def open_delivered(sidecar: Path, max_side: int = PREVIEW_MAX_SIDE) -> DeliveredView:
    """The delivered view of the original whose sidecar is ``sidecar``; a delivery without a spectral cube (an
    old calibration) is a one-line ValueError."""
    from dualrgb.app.workflow.delivery.delivery_folder import read_sidecar

    sidecar = Path(sidecar)
    doc = read_sidecar(sidecar)
    sp = doc.get("spectral")
    if not sp:
        raise ValueError(f"{sidecar.name}: this delivery has no spectral cube (its calibration had no spectral "
                         "estimator)")
    cube = cube_of(sidecar, sp)
    lines, samples, _ = cube.shape
    step = max(1, -(-max(lines, samples) // max_side))
    spectra = cube.rows(0, lines, step)
    return DeliveredView(str(doc["original"]["identifier"]), cube, step, spectra, sp["cube"]["quantity"],
                         sp["estimator"]["method"])


def cube_of(sidecar: Path, spectral: dict) -> CubeFile | MappedCube:
    """The delivered cube (ENVI) or, when the sidecar says it is made on demand, its map of the channel TIFFs."""
    if spectral["cube"].get("delivery") == "on-demand":
        section = spectral["map"]
        return MappedCube([sidecar.parent / name for name in section["channel_files"]], estimator_of_map(section))
    return open_cube(sidecar.parent / spectral["cube"]["header"])


def render_lights() -> dict[str, str]:
    """The lights a delivered original can be seen under: command-line name -> light name (D65 first)."""
    from dualrgb.simulation.other_lights import light_keys

    return light_keys()
