"""How a chart lies on the virtual copy stand: its pose (a world's ``chart_pose``) and the map between the chart's
own units (simulation.chart_geometry) and the frame's pixels.

Frame coordinates are the scene's: x a column, y a row, pixel ``i`` covering [i, i + 1) (its centre at i + 0.5).
The chart's body is first fitted into the frame with ``margin`` on every side and centred (what the lab has always
done); the pose then scales it about its centre by ``scale``, turns it by ``rotation_deg`` (counter-clockwise as the
frame is viewed, rows down) and moves it by ``shift_x`` of the frame's width to the right and ``shift_y`` of its
height down:

    frame = frame_centre + (shift_x * W, shift_y * H) + s * R(rotation) @ (chart - chart_centre)

with ``s`` the fitted scale times ``scale``. A real chart on a stand is never exactly square to the camera; the
detector (app.processing.chart_detect) must find it wherever this puts it.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from dualrgb.simulation.chart_geometry import ChartGeometry

log = logging.getLogger(__name__)

MAX_SHIFT = 0.5                 # of the frame
SCALE_RANGE = (0.2, 2.0)


@dataclass(frozen=True)
class ChartPose:
    """A chart's pose on the stand (module docstring); the default is square, centred, full size."""

    rotation_deg: float = 0.0
    shift_x: float = 0.0
    shift_y: float = 0.0
    scale: float = 1.0

    def __post_init__(self) -> None:
        for name, value, lo, hi in (("rotation_deg", self.rotation_deg, -180.0, 180.0),
                                    ("shift_x", self.shift_x, -MAX_SHIFT, MAX_SHIFT),
                                    ("shift_y", self.shift_y, -MAX_SHIFT, MAX_SHIFT),
                                    ("scale", self.scale, *SCALE_RANGE)):
            if not (math.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"chart pose {name} {value}: expected a number from {lo:g} to {hi:g}")

    @property
    def identity(self) -> bool:
        return (self.rotation_deg, self.shift_x, self.shift_y, self.scale) == (0.0, 0.0, 0.0, 1.0)

    def to_dict(self) -> dict[str, float]:
        return {"rotation_deg": self.rotation_deg, "shift_x": self.shift_x, "shift_y": self.shift_y,
                "scale": self.scale}


@dataclass(frozen=True)
class Placement:
    """The affine map of one chart geometry, posed, into a ``width`` x ``height`` frame (module docstring)."""

    geometry: ChartGeometry
    width: int
    height: int
    margin: float
    pose: ChartPose

    @property
    def fitted_scale(self) -> float:
        """Frame pixels per chart unit before the pose's own scale (the body fitted inside the margins)."""
        w, h = self.geometry.size
        return min(self.width * (1 - 2 * self.margin) / w, self.height * (1 - 2 * self.margin) / h)

    @property
    def scale(self) -> float:
        return self.fitted_scale * self.pose.scale

    def matrix(self) -> np.ndarray:
        """3 x 3: homogeneous chart (x, y, 1) -> frame (x, y, 1)."""
        a = math.radians(self.pose.rotation_deg)
        s = self.scale
        rot = s * np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
        w, h = self.geometry.size
        centre = np.array([self.width / 2 + self.pose.shift_x * self.width,
                           self.height / 2 + self.pose.shift_y * self.height])
        m = np.eye(3)
        m[:2, :2] = rot
        m[:2, 2] = centre - rot @ np.array([w / 2, h / 2])
        return m

    def to_frame(self, xy: np.ndarray) -> np.ndarray:
        """(n, 2) chart x, y -> frame x, y."""
        m = self.matrix()
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        return xy @ m[:2, :2].T + m[:2, 2]

    def classify_pixels(self, row_idx: np.ndarray, col_idx: np.ndarray) -> np.ndarray:
        """(len(row_idx), len(col_idx)) the geometry's class (patch index, SURROUND, OUTSIDE) at every pixel's
        centre: the chart coordinates of the pixel centres, then ChartGeometry.classify."""
        inv = np.linalg.inv(self.matrix())
        px = np.asarray(col_idx, dtype=float)[None, :] + 0.5
        py = np.asarray(row_idx, dtype=float)[:, None] + 0.5
        x = inv[0, 0] * px + inv[0, 1] * py + inv[0, 2]
        y = inv[1, 0] * px + inv[1, 1] * py + inv[1, 2]
        return self.geometry.classify(x, y)

    def inside(self, row_idx: np.ndarray, col_idx: np.ndarray, box: tuple[float, float, float, float]) -> np.ndarray:
        """Boolean per pixel: its centre inside ``box`` (x0, y0, x1, y1, chart units)."""
        inv = np.linalg.inv(self.matrix())
        px = np.asarray(col_idx, dtype=float)[None, :] + 0.5
        py = np.asarray(row_idx, dtype=float)[:, None] + 0.5
        x = inv[0, 0] * px + inv[0, 1] * py + inv[0, 2]
        y = inv[1, 0] * px + inv[1, 1] * py + inv[1, 2]
        return (x >= box[0]) & (x < box[2]) & (y >= box[1]) & (y < box[3])

    def corners(self) -> list[tuple[float, float]]:
        """(row, col) of the patch area's corners (the outer edges of the outermost patches) in the frame: the
        chart's top-left, top-right, bottom-right, bottom-left, wherever the pose turned them."""
        x0, y0, x1, y1 = self.geometry.patch_area
        xy = self.to_frame(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
        return [(float(y), float(x)) for x, y in xy]

    def patch_boxes(self) -> list[tuple[int, int, int, int]]:
        """(row0, row1, col0, col1), half-open, per patch: an upright box inside the (possibly turned) patch around
        its centre, for metering (every pixel of it on the patch)."""
        a = math.radians(self.pose.rotation_deg)
        c, s = abs(math.cos(a)), abs(math.sin(a))
        centres = self.to_frame(self.geometry.centres())
        b = self.geometry.boxes
        out = []
        for (cx, cy), (x0, y0, x1, y1) in zip(centres, b, strict=True):
            w, h = (x1 - x0) * self.scale / 2, (y1 - y0) * self.scale / 2      # half sizes in pixels
            k = min(w / (w * c + h * s), h / (w * s + h * c))                    # the inscribed upright box
            hx, hy = max(w * k - 0.5, 0.5), max(h * k - 0.5, 0.5)
            out.append((int(math.ceil(cy - hy)), int(math.floor(cy + hy)),
                        int(math.ceil(cx - hx)), int(math.floor(cx + hx))))
        return out

    def nd_box(self) -> tuple[float, float, float, float]:
        """The ND filter's rectangle (chart units): the first block's left ``cols // 2`` columns, over its rows,
        up to the middle of the gap after the last covered column (drivers.virtual.scene)."""
        b = self.geometry.blocks[0]
        half = b.cols // 2
        gap_x = b.step[0] - b.size[0]
        x1 = b.origin[0] + (half - 1) * b.step[0] + b.size[0] + gap_x / 2
        return b.origin[0], b.origin[1], x1, b.origin[1] + (b.rows - 1) * b.step[1] + b.size[1]

    def min_patch_px(self) -> float:
        """The smallest patch side in frame pixels."""
        return self.scale * min(min(b.size) for b in self.geometry.blocks)
