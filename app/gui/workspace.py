"""The one typed object the panels share (replaces the untyped ``ctx.shared`` dict): what the technician has set
up so far - patch grids, the preset's lights and exposures, the HDR brackets planned, the current calibration
and its check against the stand, the queue of originals, whether a sequence owns the devices - with a Qt signal
for every change. Panels read it and listen to it; none imports another panel.
"""
from __future__ import annotations

import logging
from typing import Any

import numpy as np
from PySide6.QtCore import QObject, Signal

from dualrgb.app.gui.units import light_pct
from dualrgb.app.processing.patches import PatchGrid
from dualrgb.app.workflow.calibration.profile import CalibrationProfile, ReuseCheck
from dualrgb.app.workflow.day.day import OriginalsQueue
from dualrgb.app.workflow.stand.plans import calibration_exposures
from dualrgb.core.protocols import Session
from dualrgb.core.vocabulary import NamedLight
from dualrgb.simulation.lightsource import N_SPHERE_LEDS

log = logging.getLogger(__name__)


class Workspace(QObject):
    gridsChanged = Signal(str)             # subject key whose patch grid was placed (Target)
    lightsChanged = Signal()               # preset, lights or base exposures (Calibrate & capture)
    planChanged = Signal()                 # the exposures the captures use (base + HDR brackets, a run's plan)
    calibrationChanged = Signal()          # a calibration made, loaded or cleared, or its check
    queueChanged = Signal()                # the originals queue
    runningChanged = Signal(str)           # the name of the sequence that owns the devices, '' when none
    manualLevelsChanged = Signal(object)   # the Light source sliders (np.ndarray (10,), 0..1)

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        self.grids: dict[str, PatchGrid] = {}
        self.last_grid: PatchGrid | None = None
        self.preset: Any = None                           # simulation.presets.Preset
        self.lights: list[NamedLight] = []
        self.base_exposures: dict[str, float] = {}
        self.hdr_brackets: dict[str, set[float]] = {}     # every HDR exposure planned in this session, per light
        self.run_plan: dict[str, list[float]] = {}        # a running calibration's plan
        self.calibration: CalibrationProfile | None = None
        self.calibration_check: ReuseCheck | None = None
        self.charts: dict[str, Any] = {}                  # 'train' / 'test' -> the stand's own chart (charts)
        self.queue = OriginalsQueue()
        self.running = ""
        self.manual_levels = np.zeros(N_SPHERE_LEDS)

    # ---- grids ----
    def set_grid(self, key: str, grid: PatchGrid) -> None:
        self.grids[key] = grid
        self.last_grid = grid
        self.gridsChanged.emit(key)

    # ---- lights and exposures ----
    def set_lights(self, preset: Any, lights: list[NamedLight], base: dict[str, float]) -> None:
        self.preset, self.lights, self.base_exposures = preset, list(lights), dict(base)
        self.lightsChanged.emit()
        self.planChanged.emit()

    def set_base_exposures(self, base: dict[str, float]) -> None:
        self.base_exposures = dict(base)
        self.lightsChanged.emit()
        self.planChanged.emit()

    def add_hdr_brackets(self, brackets: dict[str, list[float]]) -> None:
        for name, ts in brackets.items():
            self.hdr_brackets.setdefault(name, set()).update(float(t) for t in ts)
        self.planChanged.emit()

    def set_run_plan(self, plan: dict[str, list[float]]) -> None:
        self.run_plan = {k: list(v) for k, v in plan.items()}
        self.planChanged.emit()

    def reset_session_plan(self) -> None:
        """A new session: its HDR brackets start empty."""
        self.hdr_brackets = {}
        self.run_plan = {}
        self.planChanged.emit()

    def planned_exposures(self, session: Session | None) -> dict[str, list[float]]:
        """Per light: every exposure the captures use (the base exposures, HDR brackets, a running calibration's
        plan, the current calibration's exposures for these lights, what the session holds): what darks and flats
        must cover (app.workflow.stand.plans)."""
        base = {n: [t] for n, t in self.base_exposures.items()}
        made = self.calibration.exposures if self.calibration is not None else {}
        for plan in (self.run_plan, made):
            for n, ts in plan.items():
                if n in base or plan is self.run_plan:
                    base.setdefault(n, []).extend(ts)
        return calibration_exposures(session, base, {k: sorted(v) for k, v in self.hdr_brackets.items()})

    # ---- charts ----
    def set_charts(self, charts: dict[str, Any]) -> None:
        """The stand's own charts the calibration uses (simulation.charts.Chart per target; {}: the packaged
        targets): Target takes their layouts, Results their reference data."""
        self.charts = dict(charts)
        self.gridsChanged.emit("")

    # ---- calibration ----
    def set_calibration(self, profile: CalibrationProfile | None) -> None:
        self.calibration = profile
        self.calibration_check = None
        self.calibrationChanged.emit()

    def set_calibration_check(self, check: ReuseCheck | None) -> None:
        self.calibration_check = check
        self.calibrationChanged.emit()

    @property
    def calibration_refused(self) -> bool:
        return self.calibration_check is not None and not self.calibration_check.ok

    # ---- originals, running, manual light ----
    def queue_changed(self) -> None:
        self.queueChanged.emit()

    def set_running(self, name: str) -> None:
        if name != self.running:
            self.running = name
            self.runningChanged.emit(name)

    def light_text(self, label: str) -> str:
        """A light's label as the sequences write it ('(1, 6, 8) @ (...)') with its levels in % when it is one of
        the preset's or the calibration's lights."""
        known = list(self.lights) + (list(self.calibration.lights) if self.calibration is not None else [])
        for nl in known:
            if nl.light.label() == label:
                return light_pct(nl.light)
        return label

    def set_manual_levels(self, levels: np.ndarray) -> None:
        self.manual_levels = np.asarray(levels, dtype=float).copy()
        self.manualLevelsChanged.emit(self.manual_levels)
