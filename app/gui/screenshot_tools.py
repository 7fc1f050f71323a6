"""The screenshot run's steps for issue 30's panels (app.gui.screenshots calls :func:`tool_steps` after the
originals are delivered): live view with the zoom box, focus plot and framing light; re-delivery with the window's
calibration; measuring the camera (a short sweep) and the LEDs (a short warm-up) on the virtual lab."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

Step = tuple[str, Callable[[], Callable[[], bool] | None]]


def tool_steps(run: Any) -> list[Step]:
    """``run``: the ScreenshotRun (its window ``w`` and ``shoot``)."""
    w = run.w
    tools = w.tools

    def focus() -> Callable[[], bool]:
        w.show_panel("camera")
        w.camera.live_button.setChecked(True)
        w.camera.framing_box.check.setChecked(True)
        w.camera.peaking.setChecked(True)                  # issue 42: focus peaking, the grid, the box at 200 %
        w.camera.grid.setChecked(True)
        w.camera.focus.magnification.setCurrentIndex(1)
        return lambda: len(w.camera.focus.values) >= 8

    def live_off() -> None:
        w.camera.live_button.setChecked(False)

    def redeliver() -> Callable[[], bool]:
        w.show_panel("tools")
        tools.tabs.setCurrentWidget(tools.redeliver)
        tools.redeliver.calibration.setCurrentIndex(tools.redeliver.calibration.findData("current"))
        tools.redeliver.start()
        return lambda: tools.redeliver.outcome != ""

    def camera() -> Callable[[], bool]:
        view = tools.measure_camera
        tools.tabs.setCurrentWidget(view)
        view.step_nm.setValue(20.0)
        view.frames.setValue(1)
        view.start()
        return lambda: view.view.outcome != ""

    def leds() -> Callable[[], bool]:
        view = tools.measure_leds
        tools.tabs.setCurrentWidget(view)
        view.warmup_min.setValue(0.5)
        view.start()
        return lambda: view.view.outcome != ""
    return [("live view: focus and framing", focus), ("screenshot camera focus", lambda: run.shoot("camera",
                                                                                                    "camera-focus")),
            ("live view off", live_off),
            ("re-deliver", redeliver), ("screenshot re-deliver", lambda: run.shoot("tools", "tools-redeliver")),
            ("measure the camera", camera), ("screenshot camera measurement", lambda: run.shoot("tools",
                                                                                               "tools-camera")),
            ("measure the LEDs", leds), ("screenshot LED measurement", lambda: run.shoot("tools", "tools-leds"))]


def viewer_steps(run: Any) -> list[Step]:
    """The viewer (issue 42): the shadow original's delivered master at 400 % with the clipping and
    under-exposure overlay, centred where the overlay marks most."""
    w = run.w
    org = w.originals

    def load() -> Callable[[], bool]:
        w.show_panel("originals")
        org.tabs.setCurrentWidget(org.viewer)
        org.select("ACC-1902-03")
        return lambda: org.viewer.picture is not None and "ACC-1902-03" in org.viewer.picture.title

    def zoom() -> None:
        import numpy as np
        from PySide6.QtCore import QPointF

        pic = org.viewer.picture
        marked = np.argwhere(pic.clipped | pic.under) if pic is not None else np.zeros((0, 2))
        h, wd = pic.shape if pic is not None else (0, 0)
        y, x = marked.mean(axis=0) if len(marked) else (h / 2, wd / 2)
        org.viewer.set_zoom(4.0, QPointF(float(x), float(y)))

    return [("viewer: the shadow original", load), ("viewer at 400 %", zoom),
            ("screenshot viewer", lambda: run.shoot("originals", "viewer-400"))]
