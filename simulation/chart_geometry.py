"""Where a chart's patches physically lie: patch sizes, gaps and borders of the charts copy stands use, so that the
virtual lab renders them as they are and the patch detector (app.processing.chart_detect) looks for what is there.

A :class:`ChartGeometry` is a chart body (a rectangle, ``size`` in the chart's own units, x right, y down) holding
blocks of equal patches on a regular pitch. Its patches are numbered in the chart's order: the first block row by
row, then the next. That order is the row-major cell order of the chart's layout (simulation.charts: ``rows`` x
``cols`` cells), so patch ``k`` of the geometry is cell ``k`` of the layout.

The geometries of the physical charts are those of ArgyllCMS's recognition templates (Debian ``argyll-ref``:
``/usr/share/color/argyll/ref/*.cht``, measured off scans of the real charts; the numbers below are the charts'
physical layout, restated here, not copied data files):

=====================================  ========================================================================
chart (``name``)                       geometry (template units)
=====================================  ========================================================================
``ColorChecker Classic`` (4 x 6)       body 330 x 228; patches 46 x 46 on a 52.5 pitch from (12, 11.5):
                                       rows A-D down, columns 1-6 across (``ColorChecker.cht``)
``ColorChecker Digital SG`` (10 x 14)  body 263.95 x 185.5; patches 12.675 x 12.75 on a 15.175 x 15.25 pitch from
                                       (27.5, 20): columns A-N across, rows 1-10 down (``ColorCheckerSG.cht``)
``IT8.7`` (12 x 22 + 24 greys)         body 615 x 409; 12 x 22 patches 25.625 square without gaps from (26.625,
                                       26.625), rows A-L, columns 01-22; below them the grey scale GS00-GS23,
                                       24 patches 25.625 x 51.25 from (0, 358.75) (``it8.cht``; IT8.7/1 film and
                                       IT8.7/2 reflective share it)
``grid`` (any other layout)            rows x cols cells of pitch 1, each patch ``1 - gap`` square, centred in its
                                       cell; the body is the cells (the virtual lab's generic chart)
=====================================  ========================================================================

Inside the body, whatever is not a patch is the chart's dark surround (the gaps and borders).
"""
from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

log = logging.getLogger(__name__)

DEFAULT_GAP = 0.12                   # the generic grid's separator, fraction of the pitch (drivers.virtual.scene)
ARGYLL_REF = "/usr/share/color/argyll/ref"
OUTSIDE = -2                         # classify(): outside the chart body
SURROUND = -1                        # ... inside the body, not on a patch (gaps, borders)
_IT8_NAME = re.compile(r"^([A-La-l])0*(\d{1,2})$")


@dataclass(frozen=True)
class PatchBlock:
    """``rows`` x ``cols`` equal patches: the first's top-left corner at ``origin`` (x, y), ``step`` (x, y) from one
    patch to the next, each ``size`` (w, h); all in the chart's units."""

    rows: int
    cols: int
    origin: tuple[float, float]
    step: tuple[float, float]
    size: tuple[float, float]

    @property
    def count(self) -> int:
        return self.rows * self.cols

    def boxes(self) -> np.ndarray:
        """(rows * cols, 4) x0, y0, x1, y1 of every patch, row by row."""
        r, c = np.divmod(np.arange(self.count), self.cols)
        x0 = self.origin[0] + c * self.step[0]
        y0 = self.origin[1] + r * self.step[1]
        return np.c_[x0, y0, x0 + self.size[0], y0 + self.size[1]]

    def classify(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Per point: the block's patch index, or -1 off its patches (vectorised; x, y broadcast)."""
        sx, sy = self.step                      # a single row / column: any positive step will do
        sx, sy = (sx if self.cols > 1 else self.size[0]), (sy if self.rows > 1 else self.size[1])
        fx = (x - self.origin[0]) / sx
        fy = (y - self.origin[1]) / sy
        i, j = np.floor(fx), np.floor(fy)
        on = ((i >= 0) & (i < self.cols) & (j >= 0) & (j < self.rows)
              & ((fx - i) * sx < self.size[0]) & ((fy - j) * sy < self.size[1]))
        return np.where(on, j * self.cols + i, -1).astype(np.int32)


@dataclass(frozen=True)
class ChartGeometry:
    """A chart's body and patch blocks (module docstring); ``count`` patches of them are on the chart (a generic
    grid's last row may be partly filled); ``template``: ArgyllCMS's recognition template for it, '' for none."""

    name: str
    size: tuple[float, float]
    blocks: tuple[PatchBlock, ...]
    count: int
    layout: tuple[int, int]                 # the chart's layout (rows, cols) whose cells the patches fill in order
    template: str = ""

    def __post_init__(self) -> None:
        if self.count > sum(b.count for b in self.blocks) or self.count > self.layout[0] * self.layout[1]:
            raise ValueError(f"{self.name}: {self.count} patches do not fit its blocks / {self.layout} layout")

    @cached_property
    def boxes(self) -> np.ndarray:
        """(count, 4) x0, y0, x1, y1 of every patch in chart order."""
        return np.vstack([b.boxes() for b in self.blocks])[:self.count]

    @property
    def patch_area(self) -> tuple[float, float, float, float]:
        """x0, y0, x1, y1 of the rectangle around all patches (the outer edges of the outermost patches): what
        a patch grid's four corners are (app.processing.patches.PatchGrid)."""
        b = self.boxes
        return float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max())

    def unit_boxes(self) -> np.ndarray:
        """(rows * cols, 4) every layout cell's patch as u0, v0, u1, v1 fractions of the patch area; NaN for a
        cell without a patch."""
        x0, y0, x1, y1 = self.patch_area
        out = np.full((self.layout[0] * self.layout[1], 4), np.nan)
        b = self.boxes
        out[:self.count] = np.c_[(b[:, 0] - x0) / (x1 - x0), (b[:, 1] - y0) / (y1 - y0),
                                 (b[:, 2] - x0) / (x1 - x0), (b[:, 3] - y0) / (y1 - y0)]
        return out

    def classify(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Per point (chart units; x, y broadcast): the patch index, :data:`SURROUND` inside the body off the
        patches, :data:`OUTSIDE` off the body."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        out = np.full(x.shape, SURROUND, dtype=np.int32)
        first = 0
        for block in self.blocks:
            k = block.classify(x, y)
            hit = (k >= 0) & (k + first < self.count)
            out[hit] = k[hit] + first
            first += block.count
        w, h = self.size
        out[(x < 0) | (x >= w) | (y < 0) | (y >= h)] = OUTSIDE
        return out

    def edges(self, axis: int) -> tuple[np.ndarray, np.ndarray]:
        """The patch edges across ``axis`` (0: x, the vertical edges; 1: y) with how many patches share each:
        what an image's edge profile along that axis shows (app.processing.chart_detect)."""
        b = self.boxes
        pos = np.r_[b[:, axis], b[:, axis + 2]]
        values, counts = np.unique(np.round(pos, 6), return_counts=True)
        return values, counts.astype(float)

    def centres(self) -> np.ndarray:
        """(count, 2) x, y of every patch's centre."""
        b = self.boxes
        return np.c_[(b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2]


def classic24() -> ChartGeometry:
    """The X-Rite / Calibrite ColorChecker Classic (24 patches, 4 x 6)."""
    return ChartGeometry("ColorChecker Classic", (330.0, 228.0),
                         (PatchBlock(4, 6, (12.0, 11.5), (52.5, 52.5), (46.0, 46.0)),), 24, (4, 6),
                         "ColorChecker.cht")


def digital_sg() -> ChartGeometry:
    """The ColorChecker Digital SG (140 patches, 10 rows x 14 columns)."""
    return ChartGeometry("ColorChecker Digital SG", (263.95, 185.5),
                         (PatchBlock(10, 14, (27.5, 20.0), (15.175, 15.25), (12.675, 12.75)),), 140, (10, 14),
                         "ColorCheckerSG.cht")


def it8(layout: tuple[int, int] = (14, 22)) -> ChartGeometry:
    """An IT8.7/1 (film) or IT8.7/2 (reflective) target: 12 x 22 patches and a 24-step grey scale below them
    (288 patches; ``layout`` the chart's, e.g. 14 x 22 when the grey scale fills two more rows of 22)."""
    return ChartGeometry("IT8.7", (615.0, 409.0),
                         (PatchBlock(12, 22, (26.625, 26.625), (25.625, 25.625), (25.625, 25.625)),
                          PatchBlock(1, 24, (0.0, 358.75), (25.625, 51.25), (25.625, 51.25))), 288, layout,
                         "it8.cht")


def grid(rows: int, cols: int, count: int | None = None, gap: float = DEFAULT_GAP) -> ChartGeometry:
    """A generic chart: ``rows`` x ``cols`` cells of pitch 1, patches ``1 - gap`` square (``count`` of them,
    default every cell)."""
    g = gap / 2
    n = rows * cols if count is None else count
    return ChartGeometry("grid", (float(cols), float(rows)), (PatchBlock(rows, cols, (g, g), (1.0, 1.0),
                                                                        (1 - gap, 1 - gap)),), n, (rows, cols))


def _it8_names(names: Sequence[str]) -> bool:
    """True when the first 264 names are an IT8's A01 .. L22, row by row."""
    if len(names) < 264:
        return False
    for k, name in enumerate(names[:264]):
        m = _IT8_NAME.match(name.strip())
        if m is None or (ord(m.group(1).upper()) - ord("A"), int(m.group(2)) - 1) != divmod(k, 22):
            return False
    return True


def geometry_for(layout: tuple[int, int], count: int, names: Sequence[str] = (), gap: float = DEFAULT_GAP
                 ) -> ChartGeometry:
    """The geometry of a chart with ``count`` patches (``names``) on a ``layout`` (rows, cols) of cells: a
    ColorChecker Classic (24 on 4 x 6), a Digital SG (140 on 10 x 14), an IT8.7 (288 on 22 columns, or named
    A01 .. L22 + 24 greys), else the generic grid."""
    rows, cols = int(layout[0]), int(layout[1])
    if (rows, cols) == (4, 6) and count == 24:
        return classic24()
    if (rows, cols) == (10, 14) and count == 140:
        return digital_sg()
    if count == 288 and rows * cols >= 288 and (cols == 22 or _it8_names(names)):
        return it8((rows, cols))
    return grid(rows, cols, count, gap)


def geometry_of(chart: object) -> ChartGeometry:
    """The geometry of a :class:`simulation.charts.Chart` as the virtual lab draws it and the detector looks for
    it: from every cell of its layout as it lies on the stand (``Chart.render_target``)."""
    from dualrgb.simulation.charts import Chart

    if not isinstance(chart, Chart):
        raise TypeError(f"geometry_of needs a simulation.charts.Chart, not {type(chart).__name__}")
    target = chart.render_target()
    return geometry_for(chart.layout, len(target), list(target.patch_names))
