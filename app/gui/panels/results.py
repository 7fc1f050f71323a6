"""Results: process the session (app.workflow.session_processing.process_session: darks, HDR whites, flat field,
patch values, both matrices, outputs, report) and show the report: ΔE00 heatmap in the target layout, a*b* and
L*C* plots, ground truth vs prediction mosaic, summary statistics with FADGI / ISO 19264 / Metamorfoze badges,
export."""
from __future__ import annotations

import logging
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QUrl, Qt
from PySide6.QtGui import QDesktopServices
from PySide6.QtWidgets import (QCheckBox, QComboBox, QFileDialog, QFormLayout, QGridLayout, QGroupBox,
                               QHBoxLayout, QLabel, QProgressBar, QPushButton, QSplitter, QVBoxLayout, QWidget)

from app.gui.context import AppContext
from app.gui.widgets import image_widget, plot_widget
from app.gui.workers import TaskHandle
from app.workflow.session_processing import light_sets, subject_entries
from app.workflow.vocabulary import Subject

log = logging.getLogger(__name__)

BADGE_COLOURS = {True: "#2e7d32", False: "#c62828"}


@dataclass
class TargetView:
    """What the plots need for one target (computed in the worker from the processing results)."""

    label: str
    names: list[str]
    errors: np.ndarray
    lab_ref: np.ndarray
    lab_pred: np.ndarray
    srgb_ref: np.ndarray
    srgb_pred: np.ndarray
    layout: tuple[int, int]


def process(lab, session, grids: dict, train_subject: str, test_subject: Optional[str], optimise: bool,
            progress, cancel, lights: Optional[list[str]] = None) -> tuple[object, dict[str, TargetView], Path]:
    """Worker: the TargetSpecs (app.workflow.targets), the one processing path, the plot data."""
    from app.processing.report import xyz_to_srgb8
    from app.workflow.session_processing import process_session
    from app.workflow.targets import reference_white, target_spec
    from simulation.colorimetry import xyz_to_lab

    mode = lab.virtual_lab.mode if lab.virtual_lab is not None else lab.mode
    specs = {label: target_spec(mode, Subject.parse(key), grids.get(key), lab=lab.virtual_lab)
             for label, key in (("train", train_subject), ("test", test_subject)) if key}
    for label, spec in specs.items():
        spec.label = f"{label}: {spec.label}"                 # e.g. "train: test (CC24 on film)"
    out_dir = Path(session.path) / "results"
    result = process_session(session, out_dir, specs["train"], specs.get("test"), lights=lights, optimise=optimise,
                             white_xyz=reference_white(mode), title=f"dual-RGB capture, {Path(session.path).name}",
                             progress=progress, cancel=cancel)
    c = result.characterisation
    best = c.results[c.best]
    views = {}
    for label, spec in specs.items():
        values = result.patch_values[label]
        pred = best.matrix.apply(values)
        errors = best.train_errors if label == "train" else best.test_errors
        views[label] = TargetView(spec.label, spec.names, np.asarray(errors), xyz_to_lab(spec.xyz, c.white),
                                  xyz_to_lab(pred, c.white), xyz_to_srgb8(spec.xyz, c.white),
                                  xyz_to_srgb8(pred, c.white), spec.layout or (1, len(spec.names)))
    return result, views, out_dir


class ResultsPanel(QWidget):
    title = "Results"

    def __init__(self, ctx: AppContext, parent: Optional[QWidget] = None):
        super().__init__(parent)
        self.ctx = ctx
        self.lab = ctx.lab
        self.result = None
        self.views: dict[str, TargetView] = {}
        self.out_dir: Optional[Path] = None
        self.handle: Optional[TaskHandle] = None

        box = QGroupBox("Process the session")
        form = QFormLayout(box)
        self.train_subject = QComboBox()
        self.train_subject.setToolTip("The target the matrix is fitted on.")
        self.test_subject = QComboBox()
        self.test_subject.setToolTip("The target that checks the matrix (the accuracy figures are on this one).")
        self.lights = QComboBox()
        self.lights.setToolTip("Which preset's lights to process (a session may hold captures under several).")
        self.light_sets: dict[str, list[str]] = {}
        self.optimise = QCheckBox("also fit the ΔE00-optimised matrix")
        self.optimise.setChecked(ctx.get("results/optimise", True, bool))
        self.optimise.toggled.connect(lambda on: ctx.set("results/optimise", on))
        self.optimise.setToolTip("Besides least squares, a matrix that minimises the mean ΔE00 directly; the one "
                                 "that does better on the test target is used.")
        self.process_button = QPushButton("Process")
        self.process_button.setToolTip("Darks, flats, HDR merge, patch values, characterisation and report, in the "
                                       "background.")
        self.process_button.clicked.connect(self.start)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        self.cancel_button.clicked.connect(self.cancel_running)
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.status = QLabel("")
        self.status.setWordWrap(True)
        form.addRow("Fit on", self.train_subject)
        form.addRow("Check on", self.test_subject)
        form.addRow("Lights", self.lights)
        form.addRow(self.optimise)
        row = QHBoxLayout()
        row.addWidget(self.process_button)
        row.addWidget(self.cancel_button)
        form.addRow(row)
        form.addRow(self.progress)
        form.addRow(self.status)

        sbox = QGroupBox("Accuracy (mean CIEDE2000)")
        sl = QVBoxLayout(sbox)
        self.summary = QLabel("no results yet")
        self.summary.setWordWrap(True)
        self.summary.setTextFormat(Qt.RichText)
        self.badges = QGridLayout()
        sl.addWidget(self.summary)
        sl.addLayout(self.badges)
        self.badge_labels: dict[str, QLabel] = {}

        ebox = QGroupBox("Export")
        el = QVBoxLayout(ebox)
        self.export_button = QPushButton("Copy report and images to…")
        self.export_button.setToolTip("Copy report.json, the figures, CSVs and TIFF images to a folder you choose.")
        self.export_button.clicked.connect(self._ask_export)
        self.open_button = QPushButton("Open results folder")
        self.open_button.setToolTip("Show the results folder in the file manager.")
        self.open_button.clicked.connect(lambda: QDesktopServices.openUrl(QUrl.fromLocalFile(str(self.out_dir)))
                                         if self.out_dir else None)
        self.files_label = QLabel("")
        self.files_label.setWordWrap(True)
        for w in (self.export_button, self.open_button, self.files_label):
            el.addWidget(w)
        self.export_button.setEnabled(False)
        self.open_button.setEnabled(False)

        left = QWidget()
        ll = QVBoxLayout(left)
        ll.addWidget(box)
        ll.addWidget(sbox)
        ll.addWidget(ebox)
        ll.addStretch(1)

        # ---- plots ----
        self.which = QComboBox()
        self.which.addItems(["test", "train"])
        self.which.setToolTip("Show the test or the training target.")
        self.which.currentTextChanged.connect(lambda _t: self.show_view())
        self.heat_widget, self.heat_item, self.heat_box = image_widget("ΔE00 of every patch, laid out like the target.")
        self.heat_widget.setBackground("w")
        self.heat_texts: list[pg.TextItem] = []
        self.ab_plot = plot_widget("a* b*", "a*", "b*", "Reference colours of the patches, coloured by their ΔE00.")
        self.lc_plot = plot_widget("L* C*", "C*", "L*", "Lightness against chroma, coloured by ΔE00.")
        self.mosaic_widget, self.mosaic_item, self.mosaic_box = image_widget(
            "Each patch: left half the true colour, right half the colour the capture predicts (sRGB).")
        self.mosaic_widget.setBackground("w")
        self.colour_bar = QLabel("")
        plots = QWidget()
        pg_ = QGridLayout(plots)
        pg_.addWidget(self.which, 0, 0)
        pg_.addWidget(self.colour_bar, 0, 1)
        pg_.addWidget(self.heat_widget, 1, 0)
        pg_.addWidget(self.mosaic_widget, 1, 1)
        pg_.addWidget(self.ab_plot, 2, 0)
        pg_.addWidget(self.lc_plot, 2, 1)
        split = QSplitter(Qt.Horizontal)
        split.addWidget(left)
        split.addWidget(plots)
        split.setStretchFactor(1, 1)
        QVBoxLayout(self).addWidget(split)
        self.cmap = pg.colormap.get("viridis")

        self.lab.sessionChanged.connect(self.reload)
        ctx.bus.sessionUpdated.connect(self.reload)
        self.reload()

    # ------------------------------------------------------------------ subjects
    def reload(self) -> None:
        session = self.lab.session
        if session is None:
            return
        self.ctx.runner.submit(lambda: subject_entries(session), pool="compute", name="list targets",
                               on_result=self._fill, on_error=lambda exc: self.ctx.errors.report("Results", exc))

    def _fill(self, subjects: dict) -> None:
        keys = sorted(subjects)
        names = [n for key in keys if key.startswith("target:") for n in subjects[key]]
        self.light_sets = light_sets(list(dict.fromkeys(names)))
        current = self.lights.currentText()
        self.lights.clear()
        self.lights.addItems(list(self.light_sets))
        if current in self.light_sets:
            self.lights.setCurrentText(current)
        for combo, tag in ((self.train_subject, "train"), (self.test_subject, "test")):
            current = combo.currentText()
            combo.clear()
            if combo is self.test_subject:
                combo.addItem("")
            combo.addItems(keys)
            preferred = current if current in keys else next((k for k in keys if k == f"target:{tag}"),
                                                             next((k for k in keys if k.endswith(tag)), ""))
            combo.setCurrentText(preferred)

    # ------------------------------------------------------------------ processing
    def start(self) -> None:
        session = self.lab.session
        if session is None:
            self.ctx.errors.report("Process", "no session: capture darks, flats and the targets first")
            return
        train, test = self.train_subject.currentText(), self.test_subject.currentText() or None
        if not train:
            self.ctx.errors.report("Process", "no captured target to fit on: capture one in Calibrate & capture")
            return
        grids = dict(self.ctx.shared.get("grids", {}))
        optimise = self.optimise.isChecked()
        lights = self.light_sets.get(self.lights.currentText())
        lab = self.lab
        self.process_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.status.setText("processing …")
        self.progress.setValue(0)
        self.handle = self.ctx.runner.submit(
            lambda progress, cancel: process(lab, session, grids, train, test, optimise, progress, cancel, lights),
            pool="compute", name="process session", pass_progress=True, pass_cancel=True,
            on_progress=lambda f, m: (self.progress.setValue(int(1000 * f)), self.status.setText(m)),
            on_result=self.show_result, on_error=self._failed, on_finished=self._finished)

    def _failed(self, exc: BaseException) -> None:
        from simulation.progress import Cancelled
        if isinstance(exc, Cancelled):
            self.status.setText("processing cancelled")
            return
        self.status.setText(f"failed: {exc}")
        self.ctx.errors.report("Process the session", exc)

    def _finished(self) -> None:
        self.process_button.setEnabled(True)
        self.cancel_button.setEnabled(False)

    def cancel_running(self) -> None:
        if self.handle is not None and self.handle.running:
            self.handle.cancel()

    def shutdown(self) -> None:
        self.cancel_running()

    # ------------------------------------------------------------------ display
    def show_result(self, payload) -> None:
        result, views, out_dir = payload
        self.result, self.views, self.out_dir = result, views, out_dir
        rep = result.report
        self.progress.setValue(1000)
        self.status.setText(f"done: report in {out_dir}")

        def stats(d: Optional[dict]) -> str:
            if not d:
                return "—"
            return f"mean <b>{d['mean']:.2f}</b>, median {d['median']:.2f}, 90 % {d['p90']:.2f}, max {d['max']:.2f}"
        methods = ", ".join(f"{m}: test {v['test']['mean']:.2f}" if v.get("test") else f"{m}: train "
                            f"{v['train']['mean']:.2f}" for m, v in rep["methods"].items())
        self.summary.setText(f"{len(rep['channels'])} channels, matrix <b>{rep['best_method']}</b> "
                             f"({rep['best_reason']})<br>training: {stats(rep['train'])}<br>"
                             f"test: {stats(rep['test'])}<br><small>{methods}</small>")
        self._badges(rep["standards"])
        files = sorted(p.name for p in result.files.values())
        self.files_label.setText(f"{len(files)} files + {len(rep['figures'])} figures in {out_dir}")
        self.export_button.setEnabled(True)
        self.open_button.setEnabled(True)
        self.which.setCurrentText("test" if "test" in views else "train")
        self.show_view()
        self.ctx.bus.resultsReady.emit(rep)

    def _badges(self, standards: dict) -> None:
        while self.badges.count():
            item = self.badges.takeAt(0)
            if item.widget():
                item.widget().deleteLater()
        self.badge_labels = {}
        on = standards.get("evaluated_on", "test")
        for r, (std, res) in enumerate(standards["results"].items()):
            level = res["level"]
            badge = QLabel(f"{std}, colour accuracy only: {level if level else 'not met'}")
            badge.setStyleSheet(f"background:{BADGE_COLOURS[level is not None]}; color:white; border-radius:6px; "
                                "padding:3px 8px; font-weight:bold")
            lines = [f"{name}: {'pass' if v['pass'] else 'fail'} (" + ", ".join(
                f"{k} {v['comparison']} {lim:g}" for k, lim in v["limits"].items()) + ")"
                for name, v in res["levels"].items()]
            badge.setToolTip(f"{std} colour accuracy on the {on} target (indicative: see the report):\n"
                             + "\n".join(lines) + "\nNot a full grade: tone, white balance, noise and uniformity "
                             "are graded per metric in the report's quality section; SFR / MTF, sampling, "
                             "misregistration and gain modulation are not assessed.")
            self.badges.addWidget(badge, r, 0)
            self.badge_labels[std] = badge

    def show_view(self) -> None:
        view = self.views.get(self.which.currentText())
        if view is None:
            return
        rows, cols = view.layout
        n = len(view.errors)
        grid = np.full(rows * cols, np.nan)
        grid[:n] = view.errors
        vmax = float(np.nanmax(view.errors)) or 1.0
        lut = self.cmap.getLookupTable(0.0, 1.0, 256)
        self.heat_item.setImage(grid.reshape(rows, cols), levels=(0.0, vmax), lut=lut, autoLevels=False)
        for t in self.heat_texts:
            self.heat_box.removeItem(t)
        self.heat_texts = []
        if n <= 60:
            for k, e in enumerate(view.errors):
                r, c = divmod(k, cols)
                t = pg.TextItem(f"{e:.1f}", color="w" if e < 0.6 * vmax else "k", anchor=(0.5, 0.5))
                t.setPos(c + 0.5, r + 0.5)
                self.heat_box.addItem(t)
                self.heat_texts.append(t)
        self.heat_box.autoRange()
        self.colour_bar.setText(f"ΔE00 0 (dark) … {vmax:.2f} (yellow); {view.label}")
        brushes = [pg.mkBrush(self.cmap.map(min(e / vmax, 1.0), mode="qcolor")) for e in view.errors]
        self.ab_plot.clear()
        self.ab_plot.addItem(pg.ScatterPlotItem(view.lab_ref[:, 1], view.lab_ref[:, 2], brush=brushes, size=9,
                                                pen=pg.mkPen("#444")))
        self.ab_plot.addItem(pg.ScatterPlotItem(view.lab_pred[:, 1], view.lab_pred[:, 2], brush=None, size=5,
                                                symbol="x", pen=pg.mkPen("#d32f2f")))
        chroma_ref = np.hypot(view.lab_ref[:, 1], view.lab_ref[:, 2])
        chroma_pred = np.hypot(view.lab_pred[:, 1], view.lab_pred[:, 2])
        self.lc_plot.clear()
        self.lc_plot.addItem(pg.ScatterPlotItem(chroma_ref, view.lab_ref[:, 0], brush=brushes, size=9,
                                                pen=pg.mkPen("#444")))
        self.lc_plot.addItem(pg.ScatterPlotItem(chroma_pred, view.lab_pred[:, 0], size=5, symbol="x",
                                                pen=pg.mkPen("#d32f2f")))
        cell = 16
        img = np.ones((rows * cell, cols * cell, 3))
        for k in range(n):
            r, c = divmod(k, cols)
            y, x = r * cell, c * cell
            img[y + 1:y + cell - 1, x + 1:x + cell // 2] = view.srgb_ref[k]
            img[y + 1:y + cell - 1, x + cell // 2:x + cell - 1] = view.srgb_pred[k]
        self.mosaic_item.setImage((img * 255).astype(np.uint8), autoLevels=False, levels=(0, 255))
        self.mosaic_box.autoRange()

    # ------------------------------------------------------------------ export
    def _ask_export(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Copy the results to", str(Path.home()))
        if folder:
            self.export_to(Path(folder))

    def export_to(self, folder: Path) -> None:
        src = self.out_dir
        if src is None:
            return
        dest = folder / f"{src.parent.name}-results"

        def work() -> Path:
            shutil.copytree(src, dest, dirs_exist_ok=True)
            return dest

        self.ctx.runner.submit(work, pool="compute", name="export results",
                               on_result=lambda d: self.files_label.setText(f"copied to {d}"),
                               on_error=lambda exc: self.ctx.errors.report("Export the results", exc))
