"""Colour targets of a capture: what each patch should measure (reference XYZ, eq 4.2) and where it lies.

The reference XYZ of a target captured under the virtual lab's ND 2.0 filter (thesis 8.3) is the target's XYZ
with the patches under the filter scaled by its transmittance: that is what the camera saw. Grids are in the
processed stack's (superpixel, half-size) pixel coordinates.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dualrgb.app.processing.patches import PatchGrid
from dualrgb.app.processing.report import layout_for
from dualrgb.app.workflow.vocabulary import Subject, SubjectKind
from dualrgb.simulation.colorimetry import white_point

if TYPE_CHECKING:
    from dualrgb.drivers.virtual.lab import VirtualLab

log = logging.getLogger(__name__)


@dataclass
class TargetSpec:
    """A colour target captured in the session: where its patches are and what they should be.

    ``grid`` is in the stack's (superpixel, half-size) pixel coordinates; use ``PatchGrid.scaled(0.5)`` for a
    grid placed on the full mosaic. None tries ``detect_cc24`` on the first light's RGB (24-patch targets).
    ``simulated`` (n, C) are the simulated camera values for the thesis Fig 7.4 check (optional).
    """

    subject: Subject
    xyz: np.ndarray                    # (n, 3) reference XYZ (eq 4.2 scale, Y of a perfect white = 100)
    names: list[str]
    grid: PatchGrid | None = None
    layout: tuple[int, int] | None = None
    simulated: np.ndarray | None = None
    label: str = ""
    nd_mask: np.ndarray | None = None     # patches under the ND filter (virtual lab)
    spectra: np.ndarray | None = None     # (n, n_wl) reference spectra on the simulation grid (ND included)
    mode: str = ""                        # the packaged data (grid, CMFs, LEDs, camera) the spectra belong to


def packaged_target(mode: str, name: str) -> Any:
    """The packaged training ('train') or test ('test') target of a mode (simulation.datasets)."""
    from dualrgb.simulation.datasets import default_setup

    if name not in ("train", "test"):
        raise ValueError(f"target {name!r}: only the training and test targets have reference data")
    return getattr(default_setup(mode), name)


def nd_transmittance(nd_mask: np.ndarray | None, transmittance: float, n: int) -> np.ndarray:
    """Per patch: the ND filter's transmittance where it covers the patch, 1 elsewhere."""
    if nd_mask is None:
        return np.ones(n)
    return np.where(np.asarray(nd_mask, bool), float(transmittance), 1.0)


def reference_xyz(mode: str, name: str, nd_scale: np.ndarray | None = None,
                  method: str | None = None) -> tuple[np.ndarray, list[str]]:
    """Reference XYZ (D65, CIE 1931 2 deg, Y of a perfect white = 100) of a packaged target and its patch names;
    ``nd_scale`` (per patch) multiplies the spectra (the ND filter's transmittance where it covers a patch).
    ``method``: simulation.datasets.target_xyz's integration ('eq-4.2', the default, or 'astm-e308')."""
    from dualrgb.simulation.datasets import default_setup, target_xyz

    setup = default_setup(mode)
    target = getattr(setup, name)
    xyz, _white = target_xyz(setup, target, method)
    if nd_scale is not None:                         # XYZ is linear in the spectrum
        xyz = xyz * np.asarray(nd_scale, dtype=float)[:, None]
    return xyz, list(target.patch_names)


def reference_spectra(mode: str, name: str, nd_scale: np.ndarray | None = None) -> np.ndarray:
    """The reflectance (transmittance) factors (n, n_wl) of a packaged target on the simulation grid; ``nd_scale``
    (per patch) multiplies them (the ND filter's transmittance where it covers a patch)."""
    spectra = np.asarray(packaged_target(mode, name).spectra, dtype=float)
    return spectra if nd_scale is None else spectra * np.asarray(nd_scale, dtype=float)[:, None]


def reference_white(mode: str = "reflective", method: str | None = None) -> np.ndarray:
    """The Lab reference white on the targets' scale: D65, Y = 100 (integrated like ``method``)."""
    from dualrgb.simulation.datasets import default_setup, target_xyz

    setup = default_setup(mode)
    if method is None:
        return white_point(setup.illuminant, setup.cmfs)
    return np.asarray(target_xyz(setup, setup.test, method)[1], dtype=float)


def scene_grid(scene: Any, fraction: float = 0.5) -> PatchGrid:
    """The patch grid of a virtual-lab scene in stack (superpixel) coordinates."""
    corners_rc = np.asarray(scene.corners(), dtype=float)
    rows, cols = scene.layout
    return PatchGrid(corners_rc[:, ::-1], rows, cols, fraction=fraction).scaled(0.5)   # (row, col) -> (x, y)


def virtual_target_spec(lab: VirtualLab, subject: Subject, *, simulated: np.ndarray | None = None,
                        grid: PatchGrid | None = None, label: str = "", method: str | None = None) -> TargetSpec:
    """A TargetSpec for a target captured in the virtual lab: its scene gives the grid and the ND patches."""
    if subject.kind is not SubjectKind.TARGET:
        raise ValueError(f"{subject.label}: not a colour target")
    scene = lab.scene_for(subject.name, nd=subject.nd)
    nd_mask = scene.nd_patches()
    nd_scale = nd_transmittance(nd_mask, scene.nd_transmittance, scene.n_patches)
    xyz, names = reference_xyz(lab.mode, subject.name, nd_scale, method)
    target = packaged_target(lab.mode, subject.name)
    return TargetSpec(subject, xyz, names, grid or scene_grid(scene), scene.layout, simulated,
                      label or f"{subject.name} ({target.name})", nd_mask,
                      reference_spectra(lab.mode, subject.name, nd_scale), lab.mode)


def target_spec(mode: str, subject: Subject, grid: PatchGrid | None, *, lab: VirtualLab | None = None,
                label: str = "", method: str | None = None) -> TargetSpec:
    """The TargetSpec the GUI and the CLI use: the virtual lab's scene when there is one (ND included), else the
    packaged target of ``mode`` with the grid placed by hand (None: CC24 auto-detection). ``method``: how the
    reference XYZ is integrated (simulation.datasets.target_xyz: 'eq-4.2' or 'astm-e308')."""
    if lab is not None:
        return virtual_target_spec(lab, subject, grid=grid, label=label, method=method)
    if subject.nd:
        raise ValueError(f"{subject.label}: the ND filter's coverage is known only in the virtual lab")
    target = packaged_target(mode, subject.name)
    xyz, names = reference_xyz(mode, subject.name, method=method)
    if grid is None and len(names) != 24:
        raise ValueError(f"{subject.label}: place the patch grid on it first ({len(names)} patches)")
    if grid is not None and grid.n_patches < len(names):
        raise ValueError(f"{subject.label}: the grid has {grid.n_patches} cells but the target {len(names)} "
                         "patches; set rows and columns")
    return TargetSpec(subject, xyz, names, grid, layout_for(len(names), target.layout), None,
                      label or f"{subject.name} ({target.name})", spectra=reference_spectra(mode, subject.name),
                      mode=mode)


def load_grid(path: Path) -> PatchGrid:
    """A patch grid from JSON: {"corners": [[x, y] x4 (TL, TR, BR, BL, stack pixels)], "rows", "cols"[, "fraction"]}."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
        return PatchGrid(np.asarray(data["corners"], float), int(data["rows"]), int(data["cols"]),
                         float(data.get("fraction", 0.5)))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: not a patch grid ({exc}); expected {{\"corners\": [[x, y], ...4], \"rows\": R, "
                         "\"cols\": C}") from None
