"""Characterise: the camera response function and exposure-time linearity (app.sequences.crf_sweep.CrfSweep on the
open gate; app.processing.crf_analysis flags exposure times that depart from the line). The plots are on log
axes labelled as people read them (shutter times as 1/250 s, DN in thousands); the one linear limit the
processing uses is drawn, and the knee measured here is reported beside it."""
from __future__ import annotations

import logging
import math

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QLabel,
    QLineEdit,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.sequence_view import SequenceView
from dualrgb.app.gui.units import dn, light_pct, shutter, shutters
from dualrgb.app.gui.viewmodel import LINEAR_LIMIT_DN, light_from_levels
from dualrgb.app.gui.widgets import plot_widget, side_by_side
from dualrgb.app.sequences.crf_sweep import CrfSweep
from dualrgb.app.workflow.stand.copystand import StandSettings, plans_only
from dualrgb.app.workflow.stand.defaults import SETTLE_S
from dualrgb.app.workflow.stand.plans import StandPlanner
from dualrgb.core.vocabulary import EventKind
from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)

LEVEL_PENS = ("#1565c0", "#2e7d32", "#ef6c00", "#6a1b9a", "#00838f")
CRF_LIGHT = LightSource((1, 6, 8), name="CRF light")            # Table 7.1's first light, every LED full
TIME_TICKS = (1 / 4000, 1 / 1000, 1 / 250, 1 / 60, 1 / 15, 1 / 4, 1.0, 4.0)   # two stops apart: never overlap
DN_TICKS = (1, 10, 100, 1000, 10000)


def time_ticks() -> list[list[tuple[float, str]]]:
    """Major ticks of a log10 exposure-time axis, labelled '1/250 s' (pyqtgraph log mode works in log10)."""
    return [[(math.log10(t), shutter(t)) for t in TIME_TICKS]]


def dn_ticks() -> list[list[tuple[float, str]]]:
    return [[(math.log10(v), f"{v:,}".replace(",", "\u2009")) for v in DN_TICKS]]


class CharacterisePanel(QWidget):
    title = "Characterise"

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx, self.lab = ctx, ctx.lab
        self.sweep: CrfSweep | None = None
        self._live: dict[float, list[tuple[float, float]]] = {}
        self._live_curves: dict[float, pg.PlotDataItem] = {}
        self.view = SequenceView(ctx, preview=False)            # the response plot is the live view
        self.view.start_button.clicked.connect(self.start)
        self.view.finished.connect(self._finished)
        self.view.run_event.connect(self._event)
        self.result_label = QLabel("")
        self.result_label.setWordWrap(True)
        self.result_label.setTextFormat(Qt.TextFormat.RichText)
        left = QWidget()
        ll = QVBoxLayout(left)
        ll.addWidget(self._settings_box())
        ll.addWidget(self.view, 1)
        ll.addWidget(self.result_label)
        side_by_side(self, left, self._plots(), sizes=[520, 760])
        for sig in (self.lab.cameraChanged, self.lab.sphereChanged, self.lab.sessionChanged):
            sig.connect(self.update_plan)
        ctx.workspace.runningChanged.connect(lambda _n: self.update_plan())
        self.update_plan()

    # ------------------------------------------------------------------ builders
    def _settings_box(self) -> QGroupBox:
        box = QGroupBox("CRF and exposure-time linearity")
        form = QFormLayout(box)
        self.light = QComboBox()
        self.light.addItems([light_pct(CRF_LIGHT), "the Light source sliders"])
        self.light.setToolTip("The light of the open-gate sweep (Table 7.1's first light, or the sliders).")
        self.levels = QLineEdit(self.ctx.get("crf/levels_pct", "100, 25, 6.25", str))
        self.levels.setToolTip("Light levels in %: each repeats the sweep dimmer so every exposure time gets a point "
                               "inside the linear range (appendix A.2.1).")
        self.min_t = self._time_spin("crf/min_exposure_s", 1 / 4000, "Shortest exposure of the sweep.")
        self.max_t = self._time_spin("crf/max_exposure_s", 1.0, "Longest exposure of the sweep; the light-on limit "
                                                                "of 10 s caps it anyway.")
        form.addRow("Light", self.light)
        form.addRow("Levels (%)", self.levels)
        form.addRow("Shortest exposure", self.min_t)
        form.addRow("Longest exposure", self.max_t)
        self.levels.editingFinished.connect(lambda: self._setting("crf/levels_pct", self.levels.text()))
        self.light.currentIndexChanged.connect(lambda _i: self.update_plan())
        return box

    def _time_spin(self, key: str, default: float, tip: str) -> QDoubleSpinBox:
        spin = QDoubleSpinBox()
        spin.setDecimals(5)
        spin.setRange(1 / 8000, 10.0)
        spin.setSuffix("\u00a0s")
        spin.setValue(self.ctx.get(key, default, float))
        spin.setToolTip(tip)
        spin.valueChanged.connect(lambda v: self._setting(key, v))
        return spin

    def _setting(self, key: str, value: object) -> None:
        """Remember a setting and show the plan it makes."""
        self.ctx.set(key, value)
        self.update_plan()

    def _plots(self) -> QSplitter:
        self.crf_plot = plot_widget("camera response", "exposure time", "mean green above black (DN)",
                                    "Signal against exposure time per light level; red rings: exposure times "
                                    "flagged as departing from linearity; dashed: the linear limit the processing "
                                    "uses.")
        self.crf_plot.setLogMode(x=True, y=True)
        self.crf_plot.addLegend(offset=(10, 10))
        self.res_plot = plot_widget("linearity", "exposure time", "deviation from the line (%)",
                                    "How far each point lies from the straight line through the origin; shutter "
                                    "'bumps' stand out (appendix A). Red rings: flagged exposure times; dotted "
                                    "lines: changepoints found in the residuals.")
        self.res_plot.setLogMode(x=True, y=False)
        self.res_plot.addLegend(offset=(10, 10))
        for p in (self.crf_plot, self.res_plot):
            p.getAxis("bottom").setTicks(time_ticks())
        self.crf_plot.getAxis("left").setTicks(dn_ticks())
        plots = QSplitter(Qt.Orientation.Vertical)
        plots.addWidget(self.crf_plot)
        plots.addWidget(self.res_plot)
        return plots

    # ------------------------------------------------------------------ building
    def level_values(self) -> list[float]:
        """The light levels as fractions (the field is in %)."""
        text = self.levels.text()
        try:
            values = [float(x.strip().rstrip("%")) / 100 for x in text.replace(";", ",").split(",") if x.strip()]
        except ValueError:
            values = []
        if not values or any(not 0 < v <= 1 for v in values):
            raise ValueError(f"levels {text!r}: expected percentages above 0 and up to 100, like 100, 25")
        return values

    def chosen_light(self) -> LightSource:
        if self.light.currentIndex() == 1:
            light = light_from_levels(self.ctx.workspace.manual_levels, "CRF light")
            if light.is_dark:
                raise ValueError("the Light source sliders are all at 0: set a light there first")
            return light
        return CRF_LIGHT

    def stand_settings(self) -> StandSettings:
        latency = self.ctx.get("capture/latency_s", 0.0, float)
        return StandSettings(settle_s=self.ctx.get("capture/settle_s", SETTLE_S, float),
                             latency_s=latency if latency > 0 else None)

    def build(self, stand: StandPlanner) -> CrfSweep:
        """The sweep, built by the workflow on ``stand`` (app.workflow.stand.plans.StandPlanner)."""
        speeds = stand.facts.shutters                      # the camera's, as the run engine read them
        exposures = [t for t in (speeds or _NIKON_THIRDS) if self.min_t.value() * 0.999 <= t <= self.max_t.value()]
        return stand.crf_sweep(self.chosen_light(), self.level_values(), exposures, self.min_t.value())

    def update_plan(self) -> None:
        if self.view.running:
            return
        try:                       # the plan only: the camera's latency allowance, as the real one
            seq = self.build(plans_only(self.lab.camera, self.stand_settings()))
        except ValueError as exc:
            self.view.clear_plan(str(exc))
            return
        self.view.settle_s = self.ctx.get("capture/settle_s", SETTLE_S, float)
        self.view.show_plan(seq.plan(), "CRF sweep (stops early once a level clips)")
        ready = self.lab.camera is not None and self.lab.sphere is not None and not self.ctx.workspace.running
        self.view.start_button.setEnabled(ready)
        if not ready and not self.ctx.workspace.running:
            self.view.message.setText("needs the sphere and the camera (Devices); a session is made if there is none")

    # ------------------------------------------------------------------ running
    def start(self) -> None:
        """Start the sweep; without a session one is made first (AppContext.with_session)."""
        if self.lab.camera is None or self.lab.sphere is None:
            self.ctx.errors.report("CRF sweep", "connect the sphere and the camera first (Devices)")
            return
        self.ctx.with_session(self._start_now, "the CRF sweep")

    def _start_now(self) -> None:
        try:
            self.sweep = self.build(self.lab.copy_stand(self.stand_settings()).planner())
        except ValueError as exc:
            self.ctx.errors.report("CRF sweep", exc)
            return
        self._live = {}
        self._live_curves = {}
        self.crf_plot.clear()
        self.res_plot.clear()
        self.result_label.setText("")
        self.view.start(self.lab.plan_run(self.sweep, self.stand_settings()))

    def cancel_running(self) -> None:
        self.view.cancel()

    def shutdown(self) -> None:
        self.view.cancel()

    def _event(self, ev) -> None:
        if ev.kind is not EventKind.FRAME or "signal_dn" not in ev.data:
            return
        lv = float(ev.data["level"])
        self._live.setdefault(lv, []).append((float(ev.data["exposure_s"]), max(float(ev.data["signal_dn"]), 0.1)))
        t, s = zip(*self._live[lv], strict=True)
        if lv not in self._live_curves:
            pen = LEVEL_PENS[len(self._live_curves) % len(LEVEL_PENS)]
            self._live_curves[lv] = self.crf_plot.plot(t, s, pen=pg.mkPen(pen, width=2), symbol="o", symbolSize=4,
                                                       symbolBrush=pen, name=f"level {100 * lv:g} %")
        else:
            self._live_curves[lv].setData(t, s)

    def _finished(self, run, outcome: str) -> None:
        seq = run.source if run is not None else None
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
            self._residuals(res, lv, LEVEL_PENS[i % len(LEVEL_PENS)])
        self.crf_plot.addItem(pg.InfiniteLine(math.log10(LINEAR_LIMIT_DN), angle=0,
                                              pen=pg.mkPen("#ef6c00", width=2, style=Qt.PenStyle.DashLine),
                                              label="linear limit", labelOpts={"position": 0.95, "color": "#ef6c00"}))
        knee = summary.get("linear_limit_dn")
        flagged = summary.get("flagged_exposures") or []
        used = dn(LINEAR_LIMIT_DN)
        text = (f"linear limit used by the processing: <b>{used}</b> (thesis 4.1)" +
                (f"; knee measured on this camera: {dn(knee)} "
                 "(median over the levels)" if knee else "; no knee found in this sweep"))
        text += ("<br>exposure times departing from linearity: <b>" + shutters(flagged) + "</b>"
                 if flagged else "<br>no exposure time departs from linearity")
        self.result_label.setText(text)

    def _residuals(self, res, lv: float, pen: str) -> None:
        t = np.asarray(res.exposures)
        rel = 100 * np.asarray(res.residuals)
        inside = np.asarray(res.signal_dn) <= res.linear_limit_dn
        self.res_plot.plot(t[inside], rel[inside], pen=pg.mkPen(pen, width=1), symbol="o", symbolSize=5,
                           symbolBrush=pen, name=f"level {100 * lv:g} %")
        for cp in res.changepoints:                         # where the residuals change level (PELT)
            self.res_plot.addItem(pg.InfiniteLine(np.log10(cp), angle=90, pen=pg.mkPen(pen, width=1,
                                                                                       style=Qt.PenStyle.DotLine)))
        flagged = np.isin(t, res.flagged)
        if flagged.any():
            ring = {"pen": None, "symbol": "o", "symbolSize": 12, "symbolBrush": None,
                    "symbolPen": pg.mkPen("#c62828", width=2)}
            self.res_plot.plot(t[flagged], rel[flagged], **ring)
            s = np.asarray(res.signal_dn)
            self.crf_plot.plot(t[flagged], np.maximum(s[flagged], 0.1), **ring)


_NIKON_THIRDS = [1 / 4000, 1 / 2000, 1 / 1000, 1 / 500, 1 / 250, 1 / 125, 1 / 60, 1 / 30, 1 / 15, 1 / 8, 1 / 4,
                 1 / 2, 1.0]
