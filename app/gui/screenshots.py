"""``dualrgb gui --screenshot DIR``: a small real session on the virtual lab, one PNG per panel, then exit.

The run is a list of steps driven by a QTimer: each step starts something (a device call, a sequence, the
processing, a simulation) through the panels' own code, and the next one starts when every worker is idle.
Nothing blocks the event loop; the PNGs show what a technician would see.
"""
from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Callable, Optional

from PySide6.QtCore import QBuffer, QIODevice, QObject, QTimer
from PySide6.QtWidgets import QApplication

from simulation.atomic_io import atomic_write

log = logging.getLogger(__name__)

STEP_TIMEOUT_S = 600.0


class ScreenshotRun(QObject):
    def __init__(self, window, out_dir: Path, work_dir: Path):
        super().__init__(window)
        self.w = window
        self.out_dir = Path(out_dir)
        self.work_dir = Path(work_dir)
        self.exit_code = 0
        self.saved: list[Path] = []
        self._steps = self._plan()
        self._i = -1
        self._wait_for: Optional[Callable[[], bool]] = None
        self._t_step = 0.0
        self._idle_since: Optional[float] = None
        self._timer = QTimer(self)
        self._timer.setInterval(100)
        self._timer.timeout.connect(self._tick)

    def start(self) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.w.ctx.set("paths/captures", str(self.work_dir / "captures"))
        self.w.ctx.set("paths/presets", str(self.work_dir / "presets"))
        self._timer.start()

    # ------------------------------------------------------------------ the session
    def _plan(self) -> list[tuple[str, Callable[[], Optional[Callable[[], bool]]]]]:
        w = self.w
        cap, light, cam, tgt, res, sim, crf = (w.capture, w.light, w.camera, w.target, w.results, w.simulate,
                                               w.characterise)

        def preset_item(name: str):
            return next(i for i in light.preset_items() if i.preset.name == name)

        def light_on():
            light.presets.setCurrentItem(preset_item("dual-RGB reflective"))
            light.apply_preset(light.presets.currentItem(), 0)
            w.lab.set_light_on(True)
            return lambda: w.lab.last_status.get("light_on") is True and w.lab.last_status.get("on_time_s", 0) > 2

        def camera_shot():
            w.lab.place("test")
            cam.capture()
            return lambda: cam.last_view is not None

        def sequence(kind: str, frames: int = 0, target: int = 0):
            def run():
                cap.kind.setCurrentText(kind)
                if frames:
                    cap.frames.setValue(frames)
                cap.target.setCurrentIndex(target)
                cap.start()
                return lambda: not cap.view.running
            return run

        def show_target():
            tgt.reload()
            return lambda: tgt.subject.count() > 0

        def pick_test():
            tgt.subject.setCurrentText("target:train")
            return lambda: tgt.grid is not None

        def pick_test2():
            tgt.subject.setCurrentText("target:test")
            return lambda: tgt.grid is not None and tgt.grid.rows == 4

        def process():
            res.reload()
            return None

        def process2():
            res.start()
            return lambda: res.result is not None or "failed" in res.status.text()

        def simulate():
            sim.mode.setCurrentText("reflective")
            sim.method.setCurrentText("pso")
            sim.iterations.setValue(5)
            sim.population.setValue(30)
            sim.start()
            return lambda: sim.result is not None

        def save_sim_preset():
            sim.save_preset("screenshot PSO")
            return None

        def crf_sweep():
            crf.levels.setText("1, 0.25")
            crf.levels.editingFinished.emit()
            crf.max_t.setValue(0.5)
            crf.start()
            return lambda: not crf.view.running

        return [
            ("start the virtual lab", lambda: w.lab.start_virtual_lab()),
            ("screenshot devices", lambda: self.shoot("devices")),
            ("light on", light_on),
            ("screenshot light", lambda: self.shoot("light")),
            ("take a picture", camera_shot),
            ("screenshot camera", lambda: self.shoot("camera")),
            ("new session", lambda: cap.new_session() or (lambda: w.lab.session is not None)),
            ("choose the preset", lambda: cap.choose_preset("dual-RGB reflective")),
            ("auto-exposure", lambda: cap.auto_expose()),
            ("dark series", sequence("Dark series", frames=4)),
            ("flats", sequence("Open-gate flats", frames=2)),
            ("train target", sequence("Dual-RGB capture", target=0)),
            ("test target", sequence("Dual-RGB capture", target=1)),
            ("screenshot capture", lambda: self.shoot("capture")),
            ("list targets", show_target),
            ("grid on the training target", pick_test),
            ("grid on the test target", pick_test2),
            ("screenshot target", lambda: self.shoot("target")),
            ("results: list", process),
            ("results: process", process2),
            ("screenshot results", lambda: self.shoot("results")),
            ("simulate", simulate),
            ("save preset", save_sim_preset),
            ("screenshot simulate", lambda: self.shoot("simulate")),
            ("CRF sweep", crf_sweep),
            ("screenshot characterise", lambda: self.shoot("characterise")),
        ]

    # ------------------------------------------------------------------ driver
    def _tick(self) -> None:
        now = time.monotonic()
        if self._i >= 0:
            busy = self.w.runner.busy() or (self._wait_for is not None and not self._wait_for())
            if busy:
                self._idle_since = None
                if now - self._t_step > STEP_TIMEOUT_S:
                    self._fail(f"step {self._steps[self._i][0]!r} did not finish within {STEP_TIMEOUT_S:.0f} s")
                return
            if self._idle_since is None:
                self._idle_since = now
                return
            if now - self._idle_since < 0.4:            # let status polls and queued signals settle
                return
        self._i += 1
        if self._i >= len(self._steps):
            self._finish()
            return
        name, step = self._steps[self._i]
        log.info("screenshot run: %s", name)
        self._t_step = now
        self._idle_since = None
        try:
            self._wait_for = step() if callable(step) else None
            if not callable(self._wait_for):
                self._wait_for = None
        except Exception as exc:  # a broken step ends the run with a message, never a hang
            self._fail(f"step {name!r}: {exc}")

    def shoot(self, panel: str) -> Callable[[], bool]:
        self.w.tabs.setCurrentWidget(self.w.panels[panel])
        path = self.out_dir / f"{panel}.png"
        QTimer.singleShot(300, lambda: self._grab(panel))
        return lambda: path in self.saved

    def _grab(self, panel: str) -> None:
        path = self.out_dir / f"{panel}.png"
        buffer = QBuffer()
        buffer.open(QIODevice.WriteOnly)
        self.w.grab().save(buffer, "PNG")
        atomic_write(path, bytes(buffer.data()))
        self.saved.append(path)
        log.info("saved %s", path)

    def _fail(self, message: str) -> None:
        log.error("screenshot run failed: %s", message)
        print(f"dualrgb: error: screenshot run: {message}")
        self.exit_code = 1
        self._timer.stop()
        self.w.close()
        QApplication.instance().quit()

    def _finish(self) -> None:
        self._timer.stop()
        errors = self.w.errors.history
        for title, msg in errors:
            print(f"dualrgb: warning: {title}: {msg}")
        print(f"saved {len(self.saved)} screenshots in {self.out_dir}")
        if errors:
            self.exit_code = 1
        self.w.close()
        QApplication.instance().quit()
