"""Spectra in the GUI: a plot of factor spectra (estimated against reference, or one pixel's), and the delivered
original's view (its cube rendered under a chosen light; a click shows that pixel's spectrum from the delivered
cube). Wiring only: the cube is read and rendered by app.workflow.delivery.delivered_view, in the compute pool."""
from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QComboBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.widgets import image_widget, plot_widget

if TYPE_CHECKING:                                   # imported where a cube is opened: the GUI starts fast
    from dualrgb.app.workflow.delivery.delivered_view import DeliveredView as Cube

log = logging.getLogger(__name__)

Curve = tuple[str, np.ndarray, str, bool]        # label, values, colour, dashed


class SpectrumPlot(QWidget):
    """Factor against wavelength, 0 to 1 (the estimate's physical range), with a one-line title."""

    def __init__(self, tooltip: str, parent: QWidget | None = None):
        super().__init__(parent)
        self.plot = plot_widget("", "wavelength (nm)", "factor", tooltip)
        self.plot.addLegend(offset=(-10, 10))
        self.plot.setYRange(0.0, 1.05)
        self.title = QLabel("")
        self.title.setWordWrap(True)
        self.curves: list[Curve] = []
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.plot, 1)
        lay.addWidget(self.title)

    def show_spectra(self, wavelengths: np.ndarray, curves: Sequence[Curve], title: str = "") -> None:
        self.plot.clear()
        self.curves = list(curves)
        for label, values, colour, dashed in curves:
            pen = pg.mkPen(colour, width=2, style=pg.QtCore.Qt.DashLine if dashed else pg.QtCore.Qt.SolidLine)
            self.plot.plot(np.asarray(wavelengths), np.nan_to_num(np.asarray(values, dtype=float), nan=0.0),
                           pen=pen, name=label)
        self.title.setText(title)


def on_image_click(widget, item, handler: Callable[[int, int], None], scale: int = 1) -> None:
    """Call ``handler(row, col)`` with the image pixel (divided by ``scale``) a left click lands on."""
    def clicked(event) -> None:
        pos = item.mapFromScene(event.scenePos())
        row, col = int(np.floor(pos.y())) // scale, int(np.floor(pos.x())) // scale
        if row >= 0 and col >= 0:
            handler(row, col)
    widget.scene().sigMouseClicked.connect(clicked)


class DeliveredView(QWidget):
    """A delivered original seen under a chosen light (the combo), and a clicked pixel's spectrum."""

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        from dualrgb.app.workflow.delivery.delivered_view import render_lights

        self.ctx = ctx
        self.view: Cube | None = None
        self.pixel: tuple[int, int] | None = None
        self.shown_light = ""                        # the light the image on screen is rendered under
        self.image_widget, self.image, self.box = image_widget(
            "The delivered original, its spectral cube seen under the light chosen above (sRGB on screen). Click "
            "a pixel to see its spectrum.")
        self.illuminant = QComboBox()
        for key, name in render_lights().items():
            self.illuminant.addItem(key if key == name else f"{key} ({name})", key)
        self.illuminant.setToolTip("The light the cube is rendered under here (the delivered rendering's light is "
                                   "chosen in Originals > Options, D65 by default).")
        self.illuminant.currentIndexChanged.connect(lambda _i: self.render_light())
        self.info = QLabel("no delivered original selected")
        self.info.setWordWrap(True)
        self.spectrum = SpectrumPlot("The clicked pixel's spectrum, read from the delivered cube.")
        self.image_widget.setMinimumHeight(260)
        self.spectrum.setMinimumHeight(200)
        on_image_click(self.image_widget, self.image, self.click_pixel)
        top = QHBoxLayout()
        top.addWidget(QLabel("Seen under"))
        top.addWidget(self.illuminant, 1)
        lay = QVBoxLayout(self)
        lay.addLayout(top)
        lay.addWidget(self.image_widget, 1)
        lay.addWidget(self.info)
        lay.addWidget(self.spectrum, 1)

    @property
    def light(self) -> str:
        return str(self.illuminant.currentData())

    def show_delivery(self, sidecar: Path | None) -> None:
        """Load the delivered cube of ``sidecar`` in the compute pool and show it."""
        from dualrgb.app.workflow.delivery.delivered_view import open_delivered

        if sidecar is None:
            return
        light = self.light
        self.info.setText(f"loading {Path(sidecar).parent.name} …")
        self.ctx.runner.submit(lambda: (v := open_delivered(sidecar), (v.render(light), light)), pool="compute",
                               name="delivered preview", on_result=self._loaded,
                               on_error=lambda exc: self.info.setText(f"{Path(sidecar).name}: {exc}"))

    def _loaded(self, payload: tuple[Cube, tuple[np.ndarray, str]]) -> None:
        view, image = payload
        self.view = view
        self.pixel = None
        self._show_image(image)
        if self.shown_light != self.light:          # the light was changed while the cube loaded
            self.render_light()
        h, w = view.preview_shape
        shown = "full resolution" if view.step == 1 else f"every {view.step}th pixel"
        self.info.setText(f"{view.identifier}: {view.quantity} by {view.method}, {w} x {h} shown "
                          f"({shown}); click a pixel for its spectrum")
        self.click_pixel(h // 2, w // 2)

    def render_light(self) -> None:        # not render(): that is QWidget.render(target, ...)
        """Render the loaded cube under the chosen light (compute pool)."""
        view, light = self.view, self.light
        if view is None:
            return
        self.ctx.runner.submit(lambda: (view.render(light), light), pool="compute", name="render under a light",
                               on_result=self._show_image,
                               on_error=lambda exc: self.ctx.errors.report("Render under a light", exc))

    def _show_image(self, rendered: tuple[np.ndarray, str]) -> None:
        image, self.shown_light = rendered
        self.image.setImage(image, autoLevels=False, levels=(0, 255))
        self.box.autoRange()

    def click_pixel(self, row: int, col: int) -> None:
        """Show the spectrum of preview pixel (row, col) (one pixel read from the delivered cube)."""
        view = self.view
        if view is None:
            return
        try:
            wl, values = view.spectrum(row, col)
        except ValueError:
            return                                    # a click beside the image
        self.pixel = (row, col)
        r, c = view.full_pixel(row, col)
        self.spectrum.show_spectra(wl, [(f"pixel ({c}, {r})", values, "#1565c0", False)],
                           f"{view.identifier}, pixel x {c}, y {r} of the delivered cube: {view.quantity}"
                           + (" (no estimate there)" if np.isnan(values).all() else ""))
