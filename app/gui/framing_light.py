"""The framing light in the window: a low light while the technician frames and focuses in live view, so the view
does not go black when a lit period reaches its cap (issue 30).

The light itself is a plan of the run engine (app.workflow.stand.light_plans.FramingLight, run by
app.gui.device_hub.Lab.run_light in the ``light`` pool): it never switches the sphere itself. The rule
(docs/notes/issue-30-tools.md):
* level: at most :data:`MAX_FRAMING_LEVEL` (5 %) of full on every LED: the day's first light scaled so that its
  brightest LED sits at the chosen framing level (default 2 %), or every LED at that level when no preset is set;
* every lit period is capped like any manual light (the Light source panel's limit, at most 10 s): the sphere is
  switched on with ``ON <ms>`` (the firmware switches itself off at the cap, whatever the host does) and the
  driver's supervisor thread switches off at the same deadline. A lit period is never extended;
* so the framing light is renewed, not extended: :data:`RENEW_MARGIN_S` before the cap the plan switches the
  light off (read back) and on again - a new lit period, again capped;
* if the host hangs or dies, nothing renews it: the light goes off at the cap, at the latest by the firmware;
* counted in the light dose: the engine counts every lit period (in the session's manifest when one is open), the
  status polls count what the sphere reports lit (app.gui.viewmodel.DoseFeed, the Light source panel's dose) and
  this object shows the plan's own tally (level x seconds lit, per LED at most 5 %);
* it stops after :data:`MAX_FRAMING_S` of framing (start it again to go on), when live view stops, when a
  sequence starts (its run waits for this one to end dark), when a light is set or switched by hand, when the
  sphere goes, and when the window closes.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import QCheckBox, QDoubleSpinBox, QGroupBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from dualrgb.app.gui.device_hub import Lab
from dualrgb.app.gui.workspace import Workspace
from dualrgb.app.workflow.stand.light_plans import (
    DEFAULT_FRAMING_LEVEL,
    MAX_FRAMING_LEVEL,
    MAX_FRAMING_S,
    RENEW_MARGIN_S,
    FramingPeriod,
    framing_light,
)
from dualrgb.app.workflow.stand.light_plans import FramingLight as FramingPlan
from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)

__all__ = ["DEFAULT_FRAMING_LEVEL", "MAX_FRAMING_LEVEL", "MAX_FRAMING_S", "RENEW_MARGIN_S", "FramingBox",
           "FramingLight", "framing_light"]


class FramingLight(QObject):
    """Starts and stops the framing light's plan (module docstring) and says what it does."""

    changed = Signal(bool, str)            # active, one line for the panel

    def __init__(self, lab: Lab, workspace: Workspace, parent: QObject | None = None):
        super().__init__(parent)
        self.lab, self.ws = lab, workspace
        self.level = DEFAULT_FRAMING_LEVEL
        self.plan: FramingPlan | None = None
        self._why = ""
        self._last_periods: list[FramingPeriod] = []     # the periods of the last framing, once it ended
        self._level_seconds = 0.0
        lab.sphereChanged.connect(lambda: self.stop("the sphere was disconnected") if lab.sphere is None else None)
        workspace.runningChanged.connect(lambda name: self.stop(f"{name} is running") if name else None)
        lab.lightApplied.connect(lambda _light: self.stop("a light was set by hand"))    # (Light source panel)

    @property
    def active(self) -> bool:
        return self.plan is not None

    @property
    def periods(self) -> list[FramingPeriod]:
        return list(self.plan.periods) if self.plan is not None else list(self._last_periods)

    @property
    def cap_s(self) -> float:
        """Each lit period's cap: the manual light's (Light source panel), at most 10 s."""
        return float(self.lab.manual_max_on_s)

    def light(self) -> LightSource:
        first = self.ws.lights[0].light if self.ws.lights else None
        return framing_light(first, self.level)

    def set_level(self, level: float) -> None:
        self.level = min(max(float(level), 0.0), MAX_FRAMING_LEVEL)
        if self.plan is not None:
            self.plan.change(self.light())

    def start(self) -> bool:
        if self.plan is not None:
            return True
        if self.lab.sphere is None:
            self.changed.emit(False, "framing light: connect the LED sphere first")
            return False
        if self.ws.running:
            self.changed.emit(False, f"framing light: {self.ws.running} is running")
            return False
        self.lab.stop_light()                          # a manual light held on ends first (dark, read back)
        plan = FramingPlan(self.light(), self.cap_s)
        self.plan, self._why = plan, ""
        handle = self.lab.run_light(plan, "Framing light", on_finished=lambda outcome: self._ended(plan, outcome))
        if handle is None:
            self.plan = None
            return False
        self.changed.emit(True, f"framing light on at {100 * max(plan.light.levels):.3g} % (each lit period at "
                                f"most {plan.cap_s:g} s, renewed)")
        return True

    def stop(self, why: str = "") -> None:
        """End the framing light (its run ends dark, read back)."""
        plan = self.plan
        if plan is None:
            return
        self._why = why
        plan.cancel()
        self._ended(plan, "cancelled")

    def _ended(self, plan: FramingPlan, outcome: str) -> None:
        if self.plan is not plan:
            return
        self.plan, self._last_periods = None, list(plan.periods)
        self._level_seconds = plan.level_seconds()
        why = self._why or plan.ended or ("the light was switched off" if outcome == "cancelled"
                                          else "the sphere refused (see the error)" if outcome == "failed" else "")
        self.changed.emit(False, f"framing light off{': ' + why if why else ''}; {self.tally()}")

    @property
    def level_seconds(self) -> float:
        """Sum over periods of (brightest LED level x seconds lit), at most 5 % x t."""
        return self.plan.level_seconds() if self.plan is not None else self._level_seconds

    def tally(self) -> str:
        now = time.monotonic()
        lit = sum(p.lit_s(now) for p in self.periods)
        return (f"{len(self.periods)} lit periods, {lit:.0f} s lit, {100 * self.level_seconds:.3g} %·s at most "
                "per LED")


class FramingBox(QGroupBox):
    """The Camera panel's controls: the framing light on / off and its level (0.5..5 %), one line of state."""

    def __init__(self, framing: FramingLight, ctx_get: Callable[..., Any], ctx_set: Callable[[str, Any], None],
                 parent: QWidget | None = None):
        super().__init__("Framing and focus", parent)
        self.framing = framing
        self.check = QCheckBox("Framing light")
        self.check.setToolTip(f"A low light while framing in live view: at most {100 * MAX_FRAMING_LEVEL:g} % of "
                              "full, in lit periods each capped like the manual light and renewed before the cap "
                              "(off and on again: never extended), counted in the light dose; off when live view "
                              f"stops, a sequence starts, or after {MAX_FRAMING_S / 60:g} min.")
        self.check.toggled.connect(self._toggled)
        self.level = QDoubleSpinBox()
        self.level.setRange(0.5, 100 * MAX_FRAMING_LEVEL)
        self.level.setDecimals(1)
        self.level.setSingleStep(0.5)
        self.level.setSuffix("\u00a0% of full")
        self.level.setValue(min(max(ctx_get("camera/framing_level_pct", 100 * DEFAULT_FRAMING_LEVEL, float), 0.5),
                                100 * MAX_FRAMING_LEVEL))
        self._set = ctx_set
        self.level.valueChanged.connect(self._level_changed)
        framing.set_level(self.level.value() / 100)
        self.state = QLabel("")
        self.state.setWordWrap(True)
        framing.changed.connect(self._changed)
        layout = QVBoxLayout(self)
        row = QHBoxLayout()
        row.addWidget(self.check)
        row.addWidget(self.level)
        layout.addLayout(row)
        layout.addWidget(self.state)

    def _level_changed(self, pct: float) -> None:
        self._set("camera/framing_level_pct", float(pct))
        self.framing.set_level(pct / 100)

    def _toggled(self, on: bool) -> None:
        if on and not self.framing.start():
            self.check.setChecked(False)
        elif not on:
            self.framing.stop()

    def _changed(self, active: bool, line: str) -> None:
        self.state.setText(line)
        if self.check.isChecked() != active:
            self.check.blockSignals(True)
            self.check.setChecked(active)
            self.check.blockSignals(False)
