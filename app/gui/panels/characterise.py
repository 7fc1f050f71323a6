"""Characterise: the camera response function and exposure-time linearity (app.sequences.crf_sweep.CrfSweep on the
open gate; app.processing.crf_analysis finds the linear limit and flags exposure times that depart from the line)."""
from __future__ import annotations

import logging
from typing import Optional

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QComboBox, QDoubleSpinBox, QFormLayout, QGroupBox, QLabel, QLineEdit,
                               QSplitter, QVBoxLayout, QWidget)

from app.gui.context import AppContext
from app.gui.sequence_view import SequenceView
from app.gui.widgets import plot_widget
from app.sequences.crf_sweep import CrfSweep
from app.sequences.shooter import SafetySettings, Shooter
from app.workflow.vocabulary import format_exposure as format_shutter
from simulation.lightsource import LightSource

log = logging.getLogger(__name__)

LEVEL_PENS = ("#1565c0", "#2e7d32", "#ef6c00", "#6a1b9a", "#00838f")


class CharacterisePanel(QWidget):
    title = "Characterise"

    def __init__(self, ctx: AppContext, parent: Optional[QWidget] = None):
        super().__init__(parent)
        self.ctx = ctx
        self.lab = ctx.lab
        self.sweep: Optional[CrfSweep] = None

        box = QGroupBox("CRF and exposure-time linearity")
        form = QFormLayout(box)
        self.light = QComboBox()
        self.light.addItems(["(1, 6, 8) full", "current Light source levels"])
        self.light.setToolTip("The light of the open-gate sweep (Table 7.1's first light, or the sliders).")
        self.levels = QLineEdit(ctx.get("crf/levels", "1, 0.25, 0.0625", str))
        self.levels.setToolTip("Light levels: each repeats the sweep dimmer so every exposure time gets a point "
                               "inside the linear range (appendix A.2.1).")
        self.min_t = QDoubleSpinBox()
        self.min_t.setDecimals(5)
        self.min_t.setRange(1 / 8000, 10.0)
        self.min_t.setValue(ctx.get("crf/min_exposure_s", 1 / 4000, float))
        self.min_t.setToolTip("Shortest exposure of the sweep (s).")
        self.max_t = QDoubleSpinBox()
        self.max_t.setDecimals(4)
        self.max_t.setRange(1 / 8000, 10.0)
        self.max_t.setValue(ctx.get("crf/max_exposure_s", 1.0, float))
        self.max_t.setToolTip("Longest exposure of the sweep (s); the light-on limit of 10 s caps it anyway.")
        form.addRow("Light", self.light)
        form.addRow("Levels", self.levels)
        form.addRow("Shortest exposure (s)", self.min_t)
        form.addRow("Longest exposure (s)", self.max_t)
        self.levels.editingFinished.connect(lambda: (ctx.set("crf/levels", self.levels.text()), self.update_plan()))
        self.min_t.valueChanged.connect(lambda v: (ctx.set("crf/min_exposure_s", v), self.update_plan()))
        self.max_t.valueChanged.connect(lambda v: (ctx.set("crf/max_exposure_s", v), self.update_plan()))
        self.result_label = QLabel("")
        self.result_label.setWordWrap(True)
        self.result_label.setTextFormat(Qt.RichText)

        self.view = SequenceView(ctx)
        self.view.start_button.clicked.connect(self.start)
        self.view.finished.connect(self._finished)
        self.view.event.connect(self._event)

        left = QWidget()
        ll = QVBoxLayout(left)
        ll.addWidget(box)
        ll.addWidget(self.view, 1)
        ll.addWidget(self.result_label)

        self.crf_plot = plot_widget("camera response", "exposure time (s)", "mean green above black (DN)",
                                    "Signal against exposure time per light level; red: exposure times flagged as "
                                    "departing from linearity; dashed: the linear limit.")
        self.crf_plot.setLogMode(x=True, y=True)
        self.crf_plot.addLegend(offset=(10, 10))
        self.res_plot = plot_widget("linearity", "exposure time (s)", "deviation from the line (%)",
                                    "How far each point lies from the straight line through the origin; shutter "
                                    "'bumps' stand out (appendix A). Red rings: flagged exposure times; dotted "
                                    "lines: changepoints found in the residuals.")
        self.res_plot.setLogMode(x=True, y=False)
        self.res_plot.addLegend(offset=(10, 10))
        plots = QSplitter(Qt.Vertical)
        plots.addWidget(self.crf_plot)
        plots.addWidget(self.res_plot)
        split = QSplitter(Qt.Horizontal)
        split.addWidget(left)
        split.addWidget(plots)
        split.setStretchFactor(1, 1)
        QVBoxLayout(self).addWidget(split)
        self._live: dict[float, list[tuple[float, float]]] = {}
        self._live_curves: dict[float, pg.PlotDataItem] = {}
        for sig in (self.lab.cameraChanged, self.lab.sphereChanged, self.lab.sessionChanged):
            sig.connect(self.update_plan)
        self.update_plan()

    # ------------------------------------------------------------------ building
    def level_values(self) -> list[float]:
        try:
            values = [float(x) for x in self.levels.text().replace(";", ",").split(",") if x.strip()]
        except ValueError:
            raise ValueError(f"levels {self.levels.text()!r}: expected numbers between 0 and 1, like 1, 0.25")
        if not values or any(not 0 < v <= 1 for v in values):
            raise ValueError(f"levels {self.levels.text()!r}: expected numbers between 0 and 1, like 1, 0.25")
        return values

    def chosen_light(self) -> LightSource:
        if self.light.currentIndex() == 1:
            panel = self.ctx.shared.get("light_panel")
            if panel is not None:
                light = panel.current_light("CRF light")
                if not light.is_dark:
                    return light
            raise ValueError("the Light source sliders are all at 0: set a light there first")
        return LightSource((1, 6, 8), name="CRF light")

    def build(self, shooter) -> CrfSweep:
        cam = self.lab.camera
        speeds = cam.shutter_speeds() if cam is not None else None
        exposures = [t for t in (speeds or _NIKON_THIRDS) if self.min_t.value() * 0.999 <= t <= self.max_t.value()]
        return CrfSweep(shooter, self.chosen_light(), levels=self.level_values(), exposures=exposures,
                        min_exposure_s=self.min_t.value())

    def update_plan(self) -> None:
        if self.view.running:
            return
        try:
            seq = self.build(_PlanShooter(self.ctx.get("capture/settle_s", 0.2, float)))
        except ValueError as exc:
            self.view.clear_plan(str(exc))
            return
        self.view.settle_s = self.ctx.get("capture/settle_s", 0.2, float)
        self.view.show_plan(seq.plan(), "CRF sweep (stops early once a level clips)")
        ready = self.lab.camera is not None and self.lab.sphere is not None and self.lab.session is not None
        self.view.start_button.setEnabled(ready)
        if not ready:
            self.view.message.setText("needs the sphere, the camera and a session (Calibrate & capture)")

    # ------------------------------------------------------------------ running
    def start(self) -> None:
        lab = self.lab
        try:
            if lab.camera is None or lab.sphere is None or lab.session is None:
                raise ValueError("connect the sphere and the camera and start a session first")
            stand = lab.virtual_lab.place if lab.virtual_lab is not None else None
            shooter = Shooter(lab.camera, lab.sphere, lab.session, stand=stand,
                              safety=SafetySettings(settle_s=self.ctx.get("capture/settle_s", 0.2, float)))
            self.sweep = self.build(shooter)
        except ValueError as exc:
            self.ctx.errors.report("CRF sweep", exc)
            return
        self._live = {}
        for item in list(self._live_curves.values()):
            self.crf_plot.removeItem(item)
        self._live_curves = {}
        self.crf_plot.clear()
        self.res_plot.clear()
        self.result_label.setText("")
        self.view.start(self.sweep)

    def cancel_running(self) -> None:
        self.view.cancel()

    def shutdown(self) -> None:
        self.view.cancel()

    def _event(self, ev) -> None:
        if ev.kind != "frame" or "signal_dn" not in ev.data:
            return
        lv = float(ev.data["level"])
        self._live.setdefault(lv, []).append((float(ev.data["exposure_s"]), max(float(ev.data["signal_dn"]), 0.1)))
        t, s = zip(*self._live[lv])
        if lv not in self._live_curves:
            pen = LEVEL_PENS[len(self._live_curves) % len(LEVEL_PENS)]
            self._live_curves[lv] = self.crf_plot.plot(t, s, pen=pg.mkPen(pen, width=2), symbol="o", symbolSize=4,
                                                       symbolBrush=pen, name=f"level {lv:g}")
        else:
            self._live_curves[lv].setData(t, s)

    def _finished(self, seq, outcome: str) -> None:
        self.update_plan()
        if outcome != "done" or not isinstance(seq, CrfSweep):
            return
        self.show_summary(seq)
        self.ctx.bus.crfReady.emit(seq.summary())
        self.ctx.bus.sessionUpdated.emit()

    def show_summary(self, seq: CrfSweep) -> None:
        summary = seq.summary()
        self.res_plot.clear()
        for i, (lv, res) in enumerate(seq.results.items()):
            pen = LEVEL_PENS[i % len(LEVEL_PENS)]
            t = np.asarray(res.exposures)
            rel = 100 * np.asarray(res.residuals)
            inside = np.asarray(res.signal_dn) <= res.linear_limit_dn
            self.res_plot.plot(t[inside], rel[inside], pen=pg.mkPen(pen, width=1), symbol="o", symbolSize=5,
                               symbolBrush=pen, name=f"level {lv:g}")
            for cp in res.changepoints:                         # where the residuals change level (PELT)
                self.res_plot.addItem(pg.InfiniteLine(np.log10(cp), angle=90,
                                                      pen=pg.mkPen(pen, width=1, style=Qt.DotLine)))
            flagged = np.isin(t, res.flagged)
            if flagged.any():
                self.res_plot.plot(t[flagged], rel[flagged], pen=None, symbol="o", symbolSize=12,
                                   symbolBrush=None, symbolPen=pg.mkPen("#c62828", width=2))
                s = np.asarray(res.signal_dn)
                self.crf_plot.plot(t[flagged], np.maximum(s[flagged], 0.1), pen=None, symbol="o", symbolSize=12,
                                   symbolBrush=None, symbolPen=pg.mkPen("#c62828", width=2))
        limit = summary.get("linear_limit_dn")
        if limit:
            self.crf_plot.addItem(pg.InfiniteLine(np.log10(limit), angle=0,
                                                  pen=pg.mkPen("#ef6c00", width=2, style=Qt.DashLine)))
        flagged = summary.get("flagged_exposures") or []
        self.result_label.setText(
            f"linear limit <b>{limit:.0f} DN</b> (median over the levels); " if limit else "linear limit: not found; ")
        self.result_label.setText(self.result_label.text() + (
            "exposure times departing from linearity: <b>" + ", ".join(format_shutter(t) for t in flagged) + "</b>"
            if flagged else "no exposure time departs from linearity"))


_NIKON_THIRDS = [1 / 4000, 1 / 2000, 1 / 1000, 1 / 500, 1 / 250, 1 / 125, 1 / 60, 1 / 30, 1 / 15, 1 / 8, 1 / 4,
                 1 / 2, 1.0]


class _PlanShooter:
    def __init__(self, settle_s: float):
        self.safety = SafetySettings(settle_s=settle_s)
        self.camera = None
