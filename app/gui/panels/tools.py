"""Tools: what the CLI does at the copy stand beyond the day's capture (issue 30), one tab each - re-deliver a
session with another calibration (``dualrgb process``: app.gui.redeliver_view), measure the camera (``dualrgb
measure csrf``) and measure the LEDs (``dualrgb measure leds`` / ``import-leds``: app.gui.measure_views)."""
from __future__ import annotations

from PySide6.QtWidgets import QTabWidget, QVBoxLayout, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.measure_views import CameraMeasureView, LedMeasureView
from dualrgb.app.gui.redeliver_view import RedeliverView


class ToolsPanel(QWidget):
    title = "Tools"

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.redeliver = RedeliverView(ctx)
        self.measure_camera = CameraMeasureView(ctx)
        self.measure_leds = LedMeasureView(ctx)
        self.tabs = QTabWidget()
        self.tabs.addTab(self.redeliver, "Re-deliver")
        self.tabs.addTab(self.measure_camera, "Measure the camera")
        self.tabs.addTab(self.measure_leds, "Measure the LEDs")
        QVBoxLayout(self).addWidget(self.tabs)

    def cancel_running(self) -> None:
        for view in (self.redeliver, self.measure_camera, self.measure_leds):
            view.cancel_running()

    def shutdown(self) -> None:
        self.cancel_running()
