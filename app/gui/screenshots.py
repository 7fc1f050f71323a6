"""``dualrgb gui --screenshot DIR``: a small real session on the virtual lab - connect, calibrate (the default
lights, into the session the calibration makes), two originals (one needing HDR) captured and delivered, results,
a search, a CRF sweep - one PNG per panel plus the workflow guide and the flat-field uniformity map, then exit.

The run is a list of steps driven by a QTimer: each step starts something (a device call, a sequence, the
processing, a simulation) through the panels' own code, and the next one starts when every worker is idle.
Nothing blocks the event loop; the PNGs show what a technician would see.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QBuffer, QIODevice, QObject, QTimer
from PySide6.QtWidgets import QApplication

from dualrgb.app.gui.screenshot_tools import tool_steps, viewer_steps
from dualrgb.app.workflow.day.day import OriginalState
from dualrgb.common.atomic_files import atomic_write

log = logging.getLogger(__name__)

STEP_TIMEOUT_S = float(__import__('os').environ.get('DUALRGB_SHOT_TIMEOUT', 600))


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
        self._wait_for: Callable[[], bool] | None = None
        self._t_step = 0.0
        self._idle_since: float | None = None
        self._timer = QTimer(self)
        self._timer.setInterval(100)
        self._timer.timeout.connect(self._tick)

    def start(self) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.w.devices.set_folder("paths/captures", str(self.work_dir / "captures"))
        self.w.devices.set_folder("paths/presets", str(self.work_dir / "presets"))
        self._timer.start()

    # ------------------------------------------------------------------ the session
    def _plan(self) -> list[tuple[str, Callable[[], Callable[[], bool] | None]]]:
        w = self.w
        cap, sim = w.capture, w.simulate
        return [
            ("start the virtual lab", lambda: w.lab.start_virtual_lab()),
            ("screenshot devices", lambda: self.shoot("devices")),
            ("light on", self._light_on),
            ("screenshot light", lambda: self.shoot("light")),
            ("take a picture", self._camera_shot),
            ("screenshot camera", lambda: self.shoot("camera")),
            ("lights listed", lambda: lambda: bool(cap.presets) and None not in cap.chooser.figures),
            ("calibrate", self._calibrate),
            ("screenshot capture", lambda: self.shoot("capture")),
            ("flat-field uniformity", self._uniformity),
            ("screenshot uniformity", lambda: self.shoot("capture", "uniformity")),
            ("originals", self._originals),
            ("select an original", lambda: w.originals.select("ACC-1902-03")),
            ("screenshot originals", lambda: self.shoot("originals")),
            ("delivered: the painting under A", self._delivered),
            ("screenshot delivered", lambda: self.shoot("originals", "delivered")),
            ("screenshot guide", lambda: self.shoot_widget(w.guide_dock, "guide")),
            *tool_steps(self),                          # issue 30's panels (app.gui.screenshot_tools)
            *viewer_steps(self),                        # issue 42's viewer
            ("list targets", self._list_targets),
            ("grid on the training target", lambda: self._place_grid("target:train")),
            ("grid on the test target", lambda: self._place_grid("target:test")),
            ("screenshot target", lambda: self.shoot("target")),
            ("results: process", self._process),
            ("screenshot results", lambda: self.shoot("results")),
            ("simulate", self._simulate),
            ("save preset", lambda: sim.save_preset("screenshot PSO") and None),
            ("screenshot simulate", lambda: self.shoot("simulate")),
            ("CRF sweep", self._crf_sweep),
            ("screenshot characterise", lambda: self.shoot("characterise")),
        ]

    def _light_on(self):
        w, light = self.w, self.w.light
        item = next(i for i in light.preset_items() if i.preset.name == "dual-RGB reflective")
        light.presets.setCurrentItem(item)
        light.apply_preset(item, 0)
        w.lab.set_light_on(True)
        return lambda: w.lab.last_status.get("light_on") is True and w.lab.last_status.get("on_time_s", 0) > 2

    def _camera_shot(self):
        self.w.lab.place("test")
        self.w.camera.capture()
        return lambda: self.w.camera.last_view is not None

    def _calibrate(self):
        cap, ws = self.w.capture, self.w.ctx.workspace        # the recommended lights; the session made for it
        box = cap.calibration
        box.dark_frames.setValue(2)
        box.flat_frames.setValue(2)
        box.de_fit.setChecked(False)
        box.hdr_auto.setChecked(True)
        box.calibrate()
        return lambda: cap.view.outcome != "" and (cap.view.outcome != "done" or ws.calibration_check is not None)

    def _uniformity(self):
        cap = self.w.capture
        cap.right.setCurrentWidget(cap.uniformity)
        cap.uniformity.refresh()
        return lambda: cap.uniformity.map is not None

    def _originals(self):
        w, org = self.w, self.w.originals
        w.show_panel("originals")
        for ident, title, stand_in in (("ACC-1887-12", "Landscape with a figure", "painting"),
                                       ("ACC-1902-03", "Still life in shadow", "shadow")):
            org.identifier.setText(ident)
            org.title_edit.setText(title)
            org.operator.setText("J. Doe")
            org.stand_in.setCurrentText(stand_in)
            org.add_original()
        org.capture([r.identifier for r in w.ctx.workspace.queue.waiting()])
        ended = (OriginalState.DELIVERED, OriginalState.FAILED)
        return lambda: all(r.state in ended for r in w.ctx.workspace.queue.rows)

    def _delivered(self):
        org = self.w.originals
        dv = org.delivered
        org.tabs.setCurrentWidget(dv)
        dv.illuminant.setCurrentIndex(dv.illuminant.findData("A"))
        org.select("ACC-1887-12")
        return lambda: dv.view is not None and dv.view.identifier == "ACC-1887-12" and dv.shown_light == "A"

    def _list_targets(self):
        tgt = self.w.target
        tgt.reload()
        return lambda: tgt.subject.findData("target:test") >= 0

    def _place_grid(self, key: str):
        tgt = self.w.target
        tgt.select_subject(key)

        def placed() -> bool:                   # once its frame is shown: placed as a technician would
            if key not in self.w.ctx.workspace.grids and tgt.grid is not None and tgt.key() == key:
                tgt.place_button.click()
            return key in self.w.ctx.workspace.grids
        return placed

    def _process(self):
        res = self.w.results
        self.w.show_panel("results")
        res.optimise.setChecked(False)
        res.select(res.train_subject, "target:train")
        res.select(res.test_subject, "target:test")
        res.start()
        return lambda: res.result is not None or "failed" in res.status.text()

    def _simulate(self):
        sim = self.w.simulate
        sim.mode.setCurrentText("reflective")
        sim.method.setCurrentText("pso")
        sim.iterations.setValue(5)
        sim.population.setValue(30)
        sim.start()
        return lambda: sim.result is not None

    def _crf_sweep(self):
        crf = self.w.characterise
        crf.levels.setText("100, 25")
        crf.levels.editingFinished.emit()
        crf.max_t.setValue(0.5)
        crf.start()
        return lambda: not crf.view.running

    # ------------------------------------------------------------------ driver
    def _tick(self) -> None:
        now = time.monotonic()
        if self._i >= 0:
            busy = self._background_busy() or (self._wait_for is not None and not self._wait_for())
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
        except Exception as exc:  # noqa: BLE001 - a broken step ends the run with its message, never a hang
            self._fail(f"step {name!r}: {exc}")

    def _background_busy(self) -> bool:
        """Work in flight; live view's back-to-back previews (devices pool) are left out while it is on, or a
        step taken with live view on would never see the window idle."""
        runner, live = self.w.runner, self.w.camera.live_button.isChecked()
        return runner.busy("compute") or runner.busy("sequences") or (not live and runner.busy("devices"))

    def shoot(self, panel: str, name: str = "") -> Callable[[], bool]:
        """The whole window (the guide beside the panel) with ``panel`` in front, as ``<name or panel>.png``."""
        self.w.tabs.setCurrentWidget(self.w.panels[panel])
        return self.shoot_widget(self.w, name or panel)

    def shoot_widget(self, widget, name: str) -> Callable[[], bool]:
        path = self.out_dir / f"{name}.png"
        QTimer.singleShot(300, lambda: self._grab(widget, name))
        return lambda: path in self.saved

    def _grab(self, widget, name: str) -> None:
        path = self.out_dir / f"{name}.png"
        buffer = QBuffer()
        buffer.open(QIODevice.OpenModeFlag.WriteOnly)
        widget.grab().save(buffer, "PNG")
        atomic_write(path, bytes(buffer.data().data()))
        self.saved.append(path)
        log.info("saved %s", path)

    def _fail(self, message: str) -> None:
        log.error("screenshot run failed: %s", message)
        print(f"dualrgb: error: screenshot run: {message}")
        self.exit_code = 1
        self._timer.stop()
        self.w.close()
        QApplication.quit()

    def _finish(self) -> None:
        self._timer.stop()
        errors = self.w.errors.history
        for title, msg in errors:
            print(f"dualrgb: warning: {title}: {msg}")
        print(f"saved {len(self.saved)} screenshots in {self.out_dir}")
        if errors:
            self.exit_code = 1
        self.w.close()
        QApplication.quit()
