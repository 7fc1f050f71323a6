"""The current calibration in Calibrate & capture: make it in one run (auto-exposure, darks and flats at every
planned exposure, the training and test targets, the matrix: app.workflow.stand.copystand.CopyStand.calibrate), show it
(age, camera, ISO, lights, target errors), save it elsewhere, load one, and check it against the stand now - a
mismatch is shown here, in the guide and in Originals before anything is captured.
"""
from __future__ import annotations

import html
import logging
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QCheckBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSpinBox,
    QWidget,
)

from dualrgb.app.gui.calibration_keep import keep_refusal, kept_base
from dualrgb.app.gui.charts_form import ChartsForm
from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.sequence_view import SequenceView
from dualrgb.app.gui.stand_options import CalibrationSampling
from dualrgb.app.gui.viewmodel import calibration_lines
from dualrgb.app.gui.widgets import PathLabel
from dualrgb.app.lab.targets import LAB_TARGET_WIDTH_MM
from dualrgb.app.sequences.base import ProgressEvent
from dualrgb.app.workflow.calibration.charts import charts_of_profile, load_charts
from dualrgb.app.workflow.calibration.profile import (
    CalibrationProfile,
    CameraIdentity,
    ReuseLimits,
    SphereIdentity,
    check_reuse,
    load_profile,
)
from dualrgb.app.workflow.stand.copystand import StandSettings
from dualrgb.app.workflow.stand.defaults import workflow_defaults
from dualrgb.app.workflow.stand.plans import StandPlanner
from dualrgb.app.workflow.stand.run_phases import CALIBRATION_RUN, calibration_clock
from dualrgb.core.engine import Run, RunHooks
from dualrgb.core.protocols import Session
from dualrgb.core.vocabulary import Role, Subject, role_of
from dualrgb.simulation.stand_model import StandModel

log = logging.getLogger(__name__)

RESHOOT, KEEP, CANCEL = "Re-shoot", "Keep", "Cancel"


def calibration_frames(session: Session) -> list:
    """The session's current darks, flats and target frames."""
    return [e for e in session.entries() if role_of(e) in (Role.DARK, Role.FLAT, Role.TARGET)]


class CalibrationBox(QGroupBox):
    def __init__(self, ctx: AppContext, view: SequenceView, stand_settings: Callable[[], StandSettings],
                 plans: Callable[[], StandPlanner], parent: QWidget | None = None):
        super().__init__("Calibration (once a day, or when something changes)", parent)
        self.ctx = ctx
        self.ws = ctx.workspace
        self.view = view
        self.stand_settings = stand_settings
        self.plans = plans
        self.run: Run | None = None
        self.sampling = CalibrationSampling(ctx)            # --target-width-mm, --ppi (app.gui.stand_options)
        self._build()
        self.ws.calibrationChanged.connect(self.show_calibration)
        view.run_event.connect(self._run_event)
        view.finished.connect(self._run_finished)
        for sig in (ctx.lab.cameraChanged, ctx.lab.sphereChanged, ctx.bus.cameraSettingsChanged):
            sig.connect(self.check)
        self.show_calibration()

    # ------------------------------------------------------------------ builders
    def _build(self) -> None:
        form = QFormLayout(self)
        lab = self.ctx.lab
        mode = lab.virtual_lab.mode if lab.virtual_lab is not None else lab.mode    # the mode the day starts in
        d = workflow_defaults(mode)                       # the same defaults as `dualrgb calibrate`
        self.hdr_auto = QCheckBox("also the longer exposures HDR originals may need")
        self.hdr_auto.setChecked(self.ctx.get("calibration/hdr_auto", d.hdr_auto, bool))
        self.hdr_auto.setToolTip("Darks and flats also at the longer exposures of an HDR bracket (as many as the "
                                 "parsimony study found worth it), so dark originals can be captured with this "
                                 "calibration.")
        self.hdr_auto.toggled.connect(lambda on: self.ctx.set("calibration/hdr_auto", on))
        self.dark_frames, self.flat_frames = self._count(d.dark_frames, "darks"), self._count(d.flat_frames, "flats")
        self.de_fit = QCheckBox("also fit the ΔE00-optimised matrix (slower)")
        self.de_fit.setChecked(d.optimise_matrix)
        self.de_fit.setToolTip("Besides least squares; the delivered one is chosen by cross-validation on the "
                               "training target.")
        self.calibrate_button = QPushButton("Calibrate")
        self.calibrate_button.setToolTip("Auto-exposure, darks, flats, the training and test targets and the matrix "
                                         "in one run; the calibration is saved in the session (a new dated one in "
                                         "the captures folder when there is none).")
        self.calibrate_button.clicked.connect(self.calibrate)
        self.summary = QLabel("no calibration yet")
        self.summary.setWordWrap(True)
        self.summary.setTextFormat(Qt.TextFormat.RichText)
        self.save_button = QPushButton("Save as…")
        self.save_button.setToolTip("Write the calibration (JSON + arrays) into a folder you choose, to reuse it "
                                    "on another day or in another session.")
        self.save_button.clicked.connect(self._ask_save)
        self.load_button = QPushButton("Load…")
        self.load_button.setToolTip("Use a saved calibration (its darks, flats and matrix); it is checked against "
                                    "the stand at once.")
        self.load_button.clicked.connect(self._ask_load)
        self.check_button = QPushButton("Check")
        self.check_button.setToolTip("Compare the calibration with the stand now: camera serial and model, ISO, "
                                     "aperture, sphere serial and temperature, age.")
        self.check_button.clicked.connect(self.check)
        row = QHBoxLayout()
        for w in (self.calibrate_button, self.save_button, self.load_button, self.check_button):
            row.addWidget(w)
        form.addRow(row)                                  # the primary action first (issue 42)
        form.addRow(self.summary)
        self.charts = ChartsForm(self.ctx)
        form.addRow(self.charts)
        form.addRow(self.hdr_auto)
        form.addRow("Darks per exposure", self.dark_frames)
        form.addRow("Flats per exposure", self.flat_frames)
        form.addRow(self.de_fit)
        form.addRow(self.sampling)
        self.path_label = PathLabel("")
        form.addRow(self.path_label)

    def _count(self, default: int, what: str) -> QSpinBox:
        spin = QSpinBox()
        spin.setRange(1, 100)
        spin.setValue(self.ctx.get(f"calibration/{what}", default, int))
        spin.setToolTip(f"Frames per exposure time (default {default}{', thesis 8.2.1' if what == 'darks' else ''}).")
        spin.valueChanged.connect(lambda v: self.ctx.set(f"calibration/{what}", v))
        return spin

    # ------------------------------------------------------------------ calibrate
    def calibrate(self) -> None:
        """The whole calibration as one run; without a session one is made first (AppContext.with_session)."""
        ws, lab = self.ws, self.ctx.lab
        if ws.preset is None or not ws.lights:
            self.ctx.errors.report("Calibrate", "choose the preset whose lights the day uses first")
            return
        try:
            plan = self.plans().auto_exposure(list(ws.lights)).plan()
            if lab.camera is None or lab.sphere is None:
                raise ValueError("connect the LED sphere and the camera in Devices first")
            charts = load_charts(self.charts.choices(), ws.preset.mode)     # a chart file's problem: before the light
            start = self.sampling.measured(ws.preset.sources)       # a measured curve's problem: before the light
        except ValueError as exc:
            self.ctx.errors.report("Calibrate", exc)
            return
        ws.set_charts(charts)
        if lab.session is not None and calibration_frames(lab.session):
            self._ask_reshoot(plan, charts, start)
            return
        self.ctx.with_session(lambda: self._start(plan, charts, start), "the calibration")

    def _ask_reshoot(self, plan: list, charts: dict, start: StandModel | None) -> None:
        """The session holds calibration frames: re-shoot them (in a new dated session: this one keeps its frames
        and delivered originals, the waiting ones move along), keep them (a calibration computed again from them,
        nothing lit; offered only where the session allows it: app.gui.calibration_keep), or cancel."""
        session = self.ctx.lab.session
        n = len(calibration_frames(session)) if session is not None else 0
        refusal = keep_refusal(session, charts, list(self.ws.lights)) if session is not None else "no session"
        choices = (RESHOOT, CANCEL) if refusal else (RESHOOT, KEEP, CANCEL)
        text = (f"This session already holds {n} calibration frames (darks, flats, targets). Re-shoot them in a new "
                "session (this one keeps its frames and delivered originals; waiting originals move along), "
                + (f"or cancel? They cannot be kept: {refusal}." if refusal else
                   "keep them and compute the calibration again (nothing is lit), or cancel?"))

        def answer(choice: str) -> None:
            if choice == RESHOOT:
                old = self.ctx.lab.session
                self.ctx.lab.set_session(None)
                if old is not None:
                    old.close()                      # its writer lock given back: it can be opened again
                self.ctx.with_session(lambda: self._start(plan, charts, start), "the re-shot calibration")
            elif choice == KEEP:
                self._start(plan, charts, start, keep=True)
        self.ctx.asker.ask("Calibrate again?", text, choices, answer, default=CANCEL)

    def _start(self, plan: list, charts: dict | None = None, stand_start: StandModel | None = None,
               keep: bool = False) -> None:
        """The calibration run; ``keep``: computed again from the session's frames at their exposures, nothing lit
        (app.gui.calibration_keep)."""
        ws, lab = self.ws, self.ctx.lab
        settings = self.stand_settings()
        settings.dark_frames, settings.flat_frames = self.dark_frames.value(), self.flat_frames.value()
        settings.optimise_matrix = self.de_fit.isChecked()
        settings.ppi, settings.target_width_mm = (self.sampling.stand_fields()[k] for k in ("ppi", "target_width_mm"))
        settings.stand_start = stand_start
        settings.charts = dict(charts or {})
        preset, lights, hdr = ws.preset, list(ws.lights), self.hdr_auto.isChecked()
        placed = {**lab.lab_placement(settings.charts), **ws.grids}     # by hand in Target; the lab: too small ones
        grids = {n: placed[Subject.target(n).key] for n in ("train", "test") if Subject.target(n).key in placed}
        if lab.virtual_lab is not None and not settings.ppi and not settings.target_width_mm:
            settings.target_width_mm = LAB_TARGET_WIDTH_MM          # what the technician would type for its target
        base_kept = kept_base(lab.session) if keep and lab.session is not None else {}

        def work(hooks: RunHooks) -> CalibrationProfile:      # one run (its plans' event: 'plan', 'base', ...)
            lab.lab_charts(settings.charts)                         # the virtual lab's stand holds these charts
            if not keep:
                return lab.copy_stand(settings, hooks).calibrate(preset, hdr_auto=hdr, grids=grids)
            stand = lab.copy_stand(settings, hooks, unlit=True)     # Keep: the session's frames, nothing lit
            return stand.calibrate_at(preset, {nl.name: base_kept[nl.name] for nl in lights}, hdr_auto=hdr,
                                      grids=grids)
        try:
            lab.copy_stand(settings)                                # refuses early: devices, session
        except ValueError as exc:
            self.ctx.errors.report("Calibrate", exc)
            return
        clock = calibration_clock(plan, settings.settle_s, self.view.overhead_s, record=not keep)   # time left
        self.run = Run(CALIBRATION_RUN, plan, work, clock=clock)
        self.view.start(self.run)

    def _run_event(self, ev: ProgressEvent) -> None:
        if self.run is None or self.view.seq is not self.run:
            return
        if "base" in ev.data:
            self.ws.set_base_exposures(ev.data["base"])
        if "exposures" in ev.data:
            self.ws.set_run_plan(ev.data["exposures"])

    def _run_finished(self, run, outcome: str) -> None:
        if run is not self.run or run is None:
            return
        self.ws.set_run_plan({})
        if outcome == "done" and run.result is not None:
            self.ws.set_calibration(run.result)
            self.ctx.set("calibration/last", str(run.result.path or ""))
            self.check()

    # ------------------------------------------------------------------ save, load, check
    def _ask_save(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Save the calibration into", str(self.ctx.captures_dir))
        if folder:
            self.save_to(Path(folder))

    def save_to(self, folder: Path) -> None:
        profile = self.ws.calibration
        if profile is None:
            self.ctx.errors.report("Save the calibration", "no calibration yet: calibrate or load one")
            return
        self.ctx.runner.submit(lambda: profile.save(folder), pool="compute", name="save calibration",
                               on_result=self._saved,
                               on_error=lambda exc: self.ctx.errors.report("Save the calibration", exc))

    def _saved(self, path: Path) -> None:
        self.ctx.set("calibration/last", str(path))
        self.ctx.lab.message.emit(f"calibration saved: {path}")
        self.show_calibration()

    def _ask_load(self) -> None:
        start = self.ctx.get("calibration/last", "", str) or str(self.ctx.captures_dir)
        path, _ = QFileDialog.getOpenFileName(self, "Load a calibration", start, "Calibrations (*.json)")
        if path:
            self.load(Path(path))

    def load(self, path: Path) -> None:
        """Use a saved calibration, and the charts it was made with (Target and Results grade with them)."""
        def read() -> tuple[CalibrationProfile, dict]:
            profile = load_profile(path)
            return profile, charts_of_profile(profile)

        def loaded(result: tuple[CalibrationProfile, dict]) -> None:
            profile, charts = result
            self.ws.set_charts(charts)
            self.ws.set_calibration(profile)
            self.ctx.set("calibration/last", str(path))
            self.ctx.errors.clear("Load the calibration")
            self.check()
        self.ctx.runner.submit(read, pool="compute", name="load calibration",
                               on_result=loaded,
                               on_error=lambda exc: self.ctx.errors.report("Load the calibration", exc))

    def check(self) -> None:
        """Compare the calibration with the stand now (a device call; skipped while a sequence owns them)."""
        profile, lab = self.ws.calibration, self.ctx.lab
        if profile is None or lab.camera is None or lab.sphere is None or self.ws.running:
            return
        cam, sphere = lab.camera, lab.sphere
        lab.device_call(lambda: check_reuse(profile, CameraIdentity.of(cam), SphereIdentity.of(sphere),
                                            limits=ReuseLimits()),
                        "Check the calibration",
                        on_result=lambda c: self.ws.set_calibration_check(c) if self.ws.calibration is profile
                        else None)

    def show_calibration(self) -> None:
        profile, check = self.ws.calibration, self.ws.calibration_check
        self.save_button.setEnabled(profile is not None)
        self.check_button.setEnabled(profile is not None)
        self.path_label.set_path(str(profile.path) if profile is not None and profile.path else "")
        if profile is None:
            self.summary.setText("no calibration yet: press Calibrate, or Load a saved one")
            return
        lines = []
        for line in calibration_lines(profile, check):
            text = html.escape(line)
            bad = line.startswith("does not match") or "old (over" in line
            lines.append(f"<span style='color:#c62828; font-weight:bold'>{text}</span>" if bad else text)
        self.summary.setText("<br>".join(lines))

    def set_locked(self, locked: bool) -> None:
        for w in (self.calibrate_button, self.load_button, self.check_button, self.hdr_auto, self.dark_frames,
                  self.flat_frames, self.de_fit, self.charts):
            w.setEnabled(not locked)
        if not locked:
            self.show_calibration()
