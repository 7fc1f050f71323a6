"""The flats' uniformity map labels every block with its percent of the mean, drawn by one item (app.gui.
uniformity_view.CellLabels) at each block's centre: the texts follow the map, and they are really painted there."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from PySide6.QtGui import QImage, QPainter

from dualrgb.app.gui.uniformity_view import CellLabels
from dualrgb.app.workflow.calibration.frame_checks import UniformityMap


def _render(item: CellLabels, scale: float, size: tuple[int, int]) -> QImage:
    img = QImage(size[0], size[1], QImage.Format_ARGB32)
    img.fill(0xFFFFFFFF)
    p = QPainter(img)
    p.scale(scale, scale)                        # the view's data -> screen transform
    item.paint(p)
    p.end()
    return img


def _dark_pixels(img: QImage, x0: int, y0: int, x1: int, y1: int) -> int:
    return sum(1 for x in range(x0, x1) for y in range(y0, y1) if img.pixelColor(x, y).lightness() < 128)


def test_cell_labels_are_painted_at_each_cell_centre(qtbot):
    item = CellLabels()
    item.set_texts([["88", ""], ["", "104"]])
    assert (item.boundingRect().width(), item.boundingRect().height()) == (2.0, 2.0)
    img = _render(item, 60.0, (120, 120))
    assert _dark_pixels(img, 0, 0, 60, 60) > 5 and _dark_pixels(img, 60, 60, 120, 120) > 5      # the labelled cells
    assert _dark_pixels(img, 60, 0, 120, 60) == 0 and _dark_pixels(img, 0, 60, 60, 120) == 0    # the empty ones


def test_the_view_labels_follow_the_map(qtbot):
    from dualrgb.app.gui.uniformity_view import UniformityView

    # only what the view reads at construction: the workspace's lights and their change signal
    ctx = SimpleNamespace(workspace=SimpleNamespace(lights=[], lightsChanged=SimpleNamespace(connect=lambda _s: None)))
    view = UniformityView(ctx)
    qtbot.addWidget(view)
    view.show_map(UniformityMap("LS1", 0.5, 3, np.array([[97.6, 100.2, 102.5], [99.4, 100.0, 101.0]]), 5.1))
    assert view.labels.texts == [["98", "100", "102"], ["99", "100", "101"]]
    view.show_map(UniformityMap("LS1", 0.5, 3, np.array([[90.0], [110.0]]), 20.0))
    assert view.labels.texts == [["90"], ["110"]]
    assert view.labels.boundingRect().width() == 1.0 and "20.0" in view.info.text()
