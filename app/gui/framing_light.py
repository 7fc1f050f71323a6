"""The framing light: a low light while the technician frames and focuses in live view, so the view does not go
black when a lit period reaches its cap (issue 30).

The rule (docs/notes/issue-30-tools.md):
* level: at most :data:`MAX_FRAMING_LEVEL` (5 %) of full on every LED: the day's first light scaled so that its
  brightest LED sits at the chosen framing level (default 2 %), or every LED at that level when no preset is set;
* every lit period is capped like any manual light (the Light source panel's limit, at most 10 s): the sphere is
  switched on with ``ON <ms>`` (the firmware switches itself off at the cap, whatever the host does) and the
  driver's supervisor thread switches off at the same deadline. A lit period is never extended - not by the
  keepalive (``PING`` only restarts the sphere's watchdog) nor by switching on again while lit (the driver and
  the firmware count from the first switch-on);
* so the framing light is renewed, not extended: :data:`RENEW_MARGIN_S` before the cap the window switches the
  light off (read back) and on again - a new lit period, again capped. The view is dark for the switch-off round
  trip only (tens of ms on the emulator); a renewal that comes late (the devices thread busy) finds the light
  already off at the cap and starts a new period;
* if the GUI dies or hangs, nothing renews it: the light goes off at the cap, at the latest by the firmware;
* counted in the light dose: the status polls count what the sphere reports lit (app.gui.viewmodel.DoseFeed,
  the Light source panel's dose) and this object keeps its own tally (level x seconds lit, per LED at most 5 %);
* it stops after :data:`MAX_FRAMING_S` of framing (start it again to go on), when live view stops, when a
  sequence takes the devices, when the sphere goes, and when the window closes.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtWidgets import QCheckBox, QDoubleSpinBox, QGroupBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from dualrgb.app.gui.device_hub import Lab
from dualrgb.app.gui.workspace import Workspace
from dualrgb.simulation.lightsource import N_SPHERE_LEDS, LightSource

log = logging.getLogger(__name__)

MAX_FRAMING_LEVEL = 0.05         # of full, per LED
DEFAULT_FRAMING_LEVEL = 0.02
RENEW_MARGIN_S = 1.0             # renew this long before the cap (the devices thread may be busy with a preview)
MAX_FRAMING_S = 300.0            # one framing lasts at most 5 min (then it stops; start it again)


def framing_light(first: LightSource | None, level: float) -> LightSource:
    """The framing light: ``first`` (the day's first light) scaled so its brightest LED is at ``level`` (at most
    :data:`MAX_FRAMING_LEVEL`), else every LED at ``level``."""
    level = min(max(float(level), 0.0), MAX_FRAMING_LEVEL)
    if first is not None and max(first.levels, default=0.0) > 0:
        levels = np.asarray(first.levels, dtype=float)
        return LightSource(first.leds, tuple(float(v) for v in levels * (level / float(levels.max()))),
                           name="framing")
    return LightSource(tuple(range(1, N_SPHERE_LEDS + 1)), (level,) * N_SPHERE_LEDS, name="framing")


@dataclass
class FramingPeriod:
    """One lit period the framing light asked for (host monotonic clock)."""

    t_on: float
    max_on_s: float
    levels: tuple[float, ...]


class FramingLight(QObject):
    """Keeps the framing light on in capped lit periods (module docstring) while ``active``."""

    changed = Signal(bool, str)            # active, one line for the panel

    def __init__(self, lab: Lab, workspace: Workspace, parent: QObject | None = None):
        super().__init__(parent)
        self.lab, self.ws = lab, workspace
        self.level = DEFAULT_FRAMING_LEVEL
        self.active = False
        self.periods: list[FramingPeriod] = []
        self._open: FramingPeriod | None = None     # the period not yet added to the tally
        self.level_seconds = 0.0           # sum over periods of (brightest LED level x seconds lit), at most 5 % x t
        self._started = 0.0
        self._renew = QTimer(self)
        self._renew.setSingleShot(True)
        self._renew.timeout.connect(self._renew_period)
        self._stop_timer = QTimer(self)
        self._stop_timer.setSingleShot(True)
        self._stop_timer.timeout.connect(lambda: self.stop(f"stopped after {MAX_FRAMING_S / 60:g} min of framing"))
        lab.sphereChanged.connect(lambda: self.stop("the sphere was disconnected") if lab.sphere is None else None)
        workspace.runningChanged.connect(lambda name: self.stop(f"{name} is running") if name else None)
        lab.lightApplied.connect(lambda _light: self.stop("a light was set by hand"))    # (Light source panel)

    @property
    def cap_s(self) -> float:
        """Each lit period's cap: the manual light's (Light source panel), at most 10 s."""
        return float(self.lab.manual_max_on_s)

    def light(self) -> LightSource:
        first = self.ws.lights[0].light if self.ws.lights else None
        return framing_light(first, self.level)

    def set_level(self, level: float) -> None:
        self.level = min(max(float(level), 0.0), MAX_FRAMING_LEVEL)
        if self.active:
            self._switch_on()

    def start(self) -> bool:
        if self.active:
            return True
        if self.lab.sphere is None:
            self.changed.emit(False, "framing light: connect the LED sphere first")
            return False
        if self.ws.running:
            self.changed.emit(False, f"framing light: {self.ws.running} is running")
            return False
        self.active = True
        self._started = time.monotonic()
        self._stop_timer.start(int(MAX_FRAMING_S * 1000))
        self._switch_on()
        return True

    def stop(self, why: str = "") -> None:
        if not self.active:
            return
        self.active = False
        self._renew.stop()
        self._stop_timer.stop()
        self._close_period()
        self.lab.set_light_on(False)                   # every LED 0, light off, read back (errors: a dialog)
        self.changed.emit(False, f"framing light off{': ' + why if why else ''}; {self.tally()}")

    def tally(self) -> str:
        lit = sum(min(time.monotonic(), p.t_on + p.max_on_s) - p.t_on for p in self.periods)
        return f"{len(self.periods)} lit periods, {lit:.0f} s lit, {100 * self.level_seconds:.3g} %·s at most per LED"

    # ------------------------------------------------------------------ lit periods
    def _switch_on(self, renewal: bool = False) -> None:
        sphere, light, cap = self.lab.sphere, self.light(), self.cap_s
        if sphere is None:
            self.stop("the sphere was disconnected")
            return
        previous = self._open
        self._close_period()
        # a renewal that finds the light off well before the previous period's cap: someone switched it off
        off_by_hand_before = previous.t_on + previous.max_on_s - RENEW_MARGIN_S / 2 if renewal and previous else 0.0

        def work() -> bool:
            lit = sphere.lit_period is not None
            if renewal and not lit and time.monotonic() < off_by_hand_before:
                return False
            if lit:
                sphere.off()                            # read back; the next period starts from dark
            sphere.apply(light)                         # the framing levels, whatever was set meanwhile
            sphere.on(max_on_s=cap)
            return True

        def done(renewed: bool) -> None:
            if not renewed:
                self.stop("the light was switched off")

        def failed(_exc: BaseException) -> None:
            self.active = False
            self._renew.stop()
            self.changed.emit(False, "framing light off: the sphere refused (see the error)")
        self._open = FramingPeriod(time.monotonic(), cap, tuple(light.levels))
        self.periods.append(self._open)
        self.lab.device_call(Lab.light_call(sphere, work), "Framing light", on_result=done, on_error=failed,
                             on_finished=self.lab.poll_status)
        self._renew.start(int(max(cap - RENEW_MARGIN_S, 0.2) * 1000))
        self.changed.emit(True, f"framing light on at {100 * max(light.levels):.3g} % (each lit period at most "
                                f"{cap:g} s, renewed)")

    def _renew_period(self) -> None:
        if self.active:
            self._switch_on(renewal=True)

    def _close_period(self) -> None:
        p, self._open = self._open, None
        if p is not None:
            lit = max(0.0, min(time.monotonic(), p.t_on + p.max_on_s) - p.t_on)
            self.level_seconds += max(p.levels, default=0.0) * lit


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
