"""Focus aid for live view (issue 30): a zoom box on the live picture shown at 100, 200 or 400 % (one live-view
pixel on 1, 2 or 4 screen pixels, issue 42) and a focus measure of that region plotted over time.

The measure is Tenengrad (Krotkov 1987; Pertuz et al. 2013 compare it with 35 others): the mean squared Sobel
gradient magnitude of the region's grey levels, divided by the region's mean squared (so a brighter light or a
longer exposure does not look like sharper focus). It rises as the picture gets sharper; its absolute value
depends on the subject, so the plot shows its course and the best value since the region was placed. It is
computed on the GUI thread because the region is small (at most :data:`MAX_BOX` pixels a side: well under a
millisecond with scipy.ndimage's Sobel), never on the whole frame.

"100 %" is of the live-view picture the camera sends (the virtual camera's preview, a D610's 640 x 424 live view),
not of the sensor: for focus at the sensor's pixels take a picture (Camera) and look at it at full size.
"""
from __future__ import annotations

import logging
import time
from collections import deque

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import QComboBox, QLabel, QScrollArea, QVBoxLayout, QWidget
from scipy import ndimage

from dualrgb.app.gui.live_aids import MAGNIFICATIONS, magnified
from dualrgb.app.gui.widgets import plot_widget

log = logging.getLogger(__name__)

MAX_BOX = 256                    # the zoom box's largest side, live-view pixels
DEFAULT_BOX = 96
HISTORY = 240                    # focus values kept for the plot (a minute at four live frames a second)


def grey(frame: np.ndarray) -> np.ndarray:
    """(H, W) or (H, W, C) -> (H, W) float64 grey (the channels' mean)."""
    a = np.asarray(frame, dtype=np.float64)
    return a.mean(axis=2) if a.ndim == 3 else a


def tenengrad(frame: np.ndarray) -> float:
    """Tenengrad focus measure of ``frame``: mean(Gx^2 + Gy^2) of 3x3 Sobel gradients over the mean grey level
    squared (0 for a flat or black region). Larger is sharper."""
    g = grey(frame)
    if g.size == 0 or min(g.shape) < 3:
        return 0.0
    energy = float(np.mean(ndimage.sobel(g, axis=0) ** 2 + ndimage.sobel(g, axis=1) ** 2))
    mean = float(g.mean())
    return energy / (mean * mean) if mean > 1e-9 else 0.0


def clamp_box(x: int, y: int, w: int, h: int, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """The box (x, y, w, h) inside a frame of ``shape`` (H, W, ...), sides at most :data:`MAX_BOX`, at least 3."""
    height, width = int(shape[0]), int(shape[1])
    w, h = max(3, min(int(w), MAX_BOX, width)), max(3, min(int(h), MAX_BOX, height))
    x, y = min(max(int(x), 0), max(width - w, 0)), min(max(int(y), 0), max(height - h, 0))
    return x, y, w, h


def brightened(frame: np.ndarray, most: float = 32.0) -> tuple[np.ndarray, float]:
    """A dim uint8 live frame stretched for the screen (its 99.5th percentile to white, the gain at most
    ``most``, never below 1): (frame, gain). For looking only: nothing measured comes from it (the focus measure
    does not depend on the scale, the histogram is the camera's)."""
    top = float(np.percentile(frame, 99.5)) if frame.size else 0.0
    gain = min(max(255.0 / max(top, 1.0), 1.0), most)
    if gain <= 1.0:
        return frame, 1.0
    return np.clip(frame.astype(np.float32) * gain + 0.5, 0, 255).astype(np.uint8), gain


def to_pixmap(crop: np.ndarray) -> QPixmap:
    """A uint8 (H, W) or (H, W, 3) crop as a pixmap of the same size (nothing scaled)."""
    a = np.ascontiguousarray(np.clip(crop, 0, 255).astype(np.uint8))
    if a.ndim == 2:
        a = np.ascontiguousarray(np.repeat(a[:, :, None], 3, axis=2))
    h, w = a.shape[:2]
    image = QImage(a.data, w, h, 3 * w, QImage.Format.Format_RGB888)
    return QPixmap.fromImage(image.copy())        # copy: the array goes away


class FocusAid(QWidget):
    """The zoom box at 100 % and the focus plot; the Camera panel places the box on its live picture (a
    pyqtgraph RectROI) and feeds every live frame to :meth:`feed`."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.box: tuple[int, int, int, int] | None = None       # x, y, w, h in live-view pixels; None: centred
        self.values: deque[float] = deque(maxlen=HISTORY)
        self.times: deque[float] = deque(maxlen=HISTORY)
        self.best = 0.0
        self._t0 = time.monotonic()
        self.magnification = QComboBox()
        for m in MAGNIFICATIONS:
            self.magnification.addItem(f"{100 * m}\u00a0%", m)
        self.magnification.setToolTip("The zoom box's magnification: one live-view pixel on 1, 2 or 4 screen "
                                      "pixels (repeated, nothing interpolated).")
        self.zoom = QLabel("live view off")
        self.zoom.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.zoom.setToolTip("The zoom box at 100 %: one screen pixel per live-view pixel. Drag the box on the live "
                             "picture to choose the region.")
        scroll = QScrollArea()
        scroll.setWidget(self.zoom)
        scroll.setWidgetResizable(True)
        scroll.setMinimumHeight(120)
        self.plot = plot_widget(bottom="time (s)", left="focus",
                                tooltip="Tenengrad of the zoom box (module app.gui.focus_aid): higher is sharper; "
                                        "turn the focus ring towards the peak.")
        self.curve = self.plot.plot(pen="#1565c0")
        self.label = QLabel("")
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.magnification)
        layout.addWidget(scroll, 2)
        layout.addWidget(self.label)
        layout.addWidget(self.plot, 2)

    def attach(self, viewbox: object) -> None:
        """Put the zoom box on the live picture's ViewBox (a pyqtgraph RectROI the technician drags and
        resizes); it shows from the first live frame."""
        import pyqtgraph as pg

        self.roi = pg.RectROI([0, 0], [DEFAULT_BOX, DEFAULT_BOX], pen=pg.mkPen("#ffeb3b", width=2),
                              maxBounds=None)
        self.roi.setVisible(False)
        viewbox.addItem(self.roi)                                  # type: ignore[attr-defined]
        self.roi.sigRegionChangeFinished.connect(
            lambda r: self.set_box(*r.pos(), *r.size()))

    def set_box(self, x: float, y: float, w: float, h: float) -> None:
        """A new region: the plot starts over (a value is comparable only with values of the same region)."""
        box = (int(round(x)), int(round(y)), int(round(w)), int(round(h)))
        if box != self.box:
            self.box = box
            self.reset()

    def reset(self) -> None:
        self.values.clear()
        self.times.clear()
        self.best = 0.0
        self._t0 = time.monotonic()
        self.curve.setData([], [])

    def region(self, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
        if self.box is None:
            h, w = int(shape[0]), int(shape[1])
            side = min(DEFAULT_BOX, w, h)
            return clamp_box((w - side) // 2, (h - side) // 2, side, side, shape)
        return clamp_box(*self.box, shape)

    def feed(self, frame: np.ndarray, shown: np.ndarray | None = None) -> float:
        """One live frame: show its zoom box at 100 % (of ``shown``, the frame as displayed, when given), add the
        box's focus value (of ``frame``) to the plot; returns it."""
        x, y, w, h = self.region(frame.shape)
        roi = getattr(self, "roi", None)
        if roi is not None and not roi.isVisible():               # first frame: show the box where it measures
            roi.setPos((x, y), finish=False)
            roi.setSize((w, h), finish=False)
            roi.setVisible(True)
        crop = frame[y:y + h, x:x + w]
        value = tenengrad(crop)
        factor = int(self.magnification.currentData() or 1)
        self.zoom.setPixmap(to_pixmap(magnified(crop if shown is None else shown[y:y + h, x:x + w], factor)))
        self.values.append(value)
        self.times.append(time.monotonic() - self._t0)
        self.best = max(self.best, value)
        self.curve.setData(list(self.times), list(self.values))
        self.label.setText(f"focus {value:.4g} (best {self.best:.4g}) in {w}x{h} px at ({x}, {y})")
        return value
