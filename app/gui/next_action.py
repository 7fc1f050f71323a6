"""One obvious next action (issue 42): the guide's current step and one highlighted button agree.

The guide (app.gui.guide) marks one step ACTIVE (or WARNING: done once, needs attention); this module finds that
step's button - Devices' Connect, Calibrate & capture's Calibrate, Originals' Add to the queue, Originals'
Capture all waiting - and highlights it (the default button, a blue frame: the text keeps its width, so nothing
moves). Every other step button loses the mark.
"""
from __future__ import annotations

import logging
from collections.abc import Callable, Mapping

from PySide6.QtWidgets import QPushButton, QWidget

from dualrgb.app.workflow.day.day import DayStep, GuideStep, StepState

log = logging.getLogger(__name__)

PRIMARY = "primary"            # the dynamic property the style sheet draws
STYLE = "QPushButton:enabled { border: 2px solid #1565c0; border-radius: 3px; background: #e3f2fd; padding: 3px 8px; }"


def step_button(panels: Mapping[str, QWidget], step: DayStep, sphere_connected: bool) -> QPushButton | None:
    """The button that does ``step`` (None where its panel is missing)."""
    if step is DayStep.CONNECT:
        name = "camera_button" if sphere_connected else "sphere_button"
        button = getattr(panels.get("devices"), name, None)
    elif step is DayStep.CALIBRATE:
        button = getattr(getattr(panels.get("capture"), "calibration", None), "calibrate_button", None)
    elif step is DayStep.ORIGINALS:
        button = getattr(panels.get("originals"), "add_button", None)
    else:
        button = getattr(panels.get("originals"), "capture_all_button", None)
    return button if isinstance(button, QPushButton) else None


def current_step(steps: list[GuideStep]) -> DayStep | None:
    """The step the guide marks as the next thing to do (the first ACTIVE, else the first WARNING)."""
    for wanted in (StepState.ACTIVE, StepState.WARNING):
        for s in steps:
            if s.state is wanted:
                return s.step
    return None


class NextAction:
    """Keeps the highlighted button on the guide's current step."""

    def __init__(self, panels: Mapping[str, QWidget], sphere_connected: Callable[[], bool]):
        self.panels = panels
        self.sphere_connected = sphere_connected
        self.button: QPushButton | None = None

    def buttons(self) -> list[QPushButton]:
        found = (step_button(self.panels, s, c) for s in DayStep for c in (False, True))
        return list({id(b): b for b in found if b is not None}.values())

    def show(self, steps: list[GuideStep]) -> None:
        step = current_step(steps)
        chosen = step_button(self.panels, step, self.sphere_connected()) if step is not None else None
        for b in self.buttons():
            on = b is chosen
            if bool(b.property(PRIMARY)) != on:
                b.setProperty(PRIMARY, on)
                b.setDefault(on)
                b.setStyleSheet(STYLE if on else "")
        self.button = chosen
