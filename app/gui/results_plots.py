"""The Results panel's plots of one target: ΔE00 per patch on a fixed traffic-light scale with the patch names,
reference -> prediction vectors on a*b* and L*C*, the reference | prediction mosaic with its legend, and the
estimated against the reference spectrum of the patch clicked on the heat map or the mosaic."""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import pyqtgraph as pg
from PySide6.QtGui import QFont
from PySide6.QtWidgets import QGridLayout, QLabel, QWidget

from dualrgb.app.gui.de_scale import SCALE_MAX, de_band, lookup_table
from dualrgb.app.gui.spectra_view import SpectrumPlot, on_image_click
from dualrgb.app.gui.widgets import DeLegend, image_widget, plot_widget

log = logging.getLogger(__name__)

MAX_LABELLED = 60            # patch names on the heat map up to this many patches (a 24-patch chart, not an IT8)
CELL = 16                    # mosaic cell size (pixels)


@dataclass
class TargetView:
    """What the plots need for one target (computed in the worker from the processing results)."""

    label: str
    names: list[str]
    errors: np.ndarray
    lab_ref: np.ndarray
    lab_pred: np.ndarray
    srgb_ref: np.ndarray
    srgb_pred: np.ndarray
    layout: tuple[int, int]
    spectra: PatchSpectra | None = None


@dataclass
class PatchSpectra:
    """Reference and estimated spectra (n, n_wl) of a target's patches (the calibration's spectral estimate)."""

    wavelengths: np.ndarray
    reference: np.ndarray
    estimate: np.ndarray
    rmse: np.ndarray               # (n,) per patch
    method: str
    quantity: str


def cell_name(name: str, width: int = 9) -> str:
    """A patch name on at most two short lines (words kept whole; a long last line shortened with '…')."""
    lines: list[str] = []
    for word in name.split():
        if lines and len(lines[-1]) + 1 + len(word) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    if len(lines) > 2:
        lines = [lines[0], " ".join(lines[1:])]
    return "\n".join(line if len(line) <= width + 1 else line[:width] + "…" for line in lines)


def vector_pairs(ref: np.ndarray, pred: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x, y for a PlotDataItem(connect='pairs'): one segment from each reference point to its prediction."""
    xy = np.empty((2 * len(ref), 2))
    xy[0::2], xy[1::2] = ref, pred
    return xy[:, 0], xy[:, 1]


class TargetPlots(QWidget):
    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.heat_widget, self.heat_item, self.heat_box = image_widget(
            "ΔE00 of every patch, laid out like the target; the colours are fixed bands (legend above).")
        self.heat_widget.setBackground("w")
        self.heat_texts: list[pg.TextItem] = []
        self.ab_plot = plot_widget("a* b*: reference → capture", "a*", "b*",
                                   "Each patch's reference colour (dot, coloured by its ΔE00 band) and a line to "
                                   "where the capture puts it (cross).")
        self.lc_plot = plot_widget("L* C*: reference → capture", "C*", "L*", "Lightness against chroma, the same "
                                   "way.")
        for p in (self.ab_plot, self.lc_plot):
            p.addLegend(offset=(-10, 10))
        self.mosaic_widget, self.mosaic_item, self.mosaic_box = image_widget(
            "Each patch: left half the reference colour, right half the colour the capture predicts (sRGB).")
        self.mosaic_widget.setBackground("w")
        self.mosaic_legend = QLabel("each patch: <b>left half</b> reference colour | <b>right half</b> colour from "
                                    "the capture (sRGB)")
        self.mosaic_legend.setWordWrap(True)
        self.title = QLabel("")
        grid = QGridLayout(self)
        grid.addWidget(DeLegend(), 0, 0)
        grid.addWidget(self.mosaic_legend, 0, 1)
        grid.addWidget(self.heat_widget, 1, 0)
        grid.addWidget(self.mosaic_widget, 1, 1)
        grid.addWidget(self.ab_plot, 2, 0)
        grid.addWidget(self.lc_plot, 2, 1)
        self.spectra = SpectrumPlot("Click a patch on the ΔE00 map or the mosaic: its reference spectrum (solid) "
                                    "and the calibration's spectral estimate of it (dashed).")
        self.spectra.setMaximumHeight(200)               # below the maps and the Lab plots, never instead of them
        grid.addWidget(self.spectra, 3, 0, 1, 2)
        grid.addWidget(self.title, 4, 0, 1, 2)
        for row, stretch in ((1, 3), (2, 3), (3, 2)):          # the maps and the Lab plots keep their room
            grid.setRowStretch(row, stretch)
        self.view: TargetView | None = None
        self.patch: int | None = None
        on_image_click(self.heat_widget, self.heat_item, self.click_cell)
        on_image_click(self.mosaic_widget, self.mosaic_item, self.click_cell, scale=CELL)
        self._lut = lookup_table()
        self._cell_font = QFont()
        self._cell_font.setPointSize(7)

    def show_view(self, view: TargetView) -> None:
        self.view = view
        self._heat(view)
        self._scatter(view)
        self._mosaic(view)
        worst = int(np.argmax(view.errors))
        self.title.setText(f"{view.label}: {len(view.names)} patches; worst {view.names[worst]} "
                           f"{view.errors[worst]:.2f} ΔE00")
        self.select_patch(worst)

    def click_cell(self, row: int, col: int) -> None:
        """A click on the heat map or mosaic cell (row, col): that patch's spectra."""
        if self.view is not None and col < self.view.layout[1]:
            self.select_patch(row * self.view.layout[1] + col)

    def select_patch(self, k: int) -> None:
        """Estimated against reference spectrum of patch ``k`` (or why there is none)."""
        view = self.view
        if view is None or not 0 <= k < len(view.names):
            return
        self.patch = k
        sp = view.spectra
        if sp is None:
            self.spectra.show_spectra(np.array([]), [], f"{view.names[k]}: no spectral estimate (the targets' "
                                                        "spectra or the lights are unknown)")
            return
        self.spectra.show_spectra(sp.wavelengths, [("reference", sp.reference[k], "#212121", False),
                                                   ("estimate", sp.estimate[k], "#1565c0", True)],
                                  f"{view.names[k]}: spectral RMSE {sp.rmse[k]:.4f} ({sp.quantity}; estimated by "
                                  f"{sp.method}), ΔE00 {view.errors[k]:.2f}")

    def _heat(self, view: TargetView) -> None:
        rows, cols = view.layout
        n = len(view.errors)
        grid = np.full(rows * cols, np.nan)
        grid[:n] = view.errors
        self.heat_item.setImage(grid.reshape(rows, cols), levels=(0.0, SCALE_MAX), lut=self._lut, autoLevels=False)
        for t in self.heat_texts:
            self.heat_box.removeItem(t)
        self.heat_texts = []
        if n <= MAX_LABELLED:
            for k, (name, e) in enumerate(zip(view.names, view.errors, strict=True)):
                r, c = divmod(k, cols)
                t = pg.TextItem(f"{cell_name(name)}\n{e:.2f}", color=de_band(float(e)).text_colour, anchor=(0.5, 0.5))
                t.setFont(self._cell_font)
                t.setPos(c + 0.5, r + 0.5)
                self.heat_box.addItem(t)
                self.heat_texts.append(t)
        self.heat_box.autoRange()

    def _scatter(self, view: TargetView) -> None:
        brushes = [pg.mkBrush(de_band(float(e)).colour) for e in view.errors]
        chroma = (np.hypot(view.lab_ref[:, 1], view.lab_ref[:, 2]), np.hypot(view.lab_pred[:, 1], view.lab_pred[:, 2]))
        for plot, ref, pred in ((self.ab_plot, view.lab_ref[:, 1:3], view.lab_pred[:, 1:3]),
                                (self.lc_plot, np.column_stack([chroma[0], view.lab_ref[:, 0]]),
                                 np.column_stack([chroma[1], view.lab_pred[:, 0]]))):
            plot.clear()
            x, y = vector_pairs(ref, pred)
            plot.addItem(pg.PlotDataItem(x, y, connect="pairs", pen=pg.mkPen("#616161", width=1),
                                         name="reference → capture"))
            plot.addItem(pg.ScatterPlotItem(ref[:, 0], ref[:, 1], brush=brushes, size=9, pen=pg.mkPen("#444"),
                                            name="reference (ΔE00 band)"))
            plot.addItem(pg.ScatterPlotItem(pred[:, 0], pred[:, 1], size=6, symbol="x", pen=pg.mkPen("#212121"),
                                            brush=pg.mkBrush("#212121"), name="capture"))
        self.ab_plot.getPlotItem().setAspectLocked(True)

    def _mosaic(self, view: TargetView) -> None:
        rows, cols = view.layout
        img = np.ones((rows * CELL, cols * CELL, 3))
        for k in range(len(view.errors)):
            r, c = divmod(k, cols)
            y, x = r * CELL, c * CELL
            img[y + 1:y + CELL - 1, x + 1:x + CELL // 2] = view.srgb_ref[k]
            img[y + 1:y + CELL - 1, x + CELL // 2:x + CELL - 1] = view.srgb_pred[k]
        self.mosaic_item.setImage((img * 255).astype(np.uint8), autoLevels=False, levels=(0, 255))
        self.mosaic_box.autoRange()
