"""The open gate's light field from the flats of one light, as percent of its mean over a block grid
(app.workflow.calibration.frame_checks.flat_uniformity, the illuminance non-uniformity metric of
app.processing.quality):
what the flat field divides out, so a hot spot or a vignetted corner is seen before the targets are shot."""
from __future__ import annotations

import logging

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QColor
from PySide6.QtWidgets import QComboBox, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.units import shutter, with_unit
from dualrgb.app.gui.widgets import image_widget
from dualrgb.app.workflow.calibration.frame_checks import UniformityMap, flat_uniformity

log = logging.getLogger(__name__)

SPAN_PCT = 10.0        # the colour scale: 100 +- this many percent


class CellLabels(pg.GraphicsObject):
    """Texts centred on the cells of a rows x cols grid (cell (r, c) spans c..c+1, r..r+1 in the view), in screen
    pixels whatever the zoom, painted by this one item. A pg.TextItem per cell cost the GUI thread about a
    millisecond each to add (a block map: over 100 ms of stall); one item draws them all in one paint."""

    def __init__(self, color: str = "k"):
        super().__init__()
        self.texts: list[list[str]] = []
        self.color = QColor(color)

    def set_texts(self, texts: list[list[str]]) -> None:
        self.prepareGeometryChange()
        self.texts = [list(row) for row in texts]
        self.update()

    def boundingRect(self) -> QRectF:
        return QRectF(0.0, 0.0, float(max((len(r) for r in self.texts), default=0)), float(len(self.texts)))

    def paint(self, painter, *_args) -> None:
        to_screen = painter.transform()
        painter.resetTransform()                   # text in screen pixels, placed by the view's transform
        painter.setPen(self.color)
        for r, row in enumerate(self.texts):
            for c, text in enumerate(row):
                at = to_screen.map(QPointF(c + 0.5, r + 0.5))
                painter.drawText(QRectF(at.x() - 40.0, at.y() - 12.0, 80.0, 24.0), Qt.AlignmentFlag.AlignCenter, text)


class UniformityView(QWidget):
    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.map: UniformityMap | None = None
        self.light = QComboBox()
        self.light.setToolTip("Whose flats to show.")
        self.refresh_button = QPushButton("Show")
        self.refresh_button.setToolTip("Average this light's open-gate flats and show each block as percent of "
                                       "the mean.")
        self.refresh_button.clicked.connect(self.refresh)
        self.widget, self.image, self.box = image_widget("Each block of the open gate as percent of the mean: "
                                                         f"blue {100 - SPAN_PCT:g} %, white 100 %, red "
                                                         f"{100 + SPAN_PCT:g} % or more.")
        self.widget.setBackground("w")
        self.cmap = pg.colormap.get("CET-D1")
        self.labels = CellLabels()            # each block's percent, centred on it
        self.box.addItem(self.labels)
        self.info = QLabel("shoot open-gate flats, then Show")
        self.info.setWordWrap(True)
        row = QHBoxLayout()
        row.addWidget(QLabel("Light"))
        row.addWidget(self.light, 1)
        row.addWidget(self.refresh_button)
        lay = QVBoxLayout(self)
        lay.addLayout(row)
        lay.addWidget(self.widget, 1)
        lay.addWidget(self.info)
        ctx.workspace.lightsChanged.connect(self._fill_lights)
        self._fill_lights()

    def _fill_lights(self) -> None:
        current = self.light.currentText()
        self.light.clear()
        self.light.addItems([nl.name for nl in self.ctx.workspace.lights])
        if current:
            self.light.setCurrentText(current)

    def refresh(self) -> None:
        session, name = self.ctx.lab.session, self.light.currentText()
        if session is None or not name:
            return
        self.ctx.runner.submit(lambda: flat_uniformity(session, name), pool="compute", name="flat uniformity",
                               on_result=self.show_map,
                               on_error=lambda exc: self.info.setText(f"no uniformity map: {exc}"))

    def show_map(self, m: UniformityMap) -> None:
        self.map = m
        lut = self.cmap.getLookupTable(0.0, 1.0, 256)
        self.image.setImage(m.percent, levels=(100 - SPAN_PCT, 100 + SPAN_PCT), lut=lut, autoLevels=False)
        self.labels.set_texts([[f"{v:.0f}" for v in row] for row in m.percent])
        self.box.autoRange()
        lo, hi = float(np.nanmin(m.percent)), float(np.nanmax(m.percent))
        self.info.setText(f"{m.light}, {m.frames} flat(s) at {shutter(m.exposure_s)}: blocks from "
                          f"{with_unit(f'{lo:.1f}', '%')} to {with_unit(f'{hi:.1f}', '%')} of the mean; range "
                          f"{with_unit(f'{m.range_pct:.1f}', '%')} ((max - min) / mean, worst channel). This is "
                          "the light field the flat field divides out; the report grades what is left after it.")
