"""Issue 42, live view: focus peaking marks a sharp edge and not the same edge out of focus, the grid's lines,
the zoom box at 200 and 400 %, and the aids drawn over the virtual camera's live view."""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from dualrgb.app.gui.live_aids import GRID_RGBA, PEAK_RGBA, live_overlay, magnified, peaking_mask
from tests.gui.conftest import HANG_GUARD_MS, click, connect_devices, wait_idle


def _edge(blur: float = 0.0) -> np.ndarray:
    img = np.full((60, 80), 50.0)
    img[:, 40:] = 200.0
    return ndimage.gaussian_filter(img, blur) if blur else img


def test_peaking_marks_the_sharp_edge_and_not_the_blurred_one():
    sharp = peaking_mask(_edge())
    assert sharp.any() and set(np.nonzero(sharp)[1]) <= {38, 39, 40, 41}   # on the edge (2 px), nowhere else
    assert not peaking_mask(_edge(4.0)).any()                            # out of focus: nothing marked
    assert not peaking_mask(np.full((30, 30, 3), 90.0)).any()            # a flat picture: nothing
    noisy = np.random.default_rng(1).normal(100.0, 2.0, (60, 80))          # sensor noise, no edge
    assert peaking_mask(noisy).sum() == 0


def test_the_overlay_holds_the_grid_and_the_marks():
    frame = np.stack([_edge()] * 3, axis=2)
    over = live_overlay(frame, peaking=True, grid=3)
    assert tuple(over[20, 5]) == GRID_RGBA and tuple(over[5, 26]) == GRID_RGBA      # thirds of 60 x 80
    assert tuple(over[10, 40]) == PEAK_RGBA or tuple(over[10, 39]) == PEAK_RGBA
    assert over[10, 10, 3] == 0
    assert not live_overlay(frame, peaking=False, grid=0)[..., 3].any()


def test_magnified_repeats_pixels():
    crop = np.arange(6, dtype=np.uint8).reshape(2, 3)
    big = magnified(crop, 4)
    assert big.shape == (8, 12) and (big[:4, :4] == 0).all() and (big[4:, 8:] == 5).all()
    assert magnified(crop, 1) is crop


def test_live_view_with_peaking_grid_and_magnification(qtbot, make_window):
    w = make_window()
    connect_devices(qtbot, w)
    cam = w.camera
    w.show_panel("camera")
    cam.peaking.setChecked(True)
    cam.grid.setChecked(True)
    cam.focus.magnification.setCurrentIndex(2)                     # 400 %
    click(qtbot, cam.live_button)
    qtbot.waitUntil(lambda: len(cam.focus.values) >= 2, timeout=HANG_GUARD_MS)
    assert cam.aid_overlay.isVisible() and cam.aid_overlay.image.shape[:2] == cam.image.image.shape[:2]
    _x, _y, bw, bh = cam.focus.region(cam.image.image.shape)
    assert (cam.focus.zoom.pixmap().width(), cam.focus.zoom.pixmap().height()) == (4 * bw, 4 * bh)
    click(qtbot, cam.live_button)
    wait_idle(qtbot, w)
