"""The last frame a sequence saved: a thumbnail, its raw histogram with the linear limit and clipping marked, the
clipping percentage, and a warning when the frame is dark (light off, lens cap on) or clipped.

Frames are loaded in the compute pool; while one loads, newer ones replace the queued request (only the latest
is shown), so a fast sequence never piles up work on the GUI thread.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QHBoxLayout, QLabel, QVBoxLayout, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.units import percent
from dualrgb.app.gui.viewmodel import LINEAR_LIMIT_DN, RawHistogram, RawView, raw_view
from dualrgb.app.gui.widgets import image_widget, plot_widget

log = logging.getLogger(__name__)

CHANNEL_PENS = {"R": "#d32f2f", "G1": "#388e3c", "G2": "#81c784", "G": "#388e3c", "B": "#1976d2"}
WARNING_STYLE = "color:#c62828; font-weight:bold"


class HistogramPlot:
    """A raw DN histogram (log counts) with the linear limit and the white level as vertical lines."""

    def __init__(self, title: str = "") -> None:
        self.widget = plot_widget(title, "raw value (DN)", "pixels (log)")
        self.widget.setLogMode(y=True)
        self.widget.setToolTip("How many pixels have each raw value. Keep everything left of the orange line (the "
                               "sensor stops being linear there); at the red line pixels are clipped.")
        self.linear_line = pg.InfiniteLine(LINEAR_LIMIT_DN, angle=90, pen=pg.mkPen("#ef6c00", width=2),
                                           label="linear limit", labelOpts={"position": 0.9, "color": "#ef6c00"})
        self.white_line = pg.InfiniteLine(15520, angle=90, pen=pg.mkPen("#c62828", width=2),
                                          label="clipping", labelOpts={"position": 0.75, "color": "#c62828"})
        self.widget.addItem(self.linear_line)
        self.widget.addItem(self.white_line)
        self.curves: dict[str, pg.PlotDataItem] = {}

    def show(self, h: RawHistogram) -> None:
        centres = 0.5 * (h.edges[1:] + h.edges[:-1])
        for name in set(self.curves) - set(h.counts):
            self.widget.removeItem(self.curves.pop(name))
        for name, counts in h.counts.items():
            y = np.maximum(counts, 0.5)       # log axis: empty bins drawn at 0.5
            if name not in self.curves:
                self.curves[name] = self.widget.plot(centres, y, pen=pg.mkPen(CHANNEL_PENS.get(name, "k")), name=name)
            else:
                self.curves[name].setData(centres, y)
        self.white_line.setValue(h.white_level)
        self.linear_line.setValue(h.linear_limit)


class FramePreview(QWidget):
    """Thumbnail + histogram + one line (clipping %, level, warning) of the latest frame."""

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.view: RawView | None = None
        self.warning = ""
        self._pending = False
        self._queued: tuple[Path, str, bool] | None = None      # path, role, a long exposure of a bracket
        self.thumb_widget, self.thumb, self.thumb_box = image_widget("The last frame saved (raw, brightened).")
        self.thumb_widget.setMinimumSize(160, 110)
        self.hist = HistogramPlot()
        self.hist.widget.setMinimumHeight(110)
        self.info = QLabel("no frame yet")
        self.info.setWordWrap(True)
        row = QHBoxLayout()
        row.addWidget(self.thumb_widget, 2)
        row.addWidget(self.hist.widget, 3)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addLayout(row, 1)
        lay.addWidget(self.info)

    def show_file(self, path: Path, role: str = "", bracket_long: bool = False) -> None:
        """Load ``path`` in the background and show it (a newer request replaces a queued one). ``bracket_long``:
        a longer exposure of an HDR bracket, whose highlights the shorter one covers (clipping is expected)."""
        self._queued = (Path(path), role, bracket_long)
        if not self._pending:
            self._load_next()

    def _load_next(self) -> None:
        if self._queued is None:
            return
        path, role, long_ = self._queued
        self._queued = None
        self._pending = True
        self.ctx.runner.submit(lambda: raw_view(path), pool="compute", name="frame preview",
                               on_result=lambda v: self.show_view(v, role, long_),
                               on_error=lambda exc: self.info.setText(f"preview of {path.name}: {exc}"),
                               on_finished=self._loaded)

    def _loaded(self) -> None:
        self._pending = False
        self._load_next()

    def show_view(self, view: RawView, role: str = "", bracket_long: bool = False) -> None:
        self.view = view
        self.thumb.setImage(view.image, autoLevels=False, levels=(0, 255))
        self.thumb_box.autoRange()
        self.hist.show(view.histogram)
        check = view.check
        light_on = self.ctx.lab.last_status.get("light_on") if self.ctx.lab.last_status else None
        expected_dark = role in ("dark", "lens-cap")
        self.warning = "" if check is None or (expected_dark and check.dark) else check.warning(light_on)
        if bracket_long and check is not None and not check.dark:
            self.warning = ""                           # the bracket's shorter exposure covers the highlights
        level = f"brightest channel {percent(check.level_pct / 100, 1)} of the linear range, " if check else ""
        clipped = percent(view.histogram.fraction_clipped) + (" (a longer exposure of an HDR bracket: expected)"
                                                              if bracket_long else "")
        self.info.setText(f"{Path(view.path).name}: {level}{clipped} clipped"
                          + (f"<br><span style='{WARNING_STYLE}'>{self.warning}</span>" if self.warning else ""))
        self.info.setToolTip(view.histogram.summary())
