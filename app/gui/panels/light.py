"""Light source: ten LED levels, the mixed spectrum (live), on/off with on-time and light dose, presets."""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QDoubleSpinBox,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QInputDialog,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QSlider,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.units import dose, light_pct, temperature
from dualrgb.app.gui.viewmodel import format_duration, light_from_levels, mixed_spectrum
from dualrgb.app.gui.widgets import PathLabel, plot_widget, side_by_side
from dualrgb.drivers.led_sphere.limits import DEFAULT_MAX_ON_S
from dualrgb.simulation.datasets import led_spectra
from dualrgb.simulation.grid import SpectralGrid
from dualrgb.simulation.lightsource import N_SPHERE_LEDS, LightSource
from dualrgb.simulation.presets import Preset, PresetError, load_preset, packaged_presets, save_preset

log = logging.getLogger(__name__)

PLOT_GRID = SpectralGrid(400.0, 780.0, 2.0)
SLIDER_STEPS = 1000


def _wavelength_colour(nm: float) -> tuple[int, int, int]:
    """Rough display colour of a wavelength (for the LED labels and curves only)."""
    stops = [(400, (130, 0, 200)), (440, (0, 0, 255)), (490, (0, 200, 255)), (510, (0, 220, 0)),
             (580, (230, 230, 0)), (645, (255, 0, 0)), (780, (160, 0, 0))]
    for (w0, c0), (w1, c1) in zip(stops, stops[1:], strict=False):
        if nm <= w1:
            t = max(0.0, min(1.0, (nm - w0) / (w1 - w0)))
            r, g, b = (int(a + t * (z - a)) for a, z in zip(c0, c1, strict=True))
            return r, g, b
    return stops[-1][1]


class PresetItem(QListWidgetItem):
    def __init__(self, path: Path, preset: Preset, packaged: bool):
        super().__init__(preset.name)
        self.path, self.preset, self.packaged = path, preset, packaged
        self.setFlags(self.flags() | Qt.ItemFlag.ItemIsEditable)
        errs = preset.errors.get("test") or preset.errors.get("train") or {}
        sources = "  +  ".join(light_pct(s) for s in preset.sources)
        where = "packaged (renaming saves a copy in your presets folder)" if packaged else str(path)
        self.setToolTip(f"{sources}\n{preset.method}, {preset.mode}"
                        + (f", test mean dE00 {errs['mean']:.3f}" if "mean" in errs else "") + f"\n{where}"
                        + "\nlevels are exact in the preset file")


class LightPanel(QWidget):
    title = "Light source"
    levelsChanged = Signal(object)      # np.ndarray (10,)

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.lab = ctx.lab
        self.led_spectra = led_spectra(PLOT_GRID)                  # (10, n_wl) relative
        self.wavelengths = PLOT_GRID.wavelengths
        self.peaks = self.wavelengths[np.argmax(self.led_spectra, axis=1)]
        self._updating = False
        self._sequence_running = False
        left = QWidget()
        ll = QVBoxLayout(left)
        ll.addWidget(self._levels_box())
        ll.addWidget(self._switch_box())
        right = QSplitter(Qt.Orientation.Vertical)
        right.addWidget(self._spectrum_plot())
        right.addWidget(self._presets_box())
        side_by_side(self, left, right)
        self._connect()
        saved = ctx.get("light/levels", "", str)
        try:
            initial = [float(x) for x in saved.split(",")] if saved else [0.0] * N_SPHERE_LEDS
        except ValueError:
            initial = [0.0] * N_SPHERE_LEDS
        self.set_levels(np.clip(np.resize(initial, N_SPHERE_LEDS), 0, 1))
        self._sphere_changed()
        self.reload_presets()

    # ------------------------------------------------------------------ builders
    def _levels_box(self) -> QGroupBox:
        box = QGroupBox("LED levels (0 % = off, 100 % = full power)")
        grid = QGridLayout(box)
        self.sliders: list[QSlider] = []
        self.spins: list[QDoubleSpinBox] = []
        for i in range(N_SPHERE_LEDS):
            r, g, b = _wavelength_colour(self.peaks[i])
            name = QLabel(f"LED {i + 1}  <span style='color:rgb({r},{g},{b})'>■</span> {self.peaks[i]:.0f}\u00a0nm")
            slider = QSlider(Qt.Orientation.Horizontal)
            slider.setRange(0, SLIDER_STEPS)
            slider.setToolTip(f"Level of LED {i + 1} (peak near {self.peaks[i]:.0f} nm), 0 % = off, 100 % = full")
            spin = QDoubleSpinBox()
            spin.setRange(0.0, 100.0)
            spin.setDecimals(4)                       # the sphere's 16-bit PWM step is 0.0015 %
            spin.setSingleStep(1.0)
            spin.setSuffix("\u00a0%")
            spin.setToolTip(slider.toolTip())
            slider.valueChanged.connect(lambda v, k=i: self._slider_moved(k, v))
            spin.valueChanged.connect(lambda v, k=i: self._spin_changed(k, v))
            grid.addWidget(name, i, 0)
            grid.addWidget(slider, i, 1)
            grid.addWidget(spin, i, 2)
            self.sliders.append(slider)
            self.spins.append(spin)
        buttons = QHBoxLayout()
        self.apply_button = QPushButton("Apply to sphere")
        self.apply_button.setToolTip("These ten levels for the manual light: sent to the sphere at once while it is "
                                     "on (the same lit period), else when you switch it on.")
        self.apply_button.clicked.connect(self.apply_levels)
        self.zero_button = QPushButton("All to 0")
        self.zero_button.setToolTip("Set every slider to 0 (press Apply to send).")
        self.zero_button.clicked.connect(lambda: self.set_levels(np.zeros(N_SPHERE_LEDS)))
        self.live_apply = QCheckBox("Apply while dragging")
        self.live_apply.setToolTip("Send the levels to the sphere as you move a slider (a short moment after).")
        self.live_apply.setChecked(self.ctx.get("light/live_apply", False, bool))
        self.live_apply.toggled.connect(lambda on: self.ctx.set("light/live_apply", on))
        for w in (self.apply_button, self.zero_button, self.live_apply):
            buttons.addWidget(w)
        grid.addLayout(buttons, N_SPHERE_LEDS, 0, 1, 3)
        self._debounce = QTimer(self)
        self._debounce.setSingleShot(True)
        self._debounce.setInterval(150)
        self._debounce.timeout.connect(self.apply_levels)
        return box

    def _spectrum_plot(self):
        self.plot = plot_widget("spectrum of these levels", "wavelength (nm)", "relative radiance",
                                "The light the sphere makes with these levels: each LED's spectrum times its "
                                "level, added up (thin lines: each LED's share).")
        self.led_curves = []
        for i in range(N_SPHERE_LEDS):
            colour = _wavelength_colour(self.peaks[i])
            self.led_curves.append(self.plot.plot(self.wavelengths, np.zeros_like(self.wavelengths),
                                                  pen=pg.mkPen(colour, width=1), fillLevel=0.0,
                                                  brush=pg.mkBrush(*colour, 70)))
        self.mix_curve = self.plot.plot(self.wavelengths, np.zeros_like(self.wavelengths),
                                        pen=pg.mkPen("k", width=2), name="mixed")
        return self.plot

    def _switch_box(self) -> QGroupBox:
        box = QGroupBox("Light")
        sl = QGridLayout(box)
        self.on_button = QPushButton("Light ON")
        self.on_button.clicked.connect(lambda: self.lab.set_light_on(True))
        self.off_button = QPushButton("Light OFF")
        self.off_button.setToolTip("Every LED to 0 and the light off (protects the object).")
        self.off_button.clicked.connect(lambda: self.lab.set_light_on(False))
        self.max_on = QDoubleSpinBox()
        self.max_on.setRange(0.5, DEFAULT_MAX_ON_S)
        self.max_on.setDecimals(1)
        self.max_on.setSuffix("\u00a0s")
        self.max_on.setValue(min(self.ctx.get("light/manual_max_on_s", DEFAULT_MAX_ON_S, float), DEFAULT_MAX_ON_S))
        self.max_on.setToolTip(f"'Light ON' lights the sphere for at most this long, then it goes off by itself "
                               f"(the driver's supervisor and the sphere's firmware). At most {DEFAULT_MAX_ON_S:g} s: "
                               "LED peaks drift after that (thesis 4.3.2), and light on the object is damage.")
        self.max_on.valueChanged.connect(self._max_on_changed)
        self._max_on_changed(self.max_on.value())
        self.state_label = QLabel("sphere not connected")
        self.state_label.setWordWrap(True)
        self.on_time_label = QLabel("on-time: —")
        self.on_time_label.setToolTip("How long the light has been on now. LED peaks drift after about 10 s "
                                      "(thesis 4.3.2): capture soon after switching on.")
        self.temp_label = QLabel("temperature: —")
        self.dose_label = QLabel(f"light dose: {dose(0.0)}")
        self.dose_label.setWordWrap(True)
        self.dose_label.setToolTip("Light the object received since the sphere was connected, in lux hours as "
                                   "conservators budget it (an estimate from the levels and the time on).")
        sl.addWidget(self.on_button, 0, 0)
        sl.addWidget(self.off_button, 0, 1)
        sl.addWidget(QLabel("Light ON for at most"), 1, 0)
        sl.addWidget(self.max_on, 1, 1)
        sl.addWidget(self.state_label, 2, 0, 1, 2)
        sl.addWidget(self.on_time_label, 3, 0)
        sl.addWidget(self.temp_label, 3, 1)
        sl.addWidget(self.dose_label, 4, 0, 1, 2)
        return box

    def _max_on_changed(self, seconds: float) -> None:
        self.lab.manual_max_on_s = float(seconds)
        self.ctx.set("light/manual_max_on_s", float(seconds))
        self.on_button.setToolTip(f"Switch the sphere's light on with the levels last applied, for at most "
                                  f"{seconds:g} s: it then goes off by itself (light on the object is damage; "
                                  "captures switch it on only for their exposures).")

    def _presets_box(self) -> QGroupBox:
        box = QGroupBox("Presets")
        pl = QVBoxLayout(box)
        self.presets = QListWidget()
        self.presets.setToolTip("Light-source pairs from the optimiser. Click one, then apply light 1 or 2; "
                                "double-click applies light 1. Double-click the name slowly (or F2) to rename.")
        self.presets.itemChanged.connect(self._renamed)
        self.presets.itemActivated.connect(lambda item: self.apply_preset(item, 0))
        self.presets.currentItemChanged.connect(self._preset_selected)
        self.preset_info = QLabel("")
        self.preset_info.setWordWrap(True)
        pb = QHBoxLayout()
        self.apply1 = QPushButton("Apply light 1")
        self.apply1.setToolTip("The preset's first light source for the manual light (the light stays off until "
                               "you switch it on).")
        self.apply1.clicked.connect(lambda: self.apply_preset(self.presets.currentItem(), 0))
        self.apply2 = QPushButton("Apply light 2")
        self.apply2.setToolTip("The preset's second light source for the manual light.")
        self.apply2.clicked.connect(lambda: self.apply_preset(self.presets.currentItem(), 1))
        self.save_button = QPushButton("Save levels as preset…")
        self.save_button.setToolTip("Save the current slider levels as a one-light preset in your presets folder.")
        self.save_button.clicked.connect(self._save_current)
        for w in (self.apply1, self.apply2, self.save_button):
            pb.addWidget(w)
        pl.addWidget(self.presets, 1)
        pl.addWidget(self.preset_info)
        pl.addLayout(pb)
        self.folder_label = PathLabel()
        pl.addWidget(self.folder_label)
        return box

    def _connect(self) -> None:
        self.lab.sphereChanged.connect(self._sphere_changed)
        self.lab.sphereStatus.connect(self.show_status)
        self.ctx.bus.presetsChanged.connect(self.reload_presets)
        self.ctx.workspace.runningChanged.connect(lambda name: self._set_sequence_running(bool(name)))

    # ------------------------------------------------------------------ levels
    def levels(self) -> np.ndarray:
        """The ten levels as fractions 0..1 (the spin boxes show them in %)."""
        return np.array([s.value() / 100.0 for s in self.spins])

    def set_levels(self, levels) -> None:
        self._updating = True
        try:
            for i, v in enumerate(levels):
                self.spins[i].setValue(100.0 * float(v))
                self.sliders[i].setValue(int(round(float(v) * SLIDER_STEPS)))
        finally:
            self._updating = False
        self._levels_changed()

    def _slider_moved(self, k: int, value: int) -> None:
        if self._updating:
            return
        self._updating = True
        self.spins[k].setValue(100.0 * value / SLIDER_STEPS)
        self._updating = False
        self._levels_changed(user=True)

    def _spin_changed(self, k: int, value: float) -> None:
        if self._updating:
            return
        self._updating = True
        self.sliders[k].setValue(int(round(value / 100.0 * SLIDER_STEPS)))
        self._updating = False
        self._levels_changed(user=True)

    def _levels_changed(self, user: bool = False) -> None:
        lv = self.levels()
        for i, curve in enumerate(self.led_curves):
            curve.setData(self.wavelengths, lv[i] * self.led_spectra[i])
        self.mix_curve.setData(self.wavelengths, mixed_spectrum(lv, self.led_spectra))
        self.ctx.set("light/levels", ",".join(repr(float(v)) for v in lv))
        self.ctx.workspace.set_manual_levels(lv)
        self.levelsChanged.emit(lv)
        if user and self.live_apply.isChecked() and self.lab.sphere is not None:
            self._debounce.start()

    def current_light(self, name: str = "manual") -> LightSource:
        return light_from_levels(self.levels(), name)

    def apply_levels(self) -> None:
        self.lab.apply_light(self.current_light())

    # ------------------------------------------------------------------ status
    def _set_sequence_running(self, running: bool) -> None:
        """A sequence owns the sphere while it runs: the manual controls wait."""
        self._sequence_running = running
        self._sphere_changed()

    def _sphere_changed(self) -> None:
        connected = self.lab.sphere is not None and not getattr(self, "_sequence_running", False)
        for w in (self.apply_button, self.on_button, self.off_button, self.apply1, self.apply2):
            w.setEnabled(connected)
        if self.lab.sphere is None:
            self.state_label.setText("sphere not connected: connect it in Devices")
            self.on_time_label.setText("on-time: —")
            self.temp_label.setText("temperature: —")

    def show_status(self, status: dict) -> None:
        on = status.get("light_on", False)
        faulty = status.get("faulty_leds") or []
        text = f"light {'ON' if on else 'off'} on {status.get('port', '')}"
        if faulty:
            text += f"; LED {', '.join(map(str, faulty))} faulty"
        if on and status.get("off_in_s") is not None:
            text += f", goes off by itself in {status['off_in_s']:.0f} s"
        if status.get("watchdog_tripped"):
            text += "; the sphere switched it off by itself (on-time limit or watchdog)"
        self.state_label.setText(text)
        self.state_label.setStyleSheet("color:#b26a00; font-weight:bold" if on else "")
        self.on_time_label.setText(f"on-time: {format_duration(status.get('on_time_s')) if on else '—'}")
        t = status.get("temperature_c")
        self.temp_label.setText(f"temperature: {temperature(t)}")
        given = status.get("dose")
        if given is not None:
            self.dose_label.setText(f"light dose: {dose(given.lux_s)}, on {format_duration(given.on_s)}")

    # ------------------------------------------------------------------ presets
    def reload_presets(self) -> None:
        folder = self.ctx.presets_dir
        self.folder_label.set_path(f"your presets: {folder}")

        def work() -> list[tuple[Path, Preset | None, bool, str]]:
            out: list[tuple[Path, Preset | None, bool, str]] = []
            user = sorted(folder.glob("*.json")) if folder.is_dir() else []
            for path, packaged in [(p, True) for p in packaged_presets()] + [(p, False) for p in user]:
                try:
                    out.append((path, load_preset(path), packaged, ""))
                except PresetError as exc:
                    out.append((path, None, packaged, str(exc)))
            return out

        self.ctx.runner.submit(work, pool="compute", name="load presets", on_result=self._fill_presets,
                               on_error=lambda exc: self.ctx.errors.report("Presets", exc))

    def _fill_presets(self, rows) -> None:
        item = self.presets.currentItem()
        current = item.path if isinstance(item, PresetItem) else None
        self.presets.blockSignals(True)
        self.presets.clear()
        for path, preset, packaged, problem in rows:
            if preset is None:
                log.warning("preset skipped: %s", problem)
                continue
            item = PresetItem(path, preset, packaged)
            self.presets.addItem(item)
            if path == current:
                self.presets.setCurrentItem(item)
        self.presets.blockSignals(False)
        if self.presets.currentItem() is None and self.presets.count():
            self.presets.setCurrentRow(0)
        self._preset_selected(self.presets.currentItem())

    def preset_items(self) -> list[PresetItem]:
        return [item for i in range(self.presets.count()) if isinstance(item := self.presets.item(i), PresetItem)]

    def _preset_selected(self, item, _previous=None) -> None:
        if not isinstance(item, PresetItem):
            self.preset_info.setText("")
            return
        p = item.preset
        lines = [f"light {i}: {light_pct(s)}" for i, s in enumerate(p.sources, start=1)]
        errs = p.errors.get("test") or {}
        if "mean" in errs:
            lines.append(f"simulated test mean ΔE00 {errs['mean']:.3f}")
        self.preset_info.setText("; ".join(lines) + " (levels shown to 4 significant digits; the preset file and "
                                 "the sphere get them exactly)")
        self.apply2.setEnabled(self.lab.sphere is not None and len(p.sources) > 1)

    def apply_preset(self, item, index: int) -> None:
        if not isinstance(item, PresetItem):
            self.ctx.errors.report("Apply a preset", "select a preset in the list first")
            return
        sources = item.preset.sources
        if index >= len(sources):
            self.ctx.errors.report("Apply a preset", f"preset {item.preset.name!r} has only {len(sources)} light(s)")
            return
        light = sources[index]
        self.set_levels(light.weights(N_SPHERE_LEDS))
        self.ctx.set("light/last_preset", str(item.path))
        if self.lab.sphere is not None:
            self.lab.apply_light(LightSource(light.leds, light.levels, f"{item.preset.name} light {index + 1}"))
        else:
            self.ctx.errors.report("Apply a preset", "the LED sphere is not connected: the levels are shown here; "
                                   "connect the sphere in Devices and press Apply to sphere")

    def _renamed(self, item) -> None:
        if not isinstance(item, PresetItem):
            return
        new_name = item.text().strip()
        if not new_name or new_name == item.preset.name:
            return
        preset = item.preset
        preset.name = new_name
        if item.packaged:
            target = self.ctx.presets_dir / (_slug(new_name) + ".json")
        else:
            target = item.path

        def work() -> Path:
            return save_preset(preset, target)

        def saved(p: Path) -> None:
            log.info("preset saved as %s", p)
            self.ctx.bus.presetsChanged.emit()

        self.ctx.runner.submit(work, pool="compute", name="rename preset", on_result=saved,
                               on_error=lambda exc: self.ctx.errors.report("Rename the preset", exc))

    def _save_current(self) -> None:
        name, ok = QInputDialog.getText(self, "Save preset", "Preset name:", text="manual light")
        if ok and name.strip():
            self.save_current_as(name.strip())

    def save_current_as(self, name: str) -> None:
        light = self.current_light("source 1")
        preset = Preset(name=name, sources=(light,), method="manual")
        target = self.ctx.presets_dir / (_slug(name) + ".json")
        self.ctx.runner.submit(lambda: save_preset(preset, target), pool="compute", name="save preset",
                               on_result=lambda p: self.ctx.bus.presetsChanged.emit(),
                               on_error=lambda exc: self.ctx.errors.report("Save the preset", exc))


def _slug(name: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_" else "_" for c in name.strip())
    return keep.strip("_") or "preset"
