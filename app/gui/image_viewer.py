"""The image viewer (issue 42): a delivered master or a captured frame at full resolution - Fit, 100 %, 200 %,
400 % (one image pixel on 1, 2, 4 screen pixels), pan by dragging, the wheel zooms about the pointer - with a
clipping (red) and under-exposure (blue) overlay and the values of the pixel under the pointer (camera RGB, XYZ,
L*a*b*: app.gui.viewer_model). Loading runs in the compute pool; only drawing happens here (pyqtgraph ImageItem:
the picture is handed over once, zooming and panning only move the view)."""
from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QPointF
from PySide6.QtWidgets import QCheckBox, QFileDialog, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.units import percent
from dualrgb.app.gui.viewer_model import ZOOMS, ViewImage, load_frame, load_master

log = logging.getLogger(__name__)

RAW_FILTER = "Raw frames (*.dng *.DNG *.nef *.NEF);;Sidecars of delivered originals (*.json);;All files (*)"


class ImageViewer(QWidget):
    """A picture with zoom, pan, the clipping overlay and the pixel's values."""

    def __init__(self, ctx: AppContext, parent: QWidget | None = None, *, follow_frames: bool = False):
        super().__init__(parent)
        self.ctx = ctx
        if follow_frames:                                    # the session's newest frame, when it is saved
            ctx.bus.frameSaved.connect(self.show_last_frame)
        self.picture: ViewImage | None = None
        self.pending: tuple[Callable[[], ViewImage], str] | None = None     # loaded when the viewer is shown
        self.source: Path | None = None
        self.graphics = pg.GraphicsLayoutWidget()
        self.graphics.setBackground("#202020")
        self.box = self.graphics.addViewBox(lockAspect=True, invertY=True, enableMenu=False)
        self.image = pg.ImageItem(axisOrder="row-major")
        self.overlay = pg.ImageItem(axisOrder="row-major")
        self.box.addItem(self.image)
        self.box.addItem(self.overlay)
        self.graphics.scene().sigMouseMoved.connect(self._moved)
        self.title = QLabel("nothing shown: choose a delivered original, or Open…")
        self.title.setWordWrap(True)
        self.values = QLabel("")
        self.values.setWordWrap(True)
        self.values.setToolTip("The values of the pixel under the pointer.")
        self.zoom_label = QLabel("")
        self.clipping = QCheckBox("clipping")
        self.clipping.setChecked(True)
        self.clipping.setToolTip("Red: clipped (nothing brighter can be told apart); blue: under-exposed (a frame) "
                                 "or near black, L* < 3 (a delivered master).")
        self.clipping.toggled.connect(self.overlay.setVisible)
        self.zoom_buttons: dict[str, QPushButton] = {}
        self._build()

    def _build(self) -> None:
        row = QHBoxLayout()
        for name, zoom in (("Fit", None), *((percent(z, 0), z) for z in ZOOMS)):
            button = QPushButton(name)
            button.setToolTip("Fit the picture" if zoom is None else f"One image pixel on {zoom:g} screen pixels")
            button.clicked.connect(lambda _=False, z=zoom: self.fit() if z is None else self.set_zoom(z))
            row.addWidget(button)
            self.zoom_buttons[name] = button
        row.addWidget(self.clipping)
        self.open_button = QPushButton("Open…")
        self.open_button.setToolTip("Show a raw frame of the session, or a delivered original's sidecar.")
        self.open_button.clicked.connect(self._ask_open)
        row.addWidget(self.open_button)
        row.addStretch(1)
        row.addWidget(self.zoom_label)
        lay = QVBoxLayout(self)
        lay.addWidget(self.title)
        lay.addLayout(row)
        lay.addWidget(self.graphics, 1)
        lay.addWidget(self.values)

    # ------------------------------------------------------------------ loading
    def show_master(self, sidecar: Path, *, again: bool = False) -> None:
        """The delivered master of ``sidecar``; ``again``: loaded again although it is the one shown (delivered
        again in place)."""
        if again:
            self.source = None
        self._load(Path(sidecar), lambda: load_master(sidecar), f"delivered original {Path(sidecar).parent.name}")

    def show_frame(self, path: Path) -> None:
        self._load(Path(path), lambda: load_frame(path), f"frame {Path(path).name}")

    def show_last_frame(self) -> None:
        session = self.ctx.lab.session
        entries = session.entries() if session is not None else []
        if session is not None and entries:
            self.show_frame(session.file_path(entries[-1]))

    def _load(self, source: Path, work: Callable[[], ViewImage], what: str) -> None:
        """Load ``work`` now when the viewer is shown, else when it is (a full-resolution master costs a second)."""
        if source == self.source:
            return
        self.source = source
        self.pending = (work, what)
        if self.isVisible():
            self._load_pending()

    def showEvent(self, event) -> None:
        super().showEvent(event)
        self._load_pending()

    def _load_pending(self) -> None:
        if self.pending is None:
            return
        work, what = self.pending
        self.pending = None
        self.title.setText(f"loading {what} …")
        self.ctx.runner.submit(work, pool="compute", name=f"view {what}", on_result=self.show_picture,
                               on_error=lambda exc: self._failed(what, exc))

    def _failed(self, what: str, exc: BaseException) -> None:
        self.title.setText(f"{what} cannot be shown")
        self.ctx.errors.report("Show a picture", f"{what}: {exc}")

    def _ask_open(self) -> None:
        session = self.ctx.lab.session
        start = str(session.path) if session is not None else str(self.ctx.captures_dir)
        path, _ = QFileDialog.getOpenFileName(self, "Show a picture", start, RAW_FILTER)
        if path:
            (self.show_master if path.lower().endswith(".json") else self.show_frame)(Path(path))

    def show_picture(self, picture: ViewImage) -> None:
        """Draw ``picture`` (on the GUI thread, from the worker's result) and fit it."""
        self.picture = picture
        self.image.setImage(picture.display, levels=(0, 255), autoLevels=False)
        self.overlay.setImage(picture.overlay(), levels=(0, 255), autoLevels=False)
        clipped, under = picture.fractions()
        self.title.setText(f"{picture.title}; clipped {percent(clipped, 2)}, {picture.under_name} {percent(under, 2)}")
        self.fit()

    # ------------------------------------------------------------------ zoom and pan
    def fit(self) -> None:
        if self.picture is not None:
            h, w = self.picture.shape
            self.box.setRange(xRange=(0, w), yRange=(0, h), padding=0)
        self._show_zoom()

    def zoom(self) -> float:
        """Screen pixels per image pixel now."""
        (x0, x1), _ = self.box.viewRange()
        return float(self.box.width()) / max(x1 - x0, 1e-9)

    def set_zoom(self, zoom: float, centre: QPointF | None = None) -> None:
        """One image pixel on ``zoom`` screen pixels, about ``centre`` (image pixels; default: the view's)."""
        (x0, x1), (y0, y1) = self.box.viewRange()
        cx, cy = (centre.x(), centre.y()) if centre is not None else ((x0 + x1) / 2, (y0 + y1) / 2)
        w, h = float(self.box.width()) / zoom, float(self.box.height()) / zoom
        self.box.setRange(xRange=(cx - w / 2, cx + w / 2), yRange=(cy - h / 2, cy + h / 2), padding=0)
        self._show_zoom()

    def _show_zoom(self) -> None:
        self.zoom_label.setText(percent(self.zoom(), 0) if self.picture is not None else "")

    def _moved(self, pos: QPointF) -> None:
        if self.picture is None or not self.box.sceneBoundingRect().contains(pos):
            return
        p = self.box.mapSceneToView(pos)
        self.values.setText(self.picture.values(int(np.floor(p.x())), int(np.floor(p.y()))))
        self._show_zoom()
