"""The lights of the day (Calibrate & capture): a list of presets, packaged and the technician's own, each with its
expected captured error, the mode's recommended one marked and chosen unless the technician chose another.

The recommended preset is the one ``dualrgb calibrate`` uses by default (app.workflow.stand.defaults); the figures are
what ``dualrgb simulate`` reports for those lights (app.workflow.calibration.preset_figures), computed off the GUI
thread
and filled in when ready. A choice from the list is remembered (for its mode); switching the mode goes back to
that mode's recommended preset unless one of its own was chosen.
"""
from __future__ import annotations

import logging
from pathlib import Path

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QComboBox, QLabel, QVBoxLayout, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.app.workflow.calibration.preset_figures import PresetFigures, figures_of
from dualrgb.app.workflow.stand.defaults import default_preset_path
from dualrgb.simulation.presets import Preset, PresetError, load_preset, packaged_presets

log = logging.getLogger(__name__)

CHOSEN = "lights/preset"           # the settings key of the technician's own choice


class PresetChooser(QWidget):
    chosen = Signal(object)        # the Preset now selected

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx, self.lab = ctx, ctx.lab
        self.presets: list[tuple[Path, Preset]] = []
        self.figures: list[PresetFigures | None] = []      # per preset, once computed
        self.combo = QComboBox()
        self.combo.setToolTip(COMBO_TIP)
        self.combo.currentIndexChanged.connect(self._changed)
        self.combo.activated.connect(self._picked)
        self.note = QLabel("")
        self.note.setWordWrap(True)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.combo)
        lay.addWidget(self.note)
        self.lab.modeChanged.connect(lambda _mode: self.select(self.wanted_index()))

    # ------------------------------------------------------------------ listing
    def load(self) -> None:
        """List the packaged presets and the technician's (off the GUI thread), then their figures."""
        folder = self.ctx.presets_dir

        def work() -> list[tuple[Path, Preset]]:
            out = []
            for p in packaged_presets() + (sorted(folder.glob("*.json")) if folder.is_dir() else []):
                try:
                    out.append((p, load_preset(p)))
                except PresetError as exc:
                    log.warning("preset skipped: %s", exc)
            return out

        self.ctx.runner.submit(work, pool="compute", name="load presets", on_result=self._fill,
                               on_error=lambda exc: self.ctx.errors.report("Presets", exc))

    def _fill(self, presets: list[tuple[Path, Preset]]) -> None:
        current = self._current_key()
        self.presets, self.figures = presets, [None] * len(presets)
        self.combo.blockSignals(True)
        self.combo.clear()
        for i in range(len(presets)):
            self.combo.addItem(self.text(i))
        keys = [_key(p) for p, _ in presets]
        self.combo.setCurrentIndex(keys.index(current) if current in keys else self.wanted_index())
        self.combo.blockSignals(False)
        self._changed(self.combo.currentIndex())
        listed = self.presets
        self.ctx.runner.submit(lambda: figures_of([p for _, p in listed]), pool="compute", name="preset figures",
                               on_result=lambda figs: self._show_figures(listed, figs),
                               on_error=lambda exc: log.warning("preset figures: %s", exc))

    def _show_figures(self, listed: list, figures: list[PresetFigures | None]) -> None:
        if listed is not self.presets:
            return                                 # reloaded meanwhile: the new list's figures follow
        self.figures = list(figures)
        self.select(-1)

    # ------------------------------------------------------------------ choosing
    def _current_key(self) -> str:
        i = self.combo.currentIndex()
        return _key(self.presets[i][0]) if 0 <= i < len(self.presets) else ""

    def recommended_index(self) -> int | None:
        want = _key(default_preset_path(self.lab.mode))
        return next((i for i, (p, _) in enumerate(self.presets) if _key(p) == want), None)

    def wanted_index(self) -> int:
        """The technician's own choice when it is listed and for the stand's mode, else the mode's recommended
        preset (the lights of ``dualrgb calibrate``)."""
        chosen = self.ctx.get(CHOSEN, "", str)
        keys = [_key(p) for p, _ in self.presets]
        if chosen and _key(chosen) in keys and self.presets[keys.index(_key(chosen))][1].mode == self.lab.mode:
            return keys.index(_key(chosen))
        rec = self.recommended_index()
        return rec if rec is not None else 0

    def select(self, index: int) -> None:
        """Relabel every item (recommended, figures) and select ``index`` (-1: keep the selection)."""
        for i in range(len(self.presets)):
            self.combo.setItemText(i, self.text(i))
        if 0 <= index < len(self.presets) and self.combo.isEnabled():
            self.combo.setCurrentIndex(index)
        self._show_note()

    def choose(self, name: str) -> None:
        """Choose the preset named ``name`` as the technician does (remembered)."""
        for i, (path, p) in enumerate(self.presets):
            if p.name == name:
                self.combo.setCurrentIndex(i)
                self.ctx.set(CHOSEN, str(path))
                return
        raise ValueError(f"no preset named {name!r}")

    def _picked(self, index: int) -> None:
        if 0 <= index < len(self.presets):
            self.ctx.set(CHOSEN, str(self.presets[index][0]))

    def _changed(self, index: int) -> None:
        if 0 <= index < len(self.presets):
            self._show_note()
            self.chosen.emit(self.presets[index][1])

    # ------------------------------------------------------------------ text
    def text(self, i: int) -> str:
        """'dual-RGB-PSO reflective · expected ΔE00 0.42 / 0.30 · recommended' (the figure before the mark, so
        a narrow list still shows it)."""
        _path, p = self.presets[i]
        fig = self._figure(i)
        parts = [p.name, fig.text() if fig is not None else "expected ΔE00 …"]
        if i == self.recommended_index():
            parts.append("recommended")
        return " · ".join(parts)

    def _figure(self, i: int | None) -> PresetFigures | None:
        return self.figures[i] if i is not None and 0 <= i < len(self.figures) else None

    def _show_note(self) -> None:
        i, rec, mode = self.combo.currentIndex(), self.recommended_index(), self.lab.mode
        fig, best = self._figure(i), self._figure(rec)
        here = f"{fig.text()} on the training / test target" if fig is not None else "expected ΔE00 being computed"
        if rec is None or i == rec:
            text = f"The recommended lights for {mode} originals (what Calibrate uses): {here}"
        else:
            text = (f"Not the recommended lights for {mode}: {here}; {self.presets[rec][1].name} (recommended)"
                    + (f": {best.text()}" if best is not None else ""))
        self.note.setText(text + ". Expected ΔE00: the expected captured mean error the simulation reports for "
                                 "these lights.")
        self.combo.view().setMinimumWidth(self.combo.view().sizeHintForColumn(0) + 24)   # the list shows it all
        self.combo.setToolTip(f"{self.combo.currentText()}\n\n{COMBO_TIP}")     # the whole text of a narrow combo


COMBO_TIP = ("The preset whose lights this session uses (one preset per session), each with its expected captured "
             "error; the mode's recommended one is chosen unless you choose another.")


def _key(path: Path | str) -> str:
    """A preset file's identity (its resolved path)."""
    try:
        return str(Path(path).resolve())
    except OSError:
        return str(path)
