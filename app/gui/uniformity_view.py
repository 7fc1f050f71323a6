"""The open gate's light field from the flats of one light, as percent of its mean over a block grid
(app.workflow.frame_checks.flat_uniformity, the illuminance non-uniformity metric of app.processing.quality):
what the flat field divides out, so a hot spot or a vignetted corner is seen before the targets are shot."""
from __future__ import annotations

import logging

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QComboBox, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from app.gui.context import AppContext
from app.gui.units import shutter, with_unit
from app.gui.widgets import image_widget
from app.workflow.frame_checks import UniformityMap, flat_uniformity

log = logging.getLogger(__name__)

SPAN_PCT = 10.0        # the colour scale: 100 +- this many percent


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
        self.labels: list[pg.TextItem] = []
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
        for t in self.labels:
            self.box.removeItem(t)
        self.labels = []
        rows, cols = m.percent.shape
        for r in range(rows):
            for c in range(cols):
                t = pg.TextItem(f"{m.percent[r, c]:.0f}", color="k", anchor=(0.5, 0.5))
                t.setPos(c + 0.5, r + 0.5)
                self.box.addItem(t)
                self.labels.append(t)
        self.box.autoRange()
        lo, hi = float(np.nanmin(m.percent)), float(np.nanmax(m.percent))
        self.info.setText(f"{m.light}, {m.frames} flat(s) at {shutter(m.exposure_s)}: blocks from "
                          f"{with_unit(f'{lo:.1f}', '%')} to {with_unit(f'{hi:.1f}', '%')} of the mean; range "
                          f"{with_unit(f'{m.range_pct:.1f}', '%')} ((max - min) / mean, worst channel). This is "
                          "the light field the flat field divides out; the report grades what is left after it.")
