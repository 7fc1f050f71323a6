"""What lies on the virtual copy stand: a target (patches on a grid), an original (a painting, a film frame;
drivers/virtual/originals.py), the open gate, the lens cap, or a uniform field that emits its own light (a
monochromator's output diffused by an integrating sphere, thesis 4.2: :class:`FieldLight`).

The scene is described at patch level: every pixel carries a *class* (a patch, the neutral surround, the
dark gaps between patches, and the same again under the ND 2.0 filter of thesis 8.3), and each class has one
spectrum (reflectance or transmittance). The virtual camera computes one response per class (eq 5.10) and
looks it up per pixel, so no spectral work is ever done per pixel. An original brings its own classes (a
palette of spectra) and class map; the camera renders it exactly like a chart.

Geometry (pixel coordinates of the full sensor, rows then columns, half-open boxes):

* the patch grid (``rows`` x ``cols``, patch ``i`` at row ``i // cols``, column ``i % cols``) is centred in
  the frame with ``margin`` (fraction of the frame) of surround around it;
* each grid cell is one pitch wide; the patch fills it except for ``gap`` (a fraction of the pitch) of dark
  separator, split evenly on both sides;
* the ND filter covers the left half of the columns (``cols // 2`` of them) over the grid's height, up to the
  middle of the gap after the last covered column;
* a chart the lab knows physically (a ColorChecker Classic, a Digital SG, an IT8.7: simulation.chart_geometry)
  is drawn as it is instead: its body (dark) with its patches at their sizes, gaps and borders (the IT8's grey scale
  below its 12 x 22 patches), fitted inside the ``margin``; and any chart may lie in a ``pose`` (turned, moved,
  scaled: drivers/virtual/chart_pose.py). Such scenes classify every pixel through the chart's coordinates; the
  generic grid without a pose keeps the separable rows-then-columns classification above (bit for bit as before);
* vignetting is a smooth radial falloff ``exp(-a r^2)`` (r = 1 at the frame corners) losing ``vignetting``
  at the corners; it is separable, so it is applied as two 1-D profiles and never stored per pixel.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from dualrgb.drivers.virtual.chart_pose import ChartPose, Placement
from dualrgb.drivers.virtual.originals import Original, original, original_name
from dualrgb.simulation.chart_geometry import OUTSIDE, SURROUND, ChartGeometry, geometry_for
from dualrgb.simulation.datasets import Target
from dualrgb.simulation.grid import DEFAULT_GRID, SpectralGrid

log = logging.getLogger(__name__)

SCENE_KINDS = ("target", "original", "open_gate", "lens_cap", "field")
ND_2_TRANSMITTANCE = 0.01          # optical density 2.0
_OUTSIDE = -2                       # 1-D cell codes: outside the grid
_GAP = -1                           # ... inside the grid, in a gap


Emission = Callable[[], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True, eq=False)
class FieldLight:
    """A uniform field that emits its own light, whatever the sphere does: ``emission()`` returns (wavelengths in
    nm, spectral radiance) *now*, the radiance in the camera's relative units (the virtual camera integrates it
    against the sensitivities it renders with: ``VirtualCamera.field_response``)."""

    emission: Emission
    name: str = "field"

    def frozen(self) -> FieldLight:
        """This field as it emits now, fixed (what one exposure sees)."""
        wl, radiance = self.emission()
        wl, radiance = np.array(wl, dtype=float), np.array(radiance, dtype=float)
        return FieldLight(lambda: (wl, radiance), self.name)

    def emits(self) -> bool:
        return bool(np.any(np.asarray(self.emission()[1]) > 0))


@dataclass(frozen=True, eq=False)
class Scene:
    """A frame's content; change it with :func:`dataclasses.replace` or the constructors below.

    Frozen (derived geometry is cached on the instance) and compared by identity.
    """

    kind: str = "target"                     # 'target' | 'original' | 'open_gate' | 'lens_cap' | 'field'
    target: Target | None = None          # required for kind 'target' (reflective or transmissive)
    width: int = 600                         # sensor columns (even; the D610 is 6080 x 4028)
    height: int = 400                        # sensor rows (even)
    grid_shape: tuple[int, int] | None = None   # (rows, cols); default from target.layout or near-square
    margin: float = 0.06                     # surround around the grid, fraction of width / height
    gap: float = 0.12                        # dark separator between patches, fraction of the pitch
    surround: float = 0.18                   # neutral surround (flat spectrum), mid grey
    gap_value: float = 0.03                  # the separators (flat spectrum), nearly black
    nd_filter: bool = False                  # ND 2.0 over the left half of the columns (thesis 8.3)
    nd_transmittance: float = ND_2_TRANSMITTANCE
    vignetting: float = 0.04                 # relative falloff at the frame corners (0 = none)
    name: str = ""
    original: Original | None = None    # required for kind 'original'
    field: FieldLight | None = None     # required for kind 'field'
    pose: ChartPose | None = None       # how a chart lies (a world's chart_pose); None: square and centred

    def __post_init__(self) -> None:
        if self.kind not in SCENE_KINDS:
            raise ValueError(f"scene kind {self.kind!r}: expected one of {', '.join(SCENE_KINDS)}")
        if self.kind == "target" and (self.target is None or len(self.target) == 0):
            raise ValueError("a 'target' scene needs a target with at least one patch")
        if self.kind == "original" and self.original is None:
            raise ValueError("an 'original' scene needs an original (drivers.virtual.originals.original(name))")
        if self.kind == "field" and self.field is None:
            raise ValueError("a 'field' scene needs its FieldLight (what it emits)")
        if self.kind == "original" and self.nd_filter:
            raise ValueError(f"ND filter over original {self.shown_original.name!r}: the ND half is for charts "
                             "(thesis 8.3); originals bring their own range (e.g. 'shadow')")
        for label, v in (("width", self.width), ("height", self.height)):
            if v < 8 or v % 2:
                raise ValueError(f"scene {label} {v}: expected an even number of pixels >= 8 (Bayer 2x2 blocks)")
        if not 0.0 <= self.margin < 0.45:
            raise ValueError(f"scene margin {self.margin}: expected 0 <= margin < 0.45 of the frame")
        if not 0.0 <= self.gap < 0.9:
            raise ValueError(f"scene gap {self.gap}: expected 0 <= gap < 0.9 of the patch pitch")
        if not 0.0 <= self.vignetting < 0.9:
            raise ValueError(f"scene vignetting {self.vignetting}: expected 0 <= falloff < 0.9")
        if not 0.0 < self.nd_transmittance <= 1.0:
            raise ValueError(f"ND transmittance {self.nd_transmittance}: expected 0 < T <= 1")
        if self.kind == "target":
            rows, cols = self.layout
            if rows < 1 or cols < 1 or rows * cols < len(self.shown_target):
                raise ValueError(f"grid {rows}x{cols} cannot hold {len(self.shown_target)} patches")
            small = (self.placement.min_patch_px() < 4) if self.placement is not None else min(self.pitch) < 4
            if small:
                raise ValueError(
                    f"a {self.width}x{self.height} frame is too small for a {rows}x{cols} grid (patches under 4 px)")

    # --- constructors -----------------------------------------------------------------------------------
    @classmethod
    def with_target(cls, target: Target, width: int = 600, height: int = 400, **kw) -> Scene:
        return cls(kind="target", target=target, width=width, height=height, name=kw.pop("name", target.name), **kw)

    @classmethod
    def with_original(cls, original: Original, width: int = 600, height: int = 400, **kw) -> Scene:
        """An original on the stand (its class map follows the frame size)."""
        return cls(kind="original", original=original, width=width, height=height,
                   name=kw.pop("name", original.name), **kw)

    @classmethod
    def open_gate(cls, width: int = 600, height: int = 400, **kw) -> Scene:
        """Nothing on the stand: uniform white (reflectance / transmittance 1), the flat-field of eq 7.1."""
        return cls(kind="open_gate", width=width, height=height, name=kw.pop("name", "open gate"), **kw)

    @classmethod
    def lens_cap(cls, width: int = 600, height: int = 400, **kw) -> Scene:
        """Lens cap on: no light reaches the sensor, the dark frame of eq 7.1."""
        return cls(kind="lens_cap", width=width, height=height, name=kw.pop("name", "lens cap"), **kw)

    @classmethod
    def uniform_field(cls, field: FieldLight, width: int = 600, height: int = 400, **kw) -> Scene:
        """A uniform field emitting ``field``'s light (no target; the sphere's light plays no part)."""
        return cls(kind="field", field=field, width=width, height=height, name=kw.pop("name", field.name), **kw)

    def at_exposure(self) -> Scene:
        """This scene as one exposure sees it: a field's emission is fixed at this moment; other kinds as they are."""
        if self.kind != "field":
            return self
        return replace(self, field=self.shown_field.frozen())

    # --- what the scene shows ---------------------------------------------------------------------------
    @property
    def shown_field(self) -> FieldLight:
        """The light of a 'field' scene."""
        if self.field is None:
            raise ValueError(f"a {self.kind!r} scene emits no light of its own")
        return self.field

    @property
    def shown_target(self) -> Target:
        """The target of a 'target' scene."""
        if self.target is None:
            raise ValueError(f"a {self.kind!r} scene shows no target")
        return self.target

    @property
    def shown_original(self) -> Original:
        """The original of an 'original' scene."""
        if self.original is None:
            raise ValueError(f"a {self.kind!r} scene shows no original")
        return self.original

    # --- geometry ---------------------------------------------------------------------------------------
    @property
    def n_patches(self) -> int:
        return len(self.shown_target) if self.kind == "target" else 0

    @cached_property
    def layout(self) -> tuple[int, int]:
        """(rows, cols) of the patch grid (rows grow so the grid holds every patch)."""
        if self.kind != "target":
            return (0, 0)
        n = len(self.shown_target)
        if self.grid_shape is not None:
            return int(self.grid_shape[0]), int(self.grid_shape[1])
        if self.shown_target.layout is not None:
            cols = int(self.shown_target.layout[1])
        else:
            inner_aspect = self.width / self.height
            cols = max(1, int(round(math.sqrt(n * inner_aspect))))
        return int(math.ceil(n / cols)), cols

    @cached_property
    def geometry(self) -> ChartGeometry | None:
        """The chart's physical geometry (simulation.chart_geometry.geometry_for: a known chart, else the generic
        grid); None without a target."""
        if self.kind != "target":
            return None
        t = self.shown_target
        return geometry_for(self.layout, len(t), list(t.patch_names), gap=self.gap)

    @cached_property
    def placement(self) -> Placement | None:
        """Where the chart lies in the frame (drivers.virtual.chart_pose), for a known chart or a posed one; None
        for the generic grid square and centred, which the separable classification draws (module docstring)."""
        geometry = self.geometry
        if geometry is None:
            return None
        pose = self.pose or ChartPose()
        if geometry.name == "grid" and pose.identity:
            return None
        return Placement(geometry, self.width, self.height, self.margin, pose)

    @cached_property
    def _grid_box(self) -> tuple[float, float, float, float]:
        """(top, left, pitch_y, pitch_x) of the grid in pixels (float)."""
        rows, cols = self.layout
        inner_h = self.height * (1 - 2 * self.margin)
        inner_w = self.width * (1 - 2 * self.margin)
        pitch = min(inner_h / rows, inner_w / cols)        # square cells, grid centred
        top = (self.height - pitch * rows) / 2
        left = (self.width - pitch * cols) / 2
        return top, left, pitch, pitch

    @property
    def pitch(self) -> tuple[float, float]:
        top, left, py, px = self._grid_box
        return py, px

    def _edges(self, start: float, pitch: float, count: int) -> tuple[np.ndarray, np.ndarray]:
        """Integer [start, end) pixel edges of the patches (cells minus the gap) along one axis."""
        g = self.gap * pitch / 2
        cells = start + pitch * np.arange(count)
        return np.round(cells + g).astype(int), np.round(cells + pitch - g).astype(int)

    def patch_boxes(self) -> list[tuple[int, int, int, int]]:
        """(row0, row1, col0, col1), half-open, per patch in target order; [] without a target."""
        if self.kind != "target":
            return []
        if self.placement is not None:
            return self.placement.patch_boxes()
        rows, cols = self.layout
        top, left, py, px = self._grid_box
        r0, r1 = self._edges(top, py, rows)
        c0, c1 = self._edges(left, px, cols)
        return [(int(r0[i // cols]), int(r1[i // cols]), int(c0[i % cols]), int(c1[i % cols]))
                for i in range(self.n_patches)]

    def corners(self) -> list[tuple[float, float]]:
        """(row, col) of the grid's 4 outer corners: top-left, top-right, bottom-right, bottom-left.

        These are the outer edges of the corner patches (the outermost half-gap excluded), where a
        technician would click to register the grid; for a known or posed chart the corners of its patch area
        (ChartGeometry.patch_area) wherever the pose put them; [] without a target.
        """
        if self.kind != "target":
            return []
        if self.placement is not None:
            return self.placement.corners()
        rows, cols = self.layout
        top, left, py, px = self._grid_box
        g = self.gap * py / 2
        y0, y1 = top + g, top + rows * py - g
        x0, x1 = left + g, left + cols * px - g
        return [(y0, x0), (y0, x1), (y1, x1), (y1, x0)]

    def nd_patches(self) -> np.ndarray:
        """Boolean per patch: under the ND filter (left ``cols // 2`` columns) when the filter is on."""
        if self.kind != "target":
            return np.zeros(0, dtype=bool)
        if self.placement is not None:
            x0, y0, x1, y1 = self.placement.nd_box()
            c = self.placement.geometry.centres()[:self.n_patches]
            inside = (c[:, 0] >= x0) & (c[:, 0] < x1) & (c[:, 1] >= y0) & (c[:, 1] < y1)
            return np.asarray(self.nd_filter & inside, dtype=bool)
        cols = self.layout[1]
        return np.array([self.nd_filter and (i % cols) < cols // 2 for i in range(self.n_patches)], dtype=bool)

    # --- classes ----------------------------------------------------------------------------------------
    @property
    def n_classes(self) -> int:
        """Distinct pixel classes: patches, surround, gap (and those again under the ND filter)."""
        if self.kind == "original":
            return self.shown_original.n_classes
        if self.kind != "target":
            return 1
        return 2 * (self.n_patches + 2)

    def class_spectra(self, n_wavelengths: int) -> np.ndarray:
        """(n_classes, n_wavelengths) reflectance / transmittance of every pixel class.

        The target's spectra must already be on the simulation grid (``n_wavelengths`` samples).
        """
        if self.kind == "open_gate":
            return np.ones((1, n_wavelengths))
        if self.kind == "lens_cap":
            return np.zeros((1, n_wavelengths))
        if self.kind == "field":
            raise ValueError("a 'field' scene emits its own light: the camera renders it with field_response")
        if self.kind == "original":
            return self.shown_original.class_spectra(n_wavelengths)
        spectra = np.asarray(self.shown_target.spectra, dtype=float)
        if spectra.shape[1] != n_wavelengths:
            raise ValueError(
                f"target {self.shown_target.name!r} has {spectra.shape[1]} wavelengths but the camera's grid has "
                f"{n_wavelengths}; load it on the same grid")
        base = np.vstack([spectra, np.full((1, n_wavelengths), self.surround),
                          np.full((1, n_wavelengths), self.gap_value)])
        return np.vstack([base, base * self.nd_transmittance])

    def _axis_cells(self, idx: np.ndarray, start: float, pitch: float, count: int) -> np.ndarray:
        """Per pixel index along one axis: the grid cell, _GAP inside the grid between patches, _OUTSIDE."""
        p0, p1 = self._edges(start, pitch, count)
        lo, hi = int(round(start)), int(round(start + pitch * count))
        cell = np.floor((idx + 0.5 - start) / pitch).astype(np.int32)
        cell = np.clip(cell, 0, count - 1)
        inside_patch = (idx >= p0[cell]) & (idx < p1[cell])
        out = np.where(inside_patch, cell, _GAP).astype(np.int32)
        out[(idx < lo) | (idx >= hi)] = _OUTSIDE
        return out

    def labels(self, row_idx: np.ndarray, col_idx: np.ndarray) -> np.ndarray:
        """Class of every pixel at (row_idx x col_idx) (an outer product of the two index vectors), uint16.

        Built by broadcasting two 1-D classifications; ask for a Bayer plane with ``arange(0, H, 2)``.
        """
        row_idx = np.asarray(row_idx)
        col_idx = np.asarray(col_idx)
        if self.kind == "original":
            return self.shown_original.labels(row_idx, col_idx, self.height, self.width)
        if self.kind != "target":
            return np.zeros((len(row_idx), len(col_idx)), dtype=np.uint16)
        if self.placement is not None:
            return self._placed_labels(self.placement, row_idx, col_idx)
        n = self.n_patches
        rows, cols = self.layout
        top, left, py, px = self._grid_box
        rc = self._axis_cells(row_idx, top, py, rows)[:, None]
        cc = self._axis_cells(col_idx, left, px, cols)[None, :]
        surround, gap = n, n + 1
        patch = rc * cols + cc
        in_grid = (rc != _OUTSIDE) & (cc != _OUTSIDE)
        is_patch = (rc >= 0) & (cc >= 0) & (patch < n)
        lab = np.where(is_patch, patch, np.where(in_grid, gap, surround)).astype(np.uint16)
        if self.nd_filter:
            half = cols // 2
            if half:
                g = self.gap * px / 2
                nd_end = int(round(left + half * px))              # middle of the gap after column half-1
                nd_cols = (col_idx >= int(round(left + g))) & (col_idx < nd_end)
                nd_rows = (row_idx >= int(round(top + g))) & (row_idx < int(round(top + rows * py - g)))
                lab += ((nd_rows[:, None] & nd_cols[None, :]) * (n + 2)).astype(np.uint16)
        return lab

    def _placed_labels(self, placement: Placement, row_idx: np.ndarray, col_idx: np.ndarray) -> np.ndarray:
        """labels() of a known or posed chart: each pixel centre's class in the chart's coordinates."""
        n = self.n_patches
        k = placement.classify_pixels(row_idx, col_idx)
        lab = np.where(k >= 0, k, np.where(k == SURROUND, n + 1, n)).astype(np.uint16)
        if self.nd_filter:
            under = placement.inside(row_idx, col_idx, placement.nd_box()) & (k != OUTSIDE)
            lab += (under * (n + 2)).astype(np.uint16)
        return lab

    def vignetting_profiles(self, row_idx: np.ndarray, col_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Separable falloff: multiply pixel (r, c) by ``vy[r] * vx[c]`` (float32); both 1 without vignetting."""
        if self.vignetting <= 0:
            return np.ones(len(row_idx), np.float32), np.ones(len(col_idx), np.float32)
        a = -math.log(1.0 - self.vignetting)                       # exp(-a) at r = 1 (a corner)
        half_diag2 = ((self.width / 2) ** 2 + (self.height / 2) ** 2)
        y = (np.asarray(row_idx, float) + 0.5 - self.height / 2)
        x = (np.asarray(col_idx, float) + 0.5 - self.width / 2)
        return (np.exp(-a * y * y / half_diag2).astype(np.float32),
                np.exp(-a * x * x / half_diag2).astype(np.float32))

    def describe(self) -> dict[str, object]:
        d: dict[str, object] = {"kind": self.kind, "name": self.name, "size": f"{self.width}x{self.height}"}
        if self.kind == "target":
            d.update(patches=self.n_patches, grid="{}x{}".format(*self.layout), nd_filter=self.nd_filter)
            if self.geometry is not None and self.geometry.name != "grid":
                d.update(chart=self.geometry.name)
            if self.pose is not None and not self.pose.identity:
                d.update(pose=self.pose.to_dict())
        elif self.kind == "original":
            d.update(self.shown_original.describe())
        return d


def original_scene(what: str, width: int, height: int, *, mode: str | None = None,
                   grid: SpectralGrid = DEFAULT_GRID, **scene_kw) -> Scene:
    """The scene of original ``what`` ('original:<name>') at ``width`` x ``height`` sensor pixels.

    An original of the other mode than ``mode`` (a film in a reflective lab) is rendered all the same (the
    camera model is eq 5.10 in both modes) but logged: its calibration should be of its own mode.
    """
    orig = original(original_name(what), grid)
    if mode is not None and mode != orig.mode:
        log.warning("original %r is %s but the lab is %s: calibrate in %s mode to deliver it", orig.name,
                    orig.mode, mode, orig.mode)
    return Scene.with_original(orig, width=width, height=height, **scene_kw)
