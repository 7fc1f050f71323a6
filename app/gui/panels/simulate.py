"""Simulate & optimise: choose the sphere's two lights in simulation (exhaustive / PSO / GA), watch the search
converge, look at the chosen lights and the six channel sensitivities, save the result as a preset. "Re-optimise
for this stand" runs the same search on the stand model the loaded calibration fitted
(app.workflow.calibration.stand_reoptimise, as ``dualrgb simulate --stand``)."""
from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import cast

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import (
    QComboBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QInputDialog,
    QLabel,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QSpinBox,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from dualrgb import resources
from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.units import light_pct, time_left_s
from dualrgb.app.gui.viewmodel import ConvergenceTap, format_duration
from dualrgb.app.gui.widgets import plot_widget, side_by_side
from dualrgb.app.gui.workers import TaskHandle
from dualrgb.common.progress import COMPILING, Cancelled
from dualrgb.simulation.camera_model import channel_names, effective_sensitivities
from dualrgb.simulation.datasets import MODES, default_setup
from dualrgb.simulation.ga import GaSettings
from dualrgb.simulation.objective import Evaluator
from dualrgb.simulation.presets import save_preset
from dualrgb.simulation.pso import PsoSettings
from dualrgb.simulation.runner import DEFAULT_METHOD, DEFAULT_OBJECTIVE, METHODS, OBJECTIVES, RunResult, run
from dualrgb.simulation.search import SearchOutcome
from dualrgb.simulation.studies.common import study_charts

log = logging.getLogger(__name__)

LIGHT_PENS = ("#6a1b9a", "#00838f")
CHANNEL_COLOURS = {"R": "#d32f2f", "G": "#388e3c", "B": "#1976d2"}


def _de(stats, fallback: float | None = None) -> str:
    """A table cell: the mean ΔE00 of ``stats`` (``fallback`` without stats), or a dash when there is neither."""
    if stats is not None:
        return f"{stats.mean:.3f}"
    return f"{fallback:.3f}" if fallback is not None and np.isfinite(fallback) else "—"


def partial_result(setup, tap: ConvergenceTap, method: str, seed: int, top: int, elapsed_s: float
                   ) -> RunResult | None:
    """A cancelled search's best light pair so far (kept, labelled partial), or None before any cost."""
    cand = tap.partial()
    if cand is None:
        return None
    outcome = SearchOutcome(method, seed, elapsed_s, tap.evaluations, [cand], settings={"partial": True})
    return RunResult(mode=setup.mode, method=method, seed=seed, elapsed_s=elapsed_s, evaluations=tap.evaluations,
                     three_channel={}, outcome=outcome, setup=setup, top=top, extra={"partial": True},
                     objective=getattr(tap, "objective", "noise-free"))


def _stand_search(profile, mode: str, method: str, seed: int, top: int, objective: str, progress, cancel, emit,
                  **settings) -> RunResult | None:
    """The search on a calibration's stand model (app.workflow.calibration.stand_reoptimise), with the live plot's tap;
    a
    cancelled search keeps its best so far, as the plain search does."""
    from dualrgb.app.workflow.calibration.stand_reoptimise import assemble, calibration_lights, reoptimise
    from dualrgb.simulation.runner import make_evaluator

    model, notes = assemble(profile)
    holder: dict = {}

    def tap_for(setup, capture):
        holder["setup"] = setup
        holder["tap"] = ConvergenceTap(make_evaluator(setup, objective, capture), lambda n, best: emit((n, best)))
        return holder["tap"] if method != "three-channel" else None
    t0 = time.perf_counter()
    try:
        result = reoptimise(model, mode, method=method, objective=objective, seed=seed, top=top, progress=progress,
                            cancel=cancel, evaluator_factory=tap_for, incumbents=[calibration_lights(profile)],
                            **settings)
    except Cancelled:
        if "tap" not in holder:
            return None
        return partial_result(holder["setup"], holder["tap"], method, seed, top, time.perf_counter() - t0)
    result.extra["stand"].update(calibration=profile.id, notes=notes)
    return result


class SimulatePanel(QWidget):
    title = "Simulate & optimise"

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.result: RunResult | None = None
        self.handle: TaskHandle | None = None
        self.live: list[tuple[int, float]] = []
        self._live_dirty = False
        self._t_search: tuple[float, float] | None = None      # (time, fraction) when the search proper began
        left = QWidget()
        ll = QVBoxLayout(left)
        ll.addWidget(self._search_box())
        ll.addLayout(self._run_buttons())
        ll.addWidget(self.progress)
        ll.addWidget(self.time_left)
        ll.addWidget(self.status)
        ll.addWidget(self._results_table(), 1)
        self.right_tabs = QTabWidget()
        self.right_tabs.addTab(self._search_plots(), "Search")
        self.right_tabs.addTab(self._study_charts(), "Study charts")
        self.right_tabs.currentChanged.connect(lambda i: self.load_figures() if i == 1 else None)
        side_by_side(self, left, self.right_tabs, sizes=[480, 950])
        self._live_timer = QTimer(self)             # the live curve is redrawn at most 10 times a second
        self._live_timer.setInterval(100)
        self._live_timer.timeout.connect(self._draw_live)
        self._method_changed(self.method.currentText())

    # ------------------------------------------------------------------ builders
    def _search_box(self) -> QGroupBox:
        box = QGroupBox("Search")
        form = QFormLayout(box)
        self.mode = QComboBox()
        self.mode.addItems(MODES)
        self.mode.setToolTip("Reflective: prints, paintings. Transmissive: film on the light box.")
        self.method = QComboBox()
        self.method.addItems(METHODS)
        self.method.setToolTip("halving (default): successive halving over the thesis PSO, then L-BFGS-B; the "
                               "fastest swarm that reaches the best optimum. exhaustive: every binned pair at full "
                               "power. pso: the thesis' Algorithm 1. ga: Algorithm 2. three-channel: the ordinary "
                               "camera under D65.")
        self.objective = QComboBox()
        self.objective.addItems(OBJECTIVES)
        self.objective.setToolTip("expected-captured (default): the error a capture will have (camera noise at the "
                                  "exposures the sequence uses, the sphere's level grid). noise-free: the thesis' "
                                  "simulation. robust: the mean over plausible worlds (LEDs, camera, reference "
                                  "off by a few nm / %), 8x slower. expected-per-pixel: the expected captured error "
                                  "of one pixel of each patch, the matrix's noise amplification counted (as a master "
                                  "is judged).")
        self.seed = QSpinBox()
        self.seed.setRange(0, 2**31 - 1)
        self.seed.setToolTip("Random seed: the same seed gives the same result.")
        self.iterations = QSpinBox()
        self.iterations.setRange(1, 1000)
        self.iterations.setToolTip("PSO iterations / GA generations (thesis: 10).")
        self.population = QSpinBox()
        self.population.setRange(2, 5000)
        self.population.setToolTip("PSO particles / GA offspring per light pair (thesis: 200).")
        self.top = QSpinBox()
        self.top.setRange(1, 50)
        self.top.setToolTip("How many of the best light pairs to list.")
        form.addRow("Mode", self.mode)
        form.addRow("Method", self.method)
        form.addRow("Objective", self.objective)
        form.addRow("Seed", self.seed)
        form.addRow("Iterations", self.iterations)
        form.addRow("Particles / offspring", self.population)
        form.addRow("Show best", self.top)
        self._load_settings()
        for w in (self.mode, self.method, self.objective):
            w.currentTextChanged.connect(self._save_settings)
        for spin in (self.seed, self.iterations, self.population, self.top):
            spin.valueChanged.connect(self._save_settings)
        self.method.currentTextChanged.connect(self._method_changed)
        return box

    def _run_buttons(self) -> QHBoxLayout:
        buttons = QHBoxLayout()
        self.run_button = QPushButton("Run search")
        self.run_button.setToolTip("Start the search in the background; the window stays usable.")
        self.run_button.clicked.connect(self.start)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setToolTip("Stop the search (Esc); the best light pair found so far is kept (partial).")
        self.cancel_button.clicked.connect(self.cancel_running)
        self.cancel_button.setEnabled(False)
        self.stand_button = QPushButton("Re-optimise for this stand")
        self.stand_button.setToolTip("The same search on the stand model the current calibration fitted to its "
                                     "captures (LED outputs and peaks, camera gains and curves, flare), as "
                                     "the command line's simulate on the stand; load or make a calibration first.")
        self.stand_button.clicked.connect(self.start_for_stand)
        self.ctx.workspace.calibrationChanged.connect(self._stand_changed)
        self.save_button = QPushButton("Save as preset…")
        self.save_button.setToolTip("Save the selected light pair as a preset; it appears in Light source.")
        self.save_button.clicked.connect(self._ask_save)
        self.save_button.setEnabled(False)
        for w in (self.run_button, self.stand_button, self.cancel_button, self.save_button):
            buttons.addWidget(w)
        self._stand_changed()
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.time_left = QLabel("")
        self.status = QLabel("")
        self.status.setWordWrap(True)
        return buttons

    def _results_table(self) -> QTableWidget:
        self.table = QTableWidget(0, 4)
        self.table.setHorizontalHeaderLabels(["light 1", "light 2", "train ΔE00\nexpected / noise-free",
                                              "test ΔE00\nexpected / noise-free"])
        self.table.setToolTip("Best light pairs: mean CIEDE2000 on the training and test targets, as a capture is "
                              "expected to measure them (camera noise at the planned exposures) / in the "
                              "noise-free simulation; LED levels in %.")
        self.table.setWordWrap(True)
        header = self.table.horizontalHeader()
        for col in (0, 1):                          # the lights wrap; the numbers always show whole
            header.setSectionResizeMode(col, QHeaderView.ResizeMode.Stretch)
        for col in (2, 3):
            header.setSectionResizeMode(col, QHeaderView.ResizeMode.ResizeToContents)
        self.table.currentCellChanged.connect(lambda row, *_: self.show_candidate(row))
        return self.table

    def _search_plots(self) -> QWidget:
        self.conv = plot_widget("convergence (live)", "evaluations", "best mean ΔE00 so far (train)",
                                "Best training error found so far while the search runs.")
        self.live_curve = self.conv.plot([], [], pen=pg.mkPen("#1565c0", width=2), symbol=None)
        self.iter_plot = plot_widget("best per iteration", "iteration", "mean ΔE00 (train)",
                                     "After the search: the best training error over all light pairs after each "
                                     "iteration (PSO) or generation (GA).")
        self.iter_curve = self.iter_plot.plot([], [], pen=pg.mkPen("#2e7d32", width=2, style=Qt.PenStyle.DashLine),
                                              symbol="o", symbolSize=5)
        self.lights_plot = plot_widget("chosen lights", "wavelength (nm)", "relative radiance",
                                       "The two lights of the selected pair (LED spectra times their levels).")
        self.lights_plot.addLegend(offset=(-10, 10))
        self.sens_plot = plot_widget("six channel sensitivities", "wavelength (nm)",
                                     "relative sensitivity (each light's max = 1)",
                                     "Camera R, G, B under light 1 (solid) and light 2 (dashed): the six channels "
                                     "the characterisation turns into XYZ (eq 5.15).")
        self.sens_plot.addLegend(offset=(-10, 10))
        plots = QWidget()
        grid = QVBoxLayout(plots)
        top_row = QSplitter(Qt.Orientation.Horizontal)
        top_row.addWidget(self.conv)
        top_row.addWidget(self.iter_plot)
        bottom_row = QSplitter(Qt.Orientation.Horizontal)
        bottom_row.addWidget(self.lights_plot)
        bottom_row.addWidget(self.sens_plot)
        grid.addWidget(top_row)
        grid.addWidget(bottom_row)
        return plots

    def _study_charts(self) -> QWidget:
        studies = QWidget()
        sl = QVBoxLayout(studies)
        self.figure_combo = QComboBox()
        self.figure_combo.setToolTip("Charts of your studies (run from the command line) and the packaged "
                                     "reference runs.")
        self.figure_combo.currentIndexChanged.connect(self._show_figure)
        self.figure_label = QLabel("")
        self.figure_label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        scroll = QScrollArea()
        scroll.setWidget(self.figure_label)
        scroll.setWidgetResizable(True)
        self.figures_info = QLabel("")
        self.figures_info.setWordWrap(True)
        sl.addWidget(self.figure_combo)
        sl.addWidget(self.figures_info)
        sl.addWidget(scroll, 1)
        return studies

    # ------------------------------------------------------------------ settings
    def _load_settings(self) -> None:
        g = self.ctx.get
        self.mode.setCurrentText(g("simulate/mode", "reflective", str))
        self.method.setCurrentText(g("simulate/method", DEFAULT_METHOD, str))
        self.objective.setCurrentText(g("simulate/objective", DEFAULT_OBJECTIVE, str))
        self.seed.setValue(g("simulate/seed", 0, int))
        self.iterations.setValue(g("simulate/iterations", PsoSettings().iterations, int))
        self.population.setValue(g("simulate/population", PsoSettings().particles, int))
        self.top.setValue(g("simulate/top", 5, int))

    def _save_settings(self, *_args) -> None:
        s = self.ctx.set
        s("simulate/mode", self.mode.currentText())
        s("simulate/method", self.method.currentText())
        s("simulate/objective", self.objective.currentText())
        s("simulate/seed", self.seed.value())
        s("simulate/iterations", self.iterations.value())
        s("simulate/population", self.population.value())
        s("simulate/top", self.top.value())

    def _method_changed(self, method: str) -> None:
        tuned = method in ("pso", "ga")
        self.iterations.setEnabled(tuned)
        self.population.setEnabled(tuned)
        self.seed.setEnabled(tuned or method == "halving")
        self.objective.setEnabled(method != "three-channel")

    # ------------------------------------------------------------------ run
    def _stand_changed(self) -> None:
        profile = self.ctx.workspace.calibration
        self.stand_button.setEnabled(profile is not None and bool(profile.stand)
                                     and not (self.handle is not None and self.handle.running))

    def start_for_stand(self) -> None:
        """The search on the current calibration's stand model (off the GUI thread, like :meth:`start`)."""
        profile = self.ctx.workspace.calibration
        if profile is None or not profile.stand:
            self.ctx.errors.report("Re-optimise for this stand", "load or make a calibration with a fitted stand "
                                                                 "model first (Calibrate & capture)")
            return
        self._launch(profile)

    def start(self) -> None:
        """The search on the nominal model (Run search)."""
        self._launch(None)

    def _launch(self, stand_profile) -> None:
        """Start the search in the compute pool; ``stand_profile``: a calibration whose stand model it runs on."""
        if self.handle is not None and self.handle.running:
            return
        mode, method, seed, top = (self.mode.currentText(), self.method.currentText(), self.seed.value(),
                                   self.top.value())
        objective = self.objective.currentText()
        pso_settings = PsoSettings(iterations=self.iterations.value(), particles=self.population.value())
        ga_settings = GaSettings(generations=self.iterations.value(), lam=self.population.value())
        self.live = []
        self.live_curve.setData([], [])
        self.iter_curve.setData([], [])
        self.iter_plot.setTitle("best per iteration")
        self.progress.setValue(0)
        self.time_left.setText("")
        self._t_search = None
        self._live_timer.start()
        self.status.setText(f"running {method} ({mode})" + (f" for stand {stand_profile.id}" if stand_profile else "")
                            + " …")
        self.run_button.setEnabled(False)
        self.stand_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.save_button.setEnabled(False)

        def work(progress, cancel, emit) -> RunResult | None:
            if stand_profile is not None:
                return _stand_search(stand_profile, mode, method, seed, top, objective, progress, cancel, emit,
                                     pso_settings=pso_settings, ga_settings=ga_settings)
            setup = default_setup(mode)
            tap = ConvergenceTap.make(setup, lambda n, best: emit((n, best)), objective)
            # a ConvergenceTap forwards everything but the cost batches to the Evaluator it wraps
            evaluator = cast(Evaluator, tap) if method != "three-channel" else None
            t0 = time.perf_counter()
            try:
                return run(setup, method, seed=seed, top=top, pso_settings=pso_settings, ga_settings=ga_settings,
                           progress=progress, cancel=cancel, evaluator=evaluator, objective=objective)
            except Cancelled:
                return partial_result(setup, tap, method, seed, top, time.perf_counter() - t0)

        self.handle = self.ctx.runner.submit(work, pool="compute", name=f"simulate {method}", pass_progress=True,
                                             pass_cancel=True, pass_emit=True, on_progress=self._progress,
                                             on_event=self._live_point, on_result=self.show_result,
                                             on_error=self._failed, on_finished=self._finished)

    def _live_point(self, point: tuple[int, float]) -> None:
        self.live.append(point)
        self._live_dirty = True

    def _draw_live(self) -> None:
        if self._live_dirty and self.live:
            xs, ys = zip(*self.live, strict=True)
            self.live_curve.setData(np.array(xs, dtype=float), np.array(ys))
        self._live_dirty = False

    def _progress(self, fraction: float, message: str) -> None:
        self.progress.setValue(int(round(fraction * 1000)))
        self.status.setText(message)
        now = time.monotonic()
        if message == COMPILING or fraction <= 0:          # the one-off compile is not the search
            return
        if self._t_search is None:
            self._t_search = (now, fraction)
            return
        t0, f0 = self._t_search
        left = time_left_s(now - t0, (fraction - f0) / max(1.0 - f0, 1e-9))
        self.time_left.setText(f"time left about {format_duration(left)}" if left is not None else "")

    def _failed(self, exc: BaseException) -> None:
        if isinstance(exc, Cancelled):
            self.status.setText("search cancelled")
            log.info("simulation cancelled")
            return
        self.status.setText(f"failed: {exc}")
        self.ctx.errors.report("Simulation", exc)

    def _finished(self) -> None:
        self.run_button.setEnabled(True)
        self._stand_changed()
        self.cancel_button.setEnabled(False)
        self._live_timer.stop()
        self._draw_live()
        self.time_left.setText("")

    def cancel_running(self) -> None:
        if self.handle is not None and self.handle.running:
            self.handle.cancel()             # the search stops within one slice (simulation.search.CANCEL_SLICE)
            compiling = self.status.text() == COMPILING       # numba's one-off compile cannot be interrupted
            self.status.setText("cancelling after the kernels' one-off compile (first run only) …" if compiling
                                else "cancelling …")

    def shutdown(self) -> None:
        self.cancel_running()

    # ------------------------------------------------------------------ result
    def show_result(self, result: RunResult | None) -> None:
        if result is None:
            self.status.setText("search cancelled before any light pair was evaluated")
            return
        self.result = result
        partial = bool(result.extra.get("partial"))
        self.progress.setValue(self.progress.value() if partial else 1000)
        base = result.three_channel
        text = (f"{result.method} ({result.mode}, {result.objective}): {result.evaluations} evaluations in "
                f"{result.elapsed_s:.1f} s")
        if partial:
            text = "PARTIAL (cancelled): the best light pair found so far; " + text
        if base:
            text += f"; 3-channel D65 baseline: train {base['train']:.2f}, test {base['test']:.2f} ΔE00"
        stand = result.extra.get("stand")
        if stand:
            text += "; on the stand model: " + "; ".join(stand.get("notes", []))
        self.status.setText(text)
        self.table.setRowCount(0)
        if result.outcome is None:
            self.save_button.setEnabled(False)
            return
        self._fill_table(result.outcome.candidates[:result.top], partial)
        self._show_history(result)
        self._draw_live()
        self.save_button.setEnabled(True)
        self.table.selectRow(0)
        self.show_candidate(0)

    def _fill_table(self, cands, partial: bool) -> None:
        self.table.setRowCount(len(cands))
        for r, c in enumerate(cands):
            s1, s2 = c.sources[:2]
            values = (light_pct(s1), light_pct(s2), f"{_de(c.expected_train)} / {_de(c.train, c.train_cost)}",
                      f"{_de(c.expected_test)} / {_de(c.test)}")
            for col, v in enumerate(values):
                item = QTableWidgetItem(v + (" (partial)" if partial and col == 2 else ""))
                item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
                item.setToolTip(f"{c.sources[col].label()} (levels 0..1)" if col < 2 else v)
                self.table.setItem(r, col, item)
        self.table.resizeRowsToContents()

    def _show_history(self, result: RunResult) -> None:
        """Best per iteration: only finite values (an iteration with no finite cost is left out); a method
        without iterations says so instead of an empty axis."""
        hist = np.asarray((result.outcome.history if result.outcome else None) or [], dtype=float)
        keep = np.isfinite(hist)
        if not keep.any():
            self.iter_curve.setData([], [])
            why = "a single pass, no iterations" if result.method == "exhaustive" else "no iterations recorded"
            self.iter_plot.setTitle(f"best per iteration: none ({result.method}: {why})")
            self.iter_plot.getPlotItem().setRange(xRange=(0, 1), yRange=(0, 1))
            return
        self.iter_plot.setTitle("best per iteration")
        self.iter_curve.setData(np.flatnonzero(keep).astype(float), hist[keep])
        self.iter_plot.getPlotItem().enableAutoRange()

    def show_candidate(self, row: int) -> None:
        res = self.result
        if res is None or res.outcome is None or not 0 <= row < min(res.top, len(res.outcome.candidates)):
            return
        cand = res.outcome.candidates[row]
        setup = res.setup
        wl = setup.grid.wavelengths
        lights = np.stack([s.spectrum(setup.leds) for s in cand.sources])
        self.lights_plot.clear()
        for i, spd in enumerate(lights):
            self.lights_plot.plot(wl, spd, pen=pg.mkPen(LIGHT_PENS[i % 2], width=2),
                                  name=f"light {i + 1}: LEDs {', '.join(map(str, cand.sources[i].leds))}")
        sens = effective_sensitivities(lights, setup.camera)
        for i in range(len(lights)):                      # each light's three channels scaled together
            block = sens[:, 3 * i:3 * i + 3]
            block /= block.max() or 1.0
        self.sens_plot.clear()
        for j, name in enumerate(channel_names(len(lights))):
            style = Qt.PenStyle.SolidLine if name.endswith("1") else Qt.PenStyle.DashLine
            self.sens_plot.plot(wl, sens[:, j], pen=pg.mkPen(CHANNEL_COLOURS[name[0]], width=2, style=style),
                                name=name)

    # ------------------------------------------------------------------ presets
    def _ask_save(self) -> None:
        if self.result is None or self.result.outcome is None:
            return
        row = max(self.table.currentRow(), 0)
        default = self.result.preset(row).name
        name, ok = QInputDialog.getText(self, "Save preset", "Preset name:", text=default)
        if ok and name.strip():
            self.save_preset(name.strip(), row)

    def save_preset(self, name: str, rank: int = 0) -> Path | None:
        if self.result is None or self.result.outcome is None:
            self.ctx.errors.report("Save the preset", "run a PSO, GA or exhaustive search first")
            return None
        preset = self.result.preset(rank, name=name)
        if self.result.extra.get("stand"):                    # chosen on a stand model: the preset names it
            preset.model["stand"] = self.result.extra["stand"]["model"]
        slug = "".join(c if c.isalnum() or c in "-_" else "_" for c in name).strip("_") or "preset"
        path = self.ctx.presets_dir / f"{slug}.json"

        def saved(p: Path) -> None:
            self.status.setText(f"preset saved: {p}")
            self.ctx.bus.presetsChanged.emit()
        self.ctx.runner.submit(lambda: save_preset(preset, path), pool="compute", name="save preset",
                               on_result=saved, on_error=lambda exc: self.ctx.errors.report("Save the preset", exc))
        return path

    # ------------------------------------------------------------------ study charts
    def load_figures(self) -> None:
        def work() -> list[tuple[str, QImage]]:
            return [(label, QImage(str(p))) for label, p in study_charts()]

        def done(images: list[tuple[str, QImage]]) -> None:
            self._figures = images
            self.figure_combo.blockSignals(True)
            self.figure_combo.clear()
            self.figure_combo.addItems([n for n, _ in images])
            self.figure_combo.blockSignals(False)
            if images:
                self.figures_info.setText(f"{len(images)} chart(s); studies run from the command line add yours in "
                                          f"{resources.user_path('studies')}")
                self._show_figure(0)
            else:
                self.figures_info.setText(f"no study charts yet: a study run from the command line makes them in "
                                          f"{resources.user_path('studies')}")
                self.figure_label.clear()
        self.ctx.runner.submit(work, pool="compute", name="load study charts", on_result=done,
                               on_error=lambda exc: self.ctx.errors.report("Study charts", exc))

    def _show_figure(self, index: int) -> None:
        images = getattr(self, "_figures", [])
        if 0 <= index < len(images):
            self.figure_label.setPixmap(QPixmap.fromImage(images[index][1]))
