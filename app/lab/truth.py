"""The virtual lab's truth: an original's deliverables against what lay on the virtual stand, the delivered XYZ
and the delivered spectral cube compared per pixel with the virtual original's ground truth (drivers/virtual/
originals.py: measured spectra per class, each 2x2 Bayer cell one class).

A separate step, never part of a delivery: ``dualrgb lab score SESSION`` (app.lab.score) and the demo compute it:
per-pixel dE00 (app.lab.ground_truth) and per-pixel spectral RMSE (app.lab.spectral_truth), each with its
per-material figure (noise averaged out), at the delivery's resolution (full: per sensor pixel; half: per 2x2
cell), and each split into *edges* and *flat* regions: edges are the Bayer cells with another material among
their 8 neighbours, i.e. every pixel whose 5x5 demosaic support (app.processing.demosaic) reaches a boundary
between materials; the same object areas at both resolutions, so the figures compare.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from dualrgb.app.lab.spectral_truth import SpectralTruth
from dualrgb.simulation.defaults import default_grid
from dualrgb.simulation.grid import SpectralGrid
from dualrgb.simulation.spectral_estimation import SpectralEstimator

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


def edge_cells(cells: np.ndarray) -> np.ndarray:
    """(h, w) bool: the cells of the class map ``cells`` with another class among their 8 neighbours."""
    h, w = cells.shape
    pad = np.pad(cells, 1, mode="edge")
    edges = np.zeros((h, w), np.bool_)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            edges |= pad[dy: dy + h, dx: dx + w] != cells
    return edges


def on_grid(truth: OriginalTruth, shape: tuple[int, int]) -> tuple[str, SpectralTruth, np.ndarray]:
    """(resolution, the spectral truth, the edge mask) on a delivered grid of ``shape``: the cells' (half) or the
    sensor's (full: each cell's class on its four pixels)."""
    cells = truth.spectral.labels
    edges = edge_cells(cells)
    if tuple(shape) == cells.shape:
        return "half", truth.spectral, edges
    if tuple(shape) == (2 * cells.shape[0], 2 * cells.shape[1]):
        full = np.repeat(np.repeat(cells, 2, axis=0), 2, axis=1)
        spectral = SpectralTruth(full, truth.spectral.spectra, truth.spectral.wavelengths)
        return "full", spectral, np.repeat(np.repeat(edges, 2, axis=0), 2, axis=1)
    raise ValueError(f"delivered {shape[1]}x{shape[0]}: the truth is {2 * cells.shape[1]}x{2 * cells.shape[0]} "
                     "(full) or half that")


def regions(values: np.ndarray, edges: np.ndarray, prefix: str = "") -> dict:
    """Mean and p90 of a per-pixel map (NaN left out) over the edges and over the flat regions."""
    out = {}
    for name, mask in (("edges", edges), ("flat", ~edges)):
        v = values[mask & np.isfinite(values)].astype(np.float64)
        out[name] = ({f"{prefix}mean": round(float(v.mean()), 5), f"{prefix}p90": round(float(np.percentile(v, 90)), 5),
                      "n_pixels": int(v.size)} if v.size else {f"{prefix}mean": None, f"{prefix}p90": None,
                                                              "n_pixels": 0})
    return out


def compare(truth: OriginalTruth, xyz: np.ndarray, spectra=None) -> dict:
    """The truth figures of a delivered ``xyz`` image (H, W, 3, the white's scale; the sensor's size or
    half of it) and, when given, its ``spectra`` ((H, W, n_wl) or a function (r0, r1) -> those rows;
    app.lab.spectral_truth), each also over the edges and the flat regions (:func:`regions`)."""
    from dualrgb.app.lab.ground_truth import compare_to_ground_truth
    from dualrgb.app.lab.spectral_truth import compare_spectra_to_ground_truth

    resolution, spectral, edges = on_grid(truth, xyz.shape[:2])
    de = compare_to_ground_truth(xyz, truth.xyz, truth.white)
    out: dict = {"original": truth.name, "resolution": resolution, "xyz": {**de.to_dict(), **regions(de.de_map, edges)}}
    if spectra is not None:
        sp = compare_spectra_to_ground_truth(spectra, spectral)
        out["spectral"] = {**sp.to_dict(), **regions(sp.rmse_map, edges, "rmse_")}
    return out


def delivered_spectra(files: dict[str, Path], estimator: SpectralEstimator | None):
    """The delivered spectra as (wavelengths, a function (r0, r1) -> rows): the ENVI cube when it is a file,
    else the cube made on demand from the camera-RGB TIFFs through ``estimator`` (app.processing.cube_map);
    None when there are none."""
    from dualrgb.app.processing.cube_map import MappedCube
    from dualrgb.app.processing.envi import open_cube

    if "spectral_header" in files:
        cube = open_cube(files["spectral_header"])
        return cube.wavelengths, cube.rows
    if estimator is None:
        return None
    keys = sorted((k for k in files if k.startswith("channels_")), key=lambda k: int(k.split("_")[1]))
    mapped = MappedCube([files[k] for k in keys], estimator)
    return mapped.wavelengths, mapped.rows


def assess(truth: OriginalTruth, files: dict[str, Path], white_xyz: list[float],
           estimator: SpectralEstimator | None = None) -> dict:
    """The figures of one delivery: the delivered XYZ TIFF (``files['xyz']``) and the delivered spectra
    (:func:`delivered_spectra`) against ``truth``; ``white_xyz``: the XYZ TIFF's white."""
    import tifffile

    from dualrgb.app.processing.encode import xyz_from_codes

    xyz = xyz_from_codes(tifffile.imread(files["xyz"]), white_xyz)
    spectra = delivered_spectra(files, estimator)
    if spectra is not None:
        truth = truth.on_wavelengths(spectra[0])
    return compare(truth, xyz, spectra[1] if spectra is not None else None)


def qa_text(section: dict) -> str:
    """The QA line's part: ``virtual truth (painting, full): dE00 mean 0.54 / p90 0.90, spectral RMSE mean 0.046 /
    p90 0.071``."""
    xyz = section["xyz"]
    where = f"{section['original']}, {section['resolution']}" if section.get("resolution") else section["original"]
    text = f"virtual truth ({where}): dE00 mean {xyz['mean']:.2f} / p90 {xyz['p90']:.2f}"
    sp = section.get("spectral")
    if sp:
        text += f", spectral RMSE mean {sp['rmse_mean']:.3f} / p90 {sp['rmse_p90']:.3f}"
    return text
