"""Run by tests/gui/test_xcb_display.py in a child process on a real X display (Xvfb): the window on Qt's xcb
plugin, clicked through connect -> capture -> results with real mouse clicks (QTest), driven by a QTimer step
list (no processEvents loop). Writes what it saw as JSON to argv[1]; exit status 0 when every step passed.

    DISPLAY=:99 QT_QPA_PLATFORM=xcb python -m tests.gui.xcb_clickthrough out.json
"""
from __future__ import annotations

import json
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

STEP_TIMEOUT_S = 240.0


class Steps:
    """Each step acts (a click) and returns a condition; the next step starts when the condition holds and no
    task runs."""

    def __init__(self, window, steps: list[tuple[str, Callable[[], Callable[[], bool] | None]]], report: dict):
        from PySide6.QtCore import QTimer

        self.w, self.steps, self.report = window, steps, report
        self.i, self.until, self.t0 = -1, None, time.monotonic()
        self.timer = QTimer()
        self.timer.setInterval(50)
        self.timer.timeout.connect(self.tick)

    def tick(self) -> None:
        from PySide6.QtWidgets import QApplication

        if self.i >= 0:
            waiting = self.w.runner.busy() or (self.until is not None and not self.until())
            if waiting and time.monotonic() - self.t0 < STEP_TIMEOUT_S:
                return
            if waiting:
                self.report["failed"] = f"step {self.steps[self.i][0]!r} did not finish in {STEP_TIMEOUT_S:.0f} s"
                return self.stop(QApplication.instance())
            self.report["done"].append(self.steps[self.i][0])
        self.i += 1
        if self.i >= len(self.steps):
            return self.stop(QApplication.instance())
        name, act = self.steps[self.i]
        self.t0 = time.monotonic()
        try:
            self.until = act()
        except Exception as exc:  # noqa: BLE001 - a failing step ends the run with its message
            self.report["failed"] = f"step {name!r}: {type(exc).__name__}: {exc}"
            self.stop(QApplication.instance())

    def stop(self, app) -> None:
        self.timer.stop()
        self.w.close()
        app.quit()


def click(button) -> None:
    from PySide6.QtCore import Qt
    from PySide6.QtTest import QTest

    if not button.isEnabled():
        raise RuntimeError(f"{button.text()!r} is disabled ({button.toolTip()})")
    QTest.mouseClick(button, Qt.LeftButton)


def plan(w, report: dict) -> list:
    dev, cap, res = w.devices, w.capture, w.results

    def run(kind: str, target: int = 0):
        def act():
            cap.kind.setCurrentText(kind)
            cap.frames.setValue(1 if kind != "Dark series" else 2)
            cap.target.setCurrentIndex(target)
            click(cap.view.start_button)
            return lambda: cap.view.outcome != "" and not cap.view.running
        return act

    def process():
        w.show_panel("results")
        res.optimise.setChecked(False)
        res.select(res.train_subject, "target:train")
        res.select(res.test_subject, "target:test")
        click(res.process_button)
        return lambda: res.result is not None or "failed" in res.status.text()

    def results():
        report["test_mean_de00"] = res.result.report["test"]["mean"]
        report["badges"] = [b.text() for b in res.badge_labels.values()]
        report["errors"] = list(w.errors.history)
        report["light_on"] = w.lab.sphere.status()["light_on"]        # read back, as the window does
        return None

    def connect():
        dev.port_combo.setCurrentText("virtual sphere (emulator)")
        click(dev.sphere_button)
        return lambda: w.lab.sphere is not None

    def camera():
        dev.camera_combo.setCurrentText("virtual camera (virtual lab)")
        click(dev.camera_button)
        return lambda: w.lab.camera is not None

    def new_session():
        w.show_panel("capture")
        click(cap.new_button)
        return lambda: w.lab.session is not None and bool(cap.presets)

    def auto():
        cap.choose_preset("dual-RGB reflective")
        cap.settle.setValue(0.0)
        click(cap.auto_button)
        return lambda: cap.view.outcome == "done" and not cap.view.running

    return [("connect the sphere", connect), ("connect the camera", camera), ("new session", new_session),
            ("auto-exposure", auto), ("dark series", run("Dark series")), ("flats", run("Open-gate flats")),
            ("training target", run("Dual-RGB capture", 0)), ("test target", run("Dual-RGB capture", 1)),
            ("targets listed", lambda: res.reload() or (lambda: res.train_subject.findData("target:test") >= 0)),
            ("process", process), ("results", results)]


def main(out: Path) -> int:
    from dualrgb.app.gui.app import application, display_problem, live_display_problem

    report: dict = {"done": [], "failed": "", "probe": display_problem() or live_display_problem()}
    if report["probe"]:
        out.write_text(json.dumps(report))
        return 1
    app = application()
    from PySide6.QtCore import QSettings, QTimer
    from PySide6.QtGui import QGuiApplication

    from dualrgb.app.gui.main_window import MainWindow

    tmp = Path(tempfile.mkdtemp(prefix="dualrgb-xcb-"))
    settings = QSettings(str(tmp / "dualrgb.ini"), QSettings.IniFormat)
    settings.setValue("paths/captures", str(tmp / "captures"))
    w = MainWindow(settings, frame_size=(120, 80), show_dialogs=False)
    w.resize(1200, 800)
    w.show()
    report["platform"] = QGuiApplication.platformName()
    report["exposed"] = w.windowHandle() is not None and w.isVisible()
    steps = Steps(w, plan(w, report), report)
    QTimer.singleShot(200, steps.timer.start)
    app.exec()
    out.write_text(json.dumps(report, default=str))
    return 0 if not report["failed"] and len(report["done"]) == len(steps.steps) else 1


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
