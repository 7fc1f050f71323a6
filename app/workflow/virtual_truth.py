"""On the virtual lab, an original's deliverables against what lies on the stand: the delivered XYZ and the
delivered spectral cube compared per pixel with the virtual original's ground truth (drivers/virtual/
originals.py: measured spectra per class, each 2x2 Bayer cell one class).

``dualrgb capture --virtual-lab`` (and the GUI on the virtual lab) put the figures in the sidecar's
``virtual_truth`` section and on the QA line: per-pixel dE00 (app.processing.ground_truth) and per-pixel
spectral RMSE (app.processing.spectral_truth), each with its per-material figure (noise averaged out). On a real
stand there is no truth and nothing is added.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dualrgb.app.processing.spectral_truth import SpectralTruth
from dualrgb.simulation.defaults import default_grid
from dualrgb.simulation.grid import SpectralGrid

if TYPE_CHECKING:
    from dualrgb.drivers.virtual.lab import VirtualLab

log = logging.getLogger(__name__)

@dataclass
class OriginalTruth:
    """The ground truth of the virtual original on the stand: ``xyz`` (H, W, 3) per sensor pixel on the
    ``white``'s scale (Y = 100) and the spectra on the delivered (superpixel) grid."""

    name: str
    xyz: np.ndarray
    spectral: SpectralTruth
    white: np.ndarray

    def on_wavelengths(self, wavelengths: np.ndarray) -> OriginalTruth:
        """This truth with its spectra on ``wavelengths`` (a uniform grid: a delivered cube's bands)."""
        if np.array_equal(np.asarray(wavelengths, float), self.spectral.wavelengths):
            return self
        grid = grid_of(wavelengths)
        height, width = self.xyz.shape[:2]
        return replace(self, spectral=_spectral_truth(self.name, height, width, grid))


def grid_of(wavelengths: np.ndarray) -> SpectralGrid:
    """The uniform grid whose samples are ``wavelengths`` (a cube's bands), else a one-line ValueError."""
    w = np.asarray(wavelengths, dtype=float)
    grid = SpectralGrid(float(w[0]), float(w[-1]), float(w[1] - w[0])) if w.size > 1 else None
    if grid is None or not np.allclose(grid.wavelengths, w):
        raise ValueError(f"the delivered bands ({w.size} from {w[0]:g} nm) are not a uniform wavelength grid")
    return grid


def _spectral_truth(name: str, height: int, width: int, grid: SpectralGrid) -> SpectralTruth:
    from dualrgb.drivers.virtual.originals import original

    o = original(name, grid)
    return SpectralTruth(o.class_map(height, width), o.spectra, o.grid.wavelengths)


def original_truth(name: str, height: int, width: int, mode: str = "reflective") -> OriginalTruth:
    """The truth of virtual original ``name`` in a ``width`` x ``height`` frame; its spectra on the mode's grid
    (simulation.defaults: the grid the calibration's spectral estimate delivers by default; a cube on other bands
    is compared on those, :meth:`OriginalTruth.on_wavelengths`)."""
    from dualrgb.app.workflow.targets import reference_white
    from dualrgb.drivers.virtual.originals import ground_truth_xyz

    spectral = _spectral_truth(name, height, width, default_grid(mode))
    return OriginalTruth(name, ground_truth_xyz(name, height, width), spectral, reference_white(mode))


def placed_truth(lab: VirtualLab | None) -> OriginalTruth | None:
    """The truth of the virtual original the lab has on the stand now (None: a chart, or not a virtual lab)."""
    from dualrgb.drivers.virtual.originals import ORIGINAL_PREFIX, original_name

    placed = str(getattr(lab, "placed", "") or "")
    if lab is None or not placed.startswith(ORIGINAL_PREFIX) or "+" in placed:      # a chart, or under ND
        return None
    return original_truth(original_name(placed), lab.height, lab.width, getattr(lab, "mode", "reflective"))


def compare(truth: OriginalTruth, xyz: np.ndarray, spectra=None) -> dict:
    """The ``virtual_truth`` figures of a delivered ``xyz`` image (H, W, 3, the white's scale) and, when given, its
    ``spectra`` ((H, W, n_wl) or a function (r0, r1) -> those rows; app.processing.spectral_truth)."""
    from dualrgb.app.processing.ground_truth import compare_to_ground_truth
    from dualrgb.app.processing.spectral_truth import compare_spectra_to_ground_truth

    out: dict = {"original": truth.name, "xyz": compare_to_ground_truth(xyz, truth.xyz, truth.white).to_dict()}
    if spectra is not None:
        out["spectral"] = compare_spectra_to_ground_truth(spectra, truth.spectral).to_dict()
    return out


def assess(truth: OriginalTruth, files: dict[str, Path], white_y: float) -> dict:
    """The sidecar's ``virtual_truth`` section: the delivered XYZ TIFF (``files['xyz']``) and, when delivered, the
    ENVI cube (``files['spectral_header']``) against ``truth``; ``white_y``: the XYZ TIFF's white Y."""
    import tifffile

    from dualrgb.app.processing.encode import LINEAR_ONE
    from dualrgb.app.processing.envi import open_cube

    xyz = tifffile.imread(files["xyz"]).astype(np.float64) / LINEAR_ONE * white_y
    cube = open_cube(files["spectral_header"]) if "spectral_header" in files else None
    if cube is not None:
        truth = truth.on_wavelengths(cube.wavelengths)
    return compare(truth, xyz, cube.rows if cube is not None else None)


def qa_text(section: dict) -> str:
    """The QA line's part: ``virtual truth (painting): dE00 mean 0.54 / p90 0.90, spectral RMSE mean 0.046 /
    p90 0.071``."""
    xyz = section["xyz"]
    text = f"virtual truth ({section['original']}): dE00 mean {xyz['mean']:.2f} / p90 {xyz['p90']:.2f}"
    sp = section.get("spectral")
    if sp:
        text += f", spectral RMSE mean {sp['rmse_mean']:.3f} / p90 {sp['rmse_p90']:.3f}"
    return text
