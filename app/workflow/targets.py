"""Colour targets of a capture: what each patch should measure (reference XYZ, eq 4.2) and where it lies.

The reference data are a chart's (simulation.charts): the stand's own chart files when the calibration names
them (``calibrate --train-target / --test-target``, the GUI's calibration box), else the packaged targets of the
mode. The reference XYZ of a target captured under the stand's ND filter (thesis 8.3: ND 2.0 over half the chart) is
the target's XYZ with the patches under the filter scaled by its transmittance: that is what the camera saw. Which
patches the filter covers and its transmittance are a setting of the stand (:class:`NdFilter`). Grids are in the
processed stack's (superpixel, half-size) pixel coordinates.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.app.processing.patches import PatchGrid
from dualrgb.app.workflow.vocabulary import Subject, SubjectKind
from dualrgb.simulation.chart_geometry import ChartGeometry, geometry_of
from dualrgb.simulation.charts import Chart, ChartError, packaged_chart
from dualrgb.simulation.colorimetry import white_point

log = logging.getLogger(__name__)
MAX_GRID_BYTES = 1 << 20          # a patch grid is a few hundred bytes; checked before reading


@dataclass
class TargetSpec:
    """A colour target captured in the session: where its patches are and what they should be.

    ``grid`` is in the stack's (superpixel, half-size) pixel coordinates; use ``PatchGrid.scaled(0.5)`` for a
    grid placed on the full mosaic. None: the patches are found in the captured stack (app.processing.chart_detect,
    from ``geometry``: where the chart's patches lie on it).
    ``simulated`` (n, C) are the simulated camera values for the thesis Fig 7.4 check (optional).
    """

    subject: Subject
    xyz: np.ndarray                    # (n, 3) reference XYZ (eq 4.2 scale, Y of a perfect white = 100)
    names: list[str]
    grid: PatchGrid | None = None
    layout: tuple[int, int] | None = None
    simulated: np.ndarray | None = None
    label: str = ""
    nd_mask: np.ndarray | None = None     # patches under the ND filter (an ND capture)
    spectra: np.ndarray | None = None     # (n, n_wl) reference spectra on the simulation grid (ND included)
    mode: str = ""                        # the packaged data (grid, CMFs, LEDs, camera) the spectra belong to
    cells: list[int] | None = None        # the grid cell of each patch (None: the patches fill the cells in order)
    chart: Chart | None = None            # the chart the reference data come from (the profile records it)
    geometry: ChartGeometry | None = None  # where its patches lie (simulation.chart_geometry), for detection

    def cell_indices(self) -> list[int]:
        return list(range(len(self.names))) if self.cells is None else list(self.cells)

    @property
    def measured_range(self) -> tuple[float, float] | None:
        """The wavelengths the chart's reference file measured (spectral figures count only there; None: unknown)."""
        return self.chart.target.measured_range if self.chart is not None else None


def packaged_target(mode: str, name: str) -> Any:
    """The packaged training ('train') or test ('test') target of a mode (simulation.datasets)."""
    from dualrgb.simulation.datasets import default_setup

    if name not in ("train", "test"):
        raise ValueError(f"target {name!r}: only the training and test targets have reference data")
    return getattr(default_setup(mode), name)


def chart_of(mode: str, name: str, charts: dict[str, Chart] | None = None) -> Chart:
    """The chart whose reference data a target uses: the stand's own (``charts``), else the packaged one."""
    from dualrgb.simulation.datasets import default_setup

    if name not in ("train", "test"):
        raise ValueError(f"target {name!r}: only the training and test targets have reference data")
    chart = (charts or {}).get(name)
    if chart is not None:
        if chart.kind != mode:
            raise ChartError(f"{chart.file.path}: a {chart.kind} chart for a {mode} calibration")
        return chart
    return packaged_chart(mode, name, default_setup(mode).grid)


ND_2_TRANSMITTANCE = 0.01                 # optical density 2.0 (thesis 8.3)


@dataclass(frozen=True)
class NdFilter:
    """The stand's ND filter as it lies over a target in an ND capture (thesis 8.3): its ``transmittance`` and the
    patches it covers, the ``columns`` leftmost columns of the chart's layout over its whole height (None: half of
    them, ``cols // 2``: the stand's filter holder lays it over the left half)."""

    transmittance: float = ND_2_TRANSMITTANCE
    columns: int | None = None

    def __post_init__(self) -> None:
        if not 0.0 < self.transmittance <= 1.0:
            raise ValueError(f"ND filter transmittance {self.transmittance}: expected 0 < T <= 1")
        if self.columns is not None and self.columns < 0:
            raise ValueError(f"ND filter columns {self.columns}: expected 0 or more")

    def mask(self, layout: tuple[int, int], cells: list[int]) -> np.ndarray:
        """Per used patch (its grid cell in ``cells``): whether the filter covers it."""
        cols = int(layout[1])
        covered = cols // 2 if self.columns is None else min(int(self.columns), cols)
        return np.array([(int(c) % cols) < covered for c in cells], dtype=bool)


def nd_transmittance(nd_mask: np.ndarray | None, transmittance: float, n: int) -> np.ndarray:
    """Per patch: the ND filter's transmittance where it covers the patch, 1 elsewhere."""
    if nd_mask is None:
        return np.ones(n)
    return np.where(np.asarray(nd_mask, bool), float(transmittance), 1.0)


def reference_xyz(mode: str, name: str, nd_scale: np.ndarray | None = None,
                  method: str | None = None, chart: Chart | None = None) -> tuple[np.ndarray, list[str]]:
    """Reference XYZ (D65, CIE 1931 2 deg, Y of a perfect white = 100) of a target's used patches and their names
    (``chart``: the stand's own, else the packaged one); ``nd_scale`` (per patch) multiplies the spectra (the ND
    filter's transmittance where it covers a patch). ``method``: simulation.datasets.target_xyz's integration
    ('eq-4.2', the default, or 'astm-e308')."""
    from dualrgb.simulation.datasets import default_setup, target_xyz

    target = (chart or chart_of(mode, name)).reference()
    xyz, _white = target_xyz(default_setup(mode), target, method)
    if nd_scale is not None:                         # XYZ is linear in the spectrum
        xyz = xyz * np.asarray(nd_scale, dtype=float)[:, None]
    return xyz, list(target.patch_names)


def reference_spectra(mode: str, name: str, nd_scale: np.ndarray | None = None,
                      chart: Chart | None = None) -> np.ndarray:
    """The reflectance (transmittance) factors (n, n_wl) of a target's used patches on the simulation grid;
    ``nd_scale`` (per patch) multiplies them (the ND filter's transmittance where it covers a patch)."""
    spectra = np.asarray((chart or chart_of(mode, name)).reference().spectra, dtype=float)
    return spectra if nd_scale is None else spectra * np.asarray(nd_scale, dtype=float)[:, None]


def reference_white(mode: str = "reflective", method: str | None = None) -> np.ndarray:
    """The Lab reference white on the targets' scale: D65, Y = 100 (integrated like ``method``)."""
    from dualrgb.simulation.datasets import default_setup, target_xyz

    setup = default_setup(mode)
    if method is None:
        return white_point(setup.illuminant, setup.cmfs)
    return np.asarray(target_xyz(setup, setup.test, method)[1], dtype=float)


def target_spec(mode: str, subject: Subject, grid: PatchGrid | None, *, label: str = "", method: str | None = None,
                chart: Chart | None = None, nd: NdFilter | None = None) -> TargetSpec:
    """The TargetSpec the GUI and the CLI use: the chart (``chart``: the stand's own; None: the packaged target of
    ``mode``) with the grid placed by hand (None: found in the captured frames, app.processing.chart_detect: a
    ColorChecker Classic, a Digital SG, an IT8.7/1 or /2, or a generic grid of patches, from the chart's layout).
    ``method``: how the reference XYZ is integrated (simulation.datasets.target_xyz: 'eq-4.2' or 'astm-e308'). A
    target captured under the ND filter (``subject.nd``) has the patches ``nd`` covers scaled by its transmittance
    (default :class:`NdFilter`: ND 2.0 over the left half)."""
    if subject.kind is not SubjectKind.TARGET:
        raise ValueError(f"{subject.label}: not a colour target")
    chart = chart_of(mode, subject.name, {subject.name: chart} if chart is not None else None)
    rows, cols = chart.layout
    cells = chart.used_cells
    nd_mask = (nd or NdFilter()).mask((rows, cols), cells) if subject.nd else None
    nd_scale = nd_transmittance(nd_mask, (nd or NdFilter()).transmittance, len(cells)) if subject.nd else None
    xyz, names = reference_xyz(mode, subject.name, nd_scale, method=method, chart=chart)
    if grid is not None and (grid.rows, grid.cols) != (rows, cols) and chart.cells != list(range(len(chart.cells))):
        raise ValueError(f"{subject.label}: the grid has {grid.rows} x {grid.cols} cells but the chart's layout is "
                         f"{rows} x {cols}; set rows and columns")
    if grid is not None and grid.n_patches <= max(cells):
        raise ValueError(f"{subject.label}: the grid has {grid.n_patches} cells but the target {len(names)} "
                         "patches; set rows and columns")
    return TargetSpec(subject, xyz, names, grid, (rows, cols), None, label or f"{subject.name} ({chart.target.name})",
                      nd_mask, reference_spectra(mode, subject.name, nd_scale, chart=chart), mode, cells, chart,
                      geometry_of(chart))


def load_grid(path: Path, layout: tuple[int, int] | None = None) -> PatchGrid:
    """A patch grid from JSON: {"corners": [[x, y] x4 (TL, TR, BR, BL, stack pixels)], "rows", "cols"[, "fraction"]};
    "rows" / "cols" may be left out when ``layout`` (the chart's) gives them. At most :data:`MAX_GRID_BYTES`."""
    from dualrgb.simulation.spectral_io import read_text_file

    path = Path(path)
    try:
        data = json.loads(read_text_file(path, "patch grid JSON", ValueError, MAX_GRID_BYTES))
        rows, cols = (data["rows"], data["cols"]) if layout is None or "rows" in data else layout
        return PatchGrid(np.asarray(data["corners"], float), int(rows), int(cols), float(data.get("fraction", 0.5)))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: not a patch grid ({exc}); expected {{\"corners\": [[x, y], ...4], \"rows\": R, "
                         "\"cols\": C}") from None


def parse_corners(text: str, what: str = "corners") -> np.ndarray:
    """A chart's four corners from the command line: ``x1,y1,x2,y2,x3,y3,x4,y4`` or a JSON file holding
    ``{"corners": [[x, y], [x, y], [x, y], [x, y]]}`` (at most :data:`MAX_GRID_BYTES`); (4, 2) x, y. One line
    naming the value or the file when it is neither."""
    from dualrgb.simulation.spectral_io import read_json_file

    cells = [c.strip() for c in str(text).split(",")]
    if len(cells) > 1:
        try:
            values = [float(c) for c in cells]
        except ValueError:
            values = []
        if len(values) != 8 or not all(np.isfinite(values)):
            raise ValueError(f"{what} {text!r}: expected 8 numbers x1,y1,x2,y2,x3,y3,x4,y4 (the chart's top-left, "
                             "top-right, bottom-right, bottom-left corner) or a JSON file")
        return np.asarray(values, dtype=float).reshape(4, 2)
    path = Path(text)
    doc = read_json_file(path, f"{what} JSON", ValueError, MAX_GRID_BYTES)
    try:
        corners = np.asarray(doc["corners"], dtype=float).reshape(4, 2)
        if not np.isfinite(corners).all():
            raise ValueError("not finite")
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"{path}: not a list of corners; expected {{\"corners\": [[x, y], [x, y], [x, y], [x, y]]}} "
                         "(top-left, top-right, bottom-right, bottom-left)") from None
    return corners


def corners_grid(corners: np.ndarray, mode: str, name: str, chart: Chart | None = None,
                 fraction: float = 0.5) -> PatchGrid:
    """The patch grid of a target placed by its four corners in the frame's pixels (the raw frame's column x and
    row y, as a raw viewer shows them; top-left, top-right, bottom-right, bottom-left *of the chart*: the outer
    corners of its outermost patches), each patch where the chart's geometry puts it (simulation.chart_geometry);
    in the stack's (superpixel) coordinates. ``chart``: the stand's own, else the packaged target of ``mode``."""
    from dualrgb.app.processing.chart_detect import grid_on

    geometry = geometry_of(chart_of(mode, name, {name: chart} if chart is not None else None))
    try:
        return grid_on(np.asarray(corners, dtype=float), geometry, fraction).scaled(0.5)
    except ValueError as exc:
        raise ValueError(f"the {name} target's corners {np.asarray(corners).tolist()}: {exc}") from None
