"""Results: process the session (app.workflow.calibration.session_processing.process_session: darks, HDR whites, flat
field,
patch values, the matrices, outputs, report) and show the report: ΔE00 per patch on a fixed traffic-light scale
with the patch names, reference -> capture vectors on a*b* and L*C*, the reference | capture mosaic, summary
statistics, the FADGI / ISO 19264 / Metamorfoze badges ("colour accuracy only") with the criteria graded per
metric and those not assessed; export."""
from __future__ import annotations

import html
import logging
import shutil
from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.device_hub import Lab
from dualrgb.app.gui.results_plots import PatchSpectra, TargetPlots, TargetView
from dualrgb.app.gui.units import with_unit
from dualrgb.app.gui.widgets import PathLabel, side_by_side
from dualrgb.app.gui.workers import TaskHandle
from dualrgb.app.processing.characterise import DE2000, LEAST_SQUARES, ROOT_POLYNOMIAL_2, ROOT_POLYNOMIAL_3
from dualrgb.app.workflow.calibration.session_processing import light_sets, subject_entries
from dualrgb.common.progress import CancelToken, ProgressCallback
from dualrgb.core.protocols import Session
from dualrgb.core.vocabulary import Subject, SubjectKind

log = logging.getLogger(__name__)

BADGE_COLOURS = {True: "#2e7d32", False: "#c62828"}
REFERENCE_METHODS = (("eq 4.2 (as simulated)", "eq-4.2"), ("ASTM E308", "astm-e308"))
METHOD_NAMES = {LEAST_SQUARES: "least squares", DE2000: "the ΔE00-optimised matrix",
                ROOT_POLYNOMIAL_2: "the root-polynomial of degree 2",
                ROOT_POLYNOMIAL_3: "the root-polynomial of degree 3"}
METRIC_NAMES = {"colour_mean_de00": "colour mean", "colour_p90_de00": "colour p90", "colour_max_de00": "colour max",
                "tone_max_abs_dl": "tone (ΔL* of the greys)", "white_balance_max_de": "white balance",
                "noise_max_lstar": "noise (L*)", "illuminance_nonuniformity_pct": "uniformity after flat field"}


def process(lab: Lab, session: Session, grids: dict, train_subject: str, test_subject: str | None, optimise: bool,
            progress: ProgressCallback, cancel: CancelToken, lights: list[str] | None = None, method: str | None = None,
            charts: dict | None = None, delivered: str = "", mode: str = "",
            ) -> tuple[object, dict[str, TargetView], Path]:
    """Worker: the TargetSpecs (app.workflow.calibration.targets: reference XYZ integrated by ``method``; ``charts``:
    the
    calibration's own, :func:`calibration_charts`), the one processing path, the plot data of the ``delivered``
    matrix family (the calibration's) when it was fitted, else of the one chosen here. The grids are those placed
    in Target; where none was placed, the charts are found in their frames (app.processing.chart_detect)."""
    from dualrgb.app.processing.report import xyz_to_srgb8
    from dualrgb.app.workflow.calibration.session_processing import process_session
    from dualrgb.app.workflow.calibration.targets import reference_white, target_spec
    from dualrgb.simulation.colorimetry import xyz_to_lab

    mode = mode or (lab.virtual_lab.mode if lab.virtual_lab is not None else lab.mode)
    keys = {label: key for label, key in (("train", train_subject), ("test", test_subject)) if key}
    grids = {**lab.lab_placement(charts or {}), **grids}       # the lab's charts laid too small to be found
    specs = {label: target_spec(mode, Subject.parse(key), grids.get(key), method=method,
                                chart=(charts or {}).get(Subject.parse(key).name)) for label, key in keys.items()}
    for label, spec in specs.items():
        spec.label = f"{label}: {spec.label}"                 # e.g. "train: test (CC24 on film)"
    out_dir = Path(session.path) / "results"
    result = process_session(session, out_dir, specs["train"], specs.get("test"), lights=lights, optimise=optimise,
                             white_xyz=reference_white(mode, method),
                             title=f"dual-RGB capture, {Path(session.path).name}", progress=progress, cancel=cancel,
                             mode=mode)
    c = result.characterisation
    best = c.results[delivered if delivered in c.results else c.best]
    views = {}
    for label, spec in specs.items():
        pred = best.matrix.apply(result.patch_values[label])
        errors = best.errors(label)
        views[label] = TargetView(spec.label, spec.names, np.asarray(errors), xyz_to_lab(spec.xyz, c.white),
                                  xyz_to_lab(pred, c.white), xyz_to_srgb8(spec.xyz, c.white),
                                  xyz_to_srgb8(pred, c.white), spec.layout or (1, len(spec.names)),
                                  patch_spectra(result.spectral, label))
    return result, views, out_dir


def calibration_charts(profile: object | None, chosen: dict) -> tuple[dict, str]:
    """(charts, mode) Results grades with: the calibration's own (its recorded chart files read again and checked
    by their sha256: app.workflow.calibration.charts.charts_of_profile; {}: it used the packaged targets) when there is
    a
    calibration, else the ones chosen in the calibration box."""
    from dualrgb.app.workflow.calibration.charts import charts_of_profile

    if profile is None:
        return dict(chosen), ""
    return charts_of_profile(profile), str(getattr(profile, "mode", "") or "")


def patch_spectra(sc, target: str) -> PatchSpectra | None:
    """The estimated and reference spectra of ``target``'s patches (app.processing.spectral's
    SpectralCharacterisation; None without one)."""
    from dualrgb.simulation.spectral_metrics import spectral_rmse

    if sc is None or target not in sc.estimates:
        return None
    ref, est = sc.references[target], sc.estimates[target]
    return PatchSpectra(sc.wavelengths, ref, est, spectral_rmse(est, ref), sc.selection.chosen.label(),
                        sc.estimator.quantity)


def quality_lines(report: dict) -> list[str]:
    """Per standard: each graded criterion's status, then what was not assessed (report['quality'])."""
    grading = (report.get("quality") or {}).get("grading") or {}
    out = []
    for std, g in grading.items():
        measured = [f"{METRIC_NAMES.get(m, m)} {r['status']}" for m, r in g["metrics"].items()
                    if r["status"] != "not assessed"]
        out.append(f"{std} ({g['scope']}): " + ", ".join(measured))
    if grading:
        first = next(iter(grading.values()))
        out.append("not assessed: " + ", ".join(METRIC_NAMES.get(m, m) for m in first["not_assessed"]))
    return out


class ResultsPanel(QWidget):
    title = "Results"

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx, self.lab = ctx, ctx.lab
        self.result = None
        self.views: dict[str, TargetView] = {}
        self.out_dir: Path | None = None
        self.handle: TaskHandle | None = None
        self.light_sets: dict[str, list[str]] = {}
        self._followed = ""                         # the calibration whose matrix family Results follows
        left = QWidget()
        ll = QVBoxLayout(left)
        for box in (self._process_box(), self._accuracy_box(), self._export_box()):
            ll.addWidget(box)
        ll.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidget(left)
        scroll.setWidgetResizable(True)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)       # labels wrap instead
        left.setMinimumWidth(360)
        self.which = QComboBox()
        self.which.addItems(["test", "train"])
        self.which.setToolTip("Show the test or the training target.")
        self.which.currentTextChanged.connect(lambda _t: self.show_view())
        self.plots = TargetPlots()
        right = QWidget()
        rl = QVBoxLayout(right)
        rl.addWidget(self.which)
        rl.addWidget(self.plots, 1)
        side_by_side(self, scroll, right, sizes=[420, 900])
        self.lab.sessionChanged.connect(self.reload)
        ctx.bus.sessionUpdated.connect(self.reload)
        ctx.workspace.calibrationChanged.connect(self._follow_calibration)
        self.reload()

    # ------------------------------------------------------------------ builders
    def _process_box(self) -> QGroupBox:
        box = QGroupBox("Process the session")
        form = QFormLayout(box)
        self.train_subject = QComboBox()
        self.train_subject.setToolTip("The target the matrix is fitted on.")
        self.test_subject = QComboBox()
        self.test_subject.setToolTip("The target that checks the matrix (the accuracy figures are on this one).")
        self.lights = QComboBox()
        self.lights.setToolTip("Which preset's lights to process (a session may hold captures under several).")
        self.reference = QComboBox()
        for label, key in REFERENCE_METHODS:
            self.reference.addItem(label, key)
        self.reference.setToolTip("How the targets' reference XYZ are integrated from their spectra: eq 4.2 "
                                  "(the thesis' sum, as the simulation uses) or ASTM E308 (the measured spectra at "
                                  "their own wavelengths); they differ by 0.08 mean ΔE00 on the CC24.")
        self.optimise = QCheckBox("also fit the ΔE00-optimised matrix")
        self.optimise.setChecked(self.ctx.get("results/optimise", True, bool))
        self.optimise.toggled.connect(lambda on: self.ctx.set("results/optimise", on))
        self.optimise.setToolTip("Besides least squares, a matrix that minimises the mean ΔE00 directly; the one "
                                 "chosen by cross-validation on the training target is used.")
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
        form.addRow("Reference XYZ", self.reference)
        form.addRow(self.optimise)
        row = QHBoxLayout()
        row.addWidget(self.process_button)
        row.addWidget(self.cancel_button)
        form.addRow(row)
        form.addRow(self.progress)
        form.addRow(self.status)
        return box

    def _accuracy_box(self) -> QGroupBox:
        box = QGroupBox("Accuracy (mean CIEDE2000)")
        lay = QVBoxLayout(box)
        self.summary = QLabel("no results yet")
        self.summary.setWordWrap(True)
        self.summary.setTextFormat(Qt.TextFormat.RichText)
        self.badges = QGridLayout()
        self.quality = QLabel("")
        self.quality.setWordWrap(True)
        self.quality.setToolTip("The report's quality section graded per metric (indicative: see report.json).")
        lay.addWidget(self.summary)
        lay.addLayout(self.badges)
        lay.addWidget(self.quality)
        self.badge_labels: dict[str, QLabel] = {}
        return box

    def _export_box(self) -> QGroupBox:
        box = QGroupBox("Export")
        lay = QVBoxLayout(box)
        self.export_button = QPushButton("Copy report and images to…")
        self.export_button.setToolTip("Copy report.json, the figures, CSVs and TIFF images to a folder you choose.")
        self.export_button.clicked.connect(self._ask_export)
        self.open_button = QPushButton("Open results folder")
        self.open_button.setToolTip("Show the results folder in the file manager.")
        self.open_button.clicked.connect(lambda: self.ctx.open_path(self.out_dir) if self.out_dir else None)
        self.files_label = PathLabel("")
        for w in (self.export_button, self.open_button, self.files_label):
            lay.addWidget(w)
        self.export_button.setEnabled(False)
        self.open_button.setEnabled(False)
        return box

    # ------------------------------------------------------------------ the delivered matrix
    def delivered_method(self) -> str:
        """The matrix family the deliveries use: the current calibration's ('' without one)."""
        profile = self.ctx.workspace.calibration
        return str(profile.statistics.get("best", "")) if profile is not None else ""

    def _follow_calibration(self) -> None:
        """Fit what the calibration fitted: the ΔE00-optimised matrix only when the calibration's choice was made
        among both (otherwise Results would grade a matrix nobody delivered)."""
        profile = self.ctx.workspace.calibration
        if profile is not None and profile.id != self._followed:       # a new calibration, not a new check of it
            self._followed = profile.id
            self.optimise.setChecked(DE2000 in (profile.statistics.get("methods") or {}))

    def comparison_note(self, shown: str) -> str:
        """'' when ``shown`` is the delivered family (or there is no calibration), else what labels it a
        comparison."""
        delivered = self.delivered_method()
        if not delivered or shown == delivered:
            return ""
        return f"comparison only: the deliveries use {METHOD_NAMES.get(delivered, delivered)}"

    # ------------------------------------------------------------------ subjects
    def reload(self) -> None:
        session = self.lab.session
        if session is None:
            return
        self.ctx.runner.submit(lambda: subject_entries(session), pool="compute", name="list targets",
                               on_result=self._fill, on_error=lambda exc: self.ctx.errors.report("Results", exc))

    def _fill(self, subjects: dict) -> None:
        keys = sorted(k for k in subjects if Subject.parse(k).kind is SubjectKind.TARGET)
        names = [n for key in keys for n in subjects[key]]
        self.light_sets = light_sets(list(dict.fromkeys(names)))
        current = self.lights.currentText()
        self.lights.clear()
        self.lights.addItems(list(self.light_sets))
        if current in self.light_sets:
            self.lights.setCurrentText(current)
        for combo, tag in ((self.train_subject, "train"), (self.test_subject, "test")):
            current = combo.currentData() or ""
            combo.clear()
            if combo is self.test_subject:
                combo.addItem("(none)", "")
            for key in keys:
                combo.addItem(Subject.parse(key).label, key)          # labels for people, keys as data
            preferred = current if current in keys else next((k for k in keys if k == Subject.target(tag).key),
                                                             next((k for k in keys if k.endswith(tag)), ""))
            self.select(combo, preferred)

    @staticmethod
    def select(combo: QComboBox, key: str) -> None:
        i = combo.findData(key)
        if i >= 0:
            combo.setCurrentIndex(i)

    # ------------------------------------------------------------------ processing
    def start(self) -> None:
        session = self.lab.session
        if session is None:
            self.ctx.errors.report("Process", "no session: capture darks, flats and the targets first")
            return
        train, test = self.train_subject.currentData() or "", self.test_subject.currentData() or None
        if not train:
            self.ctx.errors.report("Process", "no captured target to fit on: capture one in Calibrate & capture")
            return
        grids, chosen = dict(self.ctx.workspace.grids), dict(self.ctx.workspace.charts)
        profile = self.ctx.workspace.calibration
        optimise, method = self.optimise.isChecked(), self.reference.currentData()
        lights = self.light_sets.get(self.lights.currentText())
        lab, delivered = self.lab, self.delivered_method()

        def work(progress: ProgressCallback, cancel: CancelToken) -> tuple[object, dict[str, TargetView], Path]:
            charts, mode = calibration_charts(profile, chosen)
            return process(lab, session, grids, train, test, optimise, progress, cancel, lights, method, charts,
                           delivered, mode)
        self.process_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.status.setText("processing …")
        self.progress.setValue(0)
        self.handle = self.ctx.runner.submit(
            work,
            pool="compute", name="process session", pass_progress=True, pass_cancel=True,
            on_progress=self._progress,
            on_result=self.show_result, on_error=self._failed, on_finished=self._finished)

    def _progress(self, fraction: float, message: str) -> None:
        self.progress.setValue(int(1000 * fraction))
        self.status.setText(message)

    def _failed(self, exc: BaseException) -> None:
        from dualrgb.common.progress import Cancelled
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
        self.status.setText("done")
        self.ctx.errors.clear("Process the session")

        def stats(d: dict | None) -> str:
            if not d:
                return "—"
            return (f"mean <b>{d['mean']:.2f}</b>, median {d['median']:.2f}, {with_unit('90', '%')} "
                    f"{d['p90']:.2f}, max {d['max']:.2f}")
        delivered = self.delivered_method()
        methods = ", ".join(f"{m}{' (delivered)' if m == delivered else ''}: test {v['test']['mean']:.2f}"
                            if v.get("test") else f"{m}: train {v['train']['mean']:.2f}"
                            for m, v in rep["methods"].items())
        note = self.comparison_note(rep["best_method"])
        label = f"<span style='color:#b26a00; font-weight:bold'>{note}</span><br>" if note else ""
        px = rep.get("per_pixel_de00") or {}
        pixel = "".join(f"<br>per pixel, {k}: mean <b>{v['mean']:.2f}</b>, {with_unit('90', '%')} {v['p90']:.2f}"
                        for k, v in px.items())
        gain = (rep.get("noise_gain") or {}).get("Y")
        pixel += f" (noise gain {gain}, condition number {rep.get('condition_number')})" if px and gain else ""
        self.summary.setText(f"{label}{len(rep['channels'])} channels, matrix <b>{rep['best_method']}</b> "
                             f"({html.escape(rep['best_reason'])})<br>training: {stats(rep['train'])}<br>"
                             f"test: {stats(rep['test'])}{pixel}<br><small>{methods}</small>")
        self._badges(rep["standards"], "comparison, " if note else "")
        self.quality.setText("\n".join(quality_lines(rep)))
        self.files_label.set_path(f"{len(result.files)} files + {len(rep['figures'])} figures in {out_dir}")
        self.export_button.setEnabled(True)
        self.open_button.setEnabled(True)
        self.which.setCurrentText("test" if "test" in views else "train")
        self.show_view()
        self.ctx.bus.resultsReady.emit(rep)

    def _badges(self, standards: dict, prefix: str = "") -> None:
        while self.badges.count():
            item = self.badges.takeAt(0)
            if item is not None and (badge := item.widget()) is not None:
                badge.deleteLater()
        self.badge_labels = {}
        on = standards.get("evaluated_on", "test")
        for r, (std, res) in enumerate(standards["results"].items()):
            level = res["level"]
            badge = QLabel(f"{prefix}{std}, colour accuracy only: {level if level else 'not met'}")
            badge.setWordWrap(True)
            badge.setStyleSheet(f"background:{BADGE_COLOURS[level is not None]}; color:white; border-radius:6px; "
                                "padding:3px 8px; font-weight:bold")
            lines = [f"{name}: {'pass' if v['pass'] else 'fail'} (" + ", ".join(
                f"{k} {v['comparison']} {lim:g}" for k, lim in v["limits"].items()) + ")"
                for name, v in res["levels"].items()]
            badge.setToolTip(f"{std} colour accuracy on the {on} target (indicative: see the report):\n"
                             + "\n".join(lines) + "\nNot a full grade: the other criteria are graded per metric "
                             "below, and some are not assessed at all.")
            self.badges.addWidget(badge, r, 0)
            self.badge_labels[std] = badge

    def show_view(self) -> None:
        view = self.views.get(self.which.currentText())
        if view is not None:
            self.plots.show_view(view)

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
                               on_result=lambda d: self.files_label.set_path(f"copied to {d}"),
                               on_error=lambda exc: self.ctx.errors.report("Export the results", exc))
