"""Patch values from a colour target image: a grid on any quadrilateral, and optional automatic CC24 detection.

PatchGrid
    Four corners of the target's patch area in image pixels (x = column, y = row, pixel centres at integer
    coordinates), in the order top-left, top-right, bottom-right, bottom-left *of the target* (patch 1 is at the
    top-left corner, patches run row by row), ``rows`` x ``cols`` cells, and a sampling fraction: only the
    central ``fraction`` of each cell (in both directions) is used, away from edges, gaps and mis-registration.
    The cell layout is mapped with the homography of the unit square onto the quadrilateral, i.e. the exact
    image of a flat target under a pinhole camera (any rotation, tilt or perspective, not only rectangles).
    ``cell_boxes`` (optional, ``rows * cols`` x 4: u0, v0, u1, v1 in the unit square, NaN for a cell with no patch)
    puts each cell where the chart's patch really is instead of on the regular grid: a chart whose patches are not
    one regular grid (an IT8.7's grey scale below its 12 x 22 patches: simulation.chart_geometry); the corners are
    then those of the chart's patch area (the outer edges of its outermost patches).
    ``sample(image)`` gives per-patch robust means for every channel: a trimmed mean (10 % cut at each end per
    channel, ``scipy.stats.trim_mean``) that ignores dust, scratches and hot pixels without the variance of a
    median; NaN pixels (no usable flat field) are left out.

detect_cc24(image)
    Finds a ColorChecker Classic (24 patches) with the optional ``colour-checker-detection`` package and
    returns a :class:`Cc24Detection` (a PatchGrid fitted to the detected chart plus the library's own swatch
    values), or None with a log line when the package is not installed or no chart is found. Install it with
    ``pip install 'dualrgb[detect]'`` (it pulls opencv-python, ~77 MB wheel + ~50 MB of models). OpenCV's wheel
    sets QT_QPA_PLATFORM_PLUGIN_PATH on import, which would break the PySide6 GUI, so the environment is
    restored around the import.
"""
from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from dualrgb.simulation.chart_geometry import ChartGeometry

log = logging.getLogger(__name__)

TRIM = 0.10


def homography(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """3x3 H with dst ~ H @ [src, 1] for 4 point pairs (direct linear transform)."""
    a = []
    for (x, y), (u, v) in zip(src, dst, strict=True):
        a.append([x, y, 1, 0, 0, 0, -u * x, -u * y, -u])
        a.append([0, 0, 0, x, y, 1, -v * x, -v * y, -v])
    _, _, vt = np.linalg.svd(np.asarray(a, dtype=float))
    h = vt[-1].reshape(3, 3)
    return h / h[2, 2]


def _apply_h(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    p = np.c_[pts, np.ones(len(pts))] @ h.T
    return p[:, :2] / p[:, 2:3]


@dataclass
class PatchValues:
    """Per-patch statistics: ``mean`` (n, C) trimmed means, ``std`` (n, C), ``count`` (n,) pixels used."""

    mean: np.ndarray
    std: np.ndarray
    count: np.ndarray
    names: list[str] = field(default_factory=list)


@dataclass
class PatchGrid:
    corners: np.ndarray                 # (4, 2) x, y of the target's TL, TR, BR, BL corners
    rows: int
    cols: int
    fraction: float = 0.5               # central part of each cell that is sampled (0 < f <= 1)
    names: list[str] = field(default_factory=list)
    cell_boxes: np.ndarray | None = None  # (rows * cols, 4) u0, v0, u1, v1 per cell; None: the regular grid

    def __post_init__(self) -> None:
        self.corners = np.asarray(self.corners, dtype=float).reshape(4, 2)
        if self.rows < 1 or self.cols < 1:
            raise ValueError(f"patch grid needs at least 1 x 1 cells, got {self.rows} x {self.cols}")
        if self.cell_boxes is not None:
            self.cell_boxes = np.asarray(self.cell_boxes, dtype=float).reshape(-1, 4)
            if len(self.cell_boxes) != self.rows * self.cols:
                raise ValueError(f"patch grid: {len(self.cell_boxes)} cell boxes for {self.rows} x {self.cols} cells")
        if not 0 < self.fraction <= 1:
            raise ValueError(f"sampling fraction must be in (0, 1], got {self.fraction}")
        c = self.corners

        def cross(a: np.ndarray, b: np.ndarray) -> float:
            return float(a[0] * b[1] - a[1] * b[0])
        turns = [cross(c[(i + 1) % 4] - c[i], c[(i + 2) % 4] - c[(i + 1) % 4]) for i in range(4)]
        if not (all(x > 0 for x in turns) or all(x < 0 for x in turns)):
            raise ValueError("patch grid corners do not form a convex quadrilateral in TL, TR, BR, BL order")
        self._h = homography(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float), c)
        self._h_inv = np.linalg.inv(self._h)

    @property
    def n_patches(self) -> int:
        return self.rows * self.cols

    def to_image(self, uv: np.ndarray) -> np.ndarray:
        """Target coordinates (u across, v down, 0..1) -> image x, y."""
        return _apply_h(self._h, np.atleast_2d(uv))

    def to_target(self, xy: np.ndarray) -> np.ndarray:
        return _apply_h(self._h_inv, np.atleast_2d(xy))

    def boxes(self) -> np.ndarray:
        """(n, 4) u0, v0, u1, v1 of every cell in the unit square (``cell_boxes``, else the regular grid's);
        a row of NaN is a cell with no patch."""
        if self.cell_boxes is not None:
            return self.cell_boxes
        r, c = np.divmod(np.arange(self.n_patches), self.cols)
        return np.c_[c / self.cols, r / self.rows, (c + 1) / self.cols, (r + 1) / self.rows]

    def present(self) -> np.ndarray:
        """Boolean per cell: the cell has a patch (always, on the regular grid)."""
        return np.isfinite(self.boxes()).all(axis=1)

    def _sampled_boxes(self) -> np.ndarray:
        """The central ``fraction`` of every cell's box (unit square)."""
        b = self.boxes()
        h = (1 - self.fraction) / 2
        du, dv = (b[:, 2] - b[:, 0]) * h, (b[:, 3] - b[:, 1]) * h
        return np.c_[b[:, 0] + du, b[:, 1] + dv, b[:, 2] - du, b[:, 3] - dv]

    def centres(self) -> np.ndarray:
        """(n, 2) image x, y of every cell centre, row by row (NaN for a cell with no patch)."""
        b = self.boxes()
        return self.to_image(np.c_[(b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2])

    def sample_polygons(self) -> np.ndarray:
        """(n, 4, 2) image corners of each cell's sampled area (for drawing the grid over a preview; NaN for a
        cell with no patch)."""
        b = self._sampled_boxes()
        uv = np.stack([b[:, [0, 1]], b[:, [2, 1]], b[:, [2, 3]], b[:, [0, 3]]], axis=1)       # (n, 4, 2)
        return self.to_image(uv.reshape(-1, 2)).reshape(-1, 4, 2)

    def scaled(self, factor: float) -> PatchGrid:
        """The same grid for an image scaled by ``factor`` (0.5: full mosaic -> superpixel image).

        Pixel centres at integer coordinates: x_scaled = (x + 0.5) * factor - 0.5.
        """
        return PatchGrid((self.corners + 0.5) * factor - 0.5, self.rows, self.cols, self.fraction, list(self.names),
                         self.cell_boxes)

    def masks(self, shape: tuple[int, int]) -> list[tuple[slice, slice, np.ndarray]]:
        """For each cell, the bounding box (row slice, column slice) and the boolean mask inside it."""
        out = []
        sampled = self._sampled_boxes()
        polys = self.sample_polygons()
        H, W = shape
        empty = (slice(0, 0), slice(0, 0), np.zeros((0, 0), bool))
        for poly, (u0, v0, u1, v1) in zip(polys, sampled, strict=True):
            if not np.isfinite(poly).all():
                out.append(empty)
                continue
            x0 = max(int(np.floor(poly[:, 0].min())), 0)
            x1 = min(int(np.ceil(poly[:, 0].max())) + 1, W)
            y0 = max(int(np.floor(poly[:, 1].min())), 0)
            y1 = min(int(np.ceil(poly[:, 1].max())) + 1, H)
            if x1 <= x0 or y1 <= y0:
                out.append(empty)
                continue
            yy, xx = np.mgrid[y0:y1, x0:x1]
            uv = self.to_target(np.c_[xx.ravel(), yy.ravel()])
            inside = (uv[:, 0] >= u0) & (uv[:, 0] <= u1) & (uv[:, 1] >= v0) & (uv[:, 1] <= v1)
            out.append((slice(y0, y1), slice(x0, x1), inside.reshape(yy.shape)))
        return out

    def sample(self, image: np.ndarray, *, trim: float = TRIM) -> PatchValues:
        """Trimmed mean, std and pixel count of every channel in every cell; image is (H, W) or (H, W, C)."""
        img = image if image.ndim == 3 else image[..., None]
        n, C = self.n_patches, img.shape[2]
        mean = np.full((n, C), np.nan)
        std = np.full((n, C), np.nan)
        count = np.zeros(n, dtype=int)
        for k, (rs, cs, mask) in enumerate(self.masks(img.shape[:2])):
            if mask.size == 0:
                continue
            px = img[rs, cs][mask].astype(np.float64)            # (m, C)
            finite = np.isfinite(px).all(axis=1)
            px = px[finite]
            count[k] = px.shape[0]
            if px.shape[0] == 0:
                continue
            mean[k] = stats.trim_mean(px, trim, axis=0)
            std[k] = px.std(axis=0)
        empty = np.flatnonzero((count == 0) & self.present())
        if empty.size:
            log.warning("patch grid: %d cells have no usable pixels (outside the image or all NaN): %s",
                        empty.size, ", ".join(str(i + 1) for i in empty[:10]))
        return PatchValues(mean, std, count, list(self.names))


class ChartNotFound(ValueError):
    """A chart is not in the frame (one line: what was looked for and why it was not found;
    app.processing.chart_detect, app.processing.scanin)."""


def grid_on(corners: np.ndarray, geometry: ChartGeometry, fraction: float = 0.5) -> PatchGrid:
    """The patch grid of ``geometry`` on the four corners of its patch area (TL, TR, BR, BL of the chart, image
    x, y): the chart's layout as rows x cols, each cell where the chart's patch is (PatchGrid.cell_boxes)."""
    rows, cols = geometry.layout
    return PatchGrid(corners, rows, cols, fraction, cell_boxes=geometry.unit_boxes())


@dataclass
class Cc24Detection:
    grid: PatchGrid               # 4 x 6 grid in the input image's coordinates
    swatches: np.ndarray          # (24, 3) the library's own swatch values (of the RGB image it was given)


def _import_detection():
    """Import colour_checker_detection without letting OpenCV's wheel repoint Qt's plugin path."""
    saved = {k: os.environ.get(k) for k in ("QT_QPA_PLATFORM_PLUGIN_PATH", "QT_QPA_FONTDIR")}
    try:
        import colour_checker_detection as ccd
        return ccd
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def detect_cc24(image: np.ndarray, *, fraction: float = 0.5) -> Cc24Detection | None:
    """Find a ColorChecker Classic in an (H, W, 3) RGB image (linear or display-encoded, any scale).

    Returns None (with a log line) when ``colour-checker-detection`` is not installed or finds no chart.
    """
    try:
        ccd = _import_detection()
    except ImportError as exc:
        log.info("automatic chart detection unavailable (%s); place the patch grid by hand or install "
                 "dualrgb[detect]", exc)
        return None
    img = np.asarray(image, dtype=np.float32)
    if img.ndim != 3 or img.shape[2] < 3:
        raise ValueError(f"detect_cc24 needs an (H, W, 3) RGB image, got shape {img.shape}")
    img = img[..., :3]
    finite = img[np.isfinite(img)]
    top = float(np.percentile(finite, 99.5)) if finite.size else 0.0
    if top <= 0:
        log.info("detect_cc24: image is black; no chart")
        return None
    img = np.clip(np.nan_to_num(img / top), 0, 1).astype(np.float32)
    try:
        found = ccd.detect_colour_checkers_segmentation(img, additional_data=True)
    except Exception as exc:  # noqa: BLE001 - third-party detector: any failure means "not found"
        log.info("detect_cc24: detector failed (%s: %s)", type(exc).__name__, exc)
        return None
    if not found:
        log.info("detect_cc24: no ColorChecker Classic found")
        return None
    best = found[0]
    # the quadrilateral is in the detector's working image (resized to 1440 px wide), ordered like its target
    # rectangle: top-right, bottom-right, bottom-left, top-left of the chart
    scale = img.shape[1] / 1440.0
    q = np.asarray(best.quadrilateral, dtype=float) * scale
    corners = np.array([q[3], q[0], q[1], q[2]])
    try:
        grid = PatchGrid(corners, 4, 6, fraction)
    except ValueError as exc:
        log.info("detect_cc24: detected outline is not usable (%s)", exc)
        return None
    log.info("detect_cc24: chart found, corners %s", np.round(corners, 1).tolist())
    return Cc24Detection(grid, np.asarray(best.swatch_colours, dtype=float))
