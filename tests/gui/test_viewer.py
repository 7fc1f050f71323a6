"""Issue 42, the viewer: a delivered master at its full resolution with the pixel's camera RGB, XYZ and L*a*b*
(L* checked against CIE 15's formula written out here), the clipping and under-exposure overlay where the
pixels are, a raw frame's raw DN per Bayer cell, and the Qt viewer's zooms (Fit, 100, 200, 400 %)."""
from __future__ import annotations

import json

import numpy as np
import pytest
from workflow_profiles import make_profile

from dualrgb.app.gui.viewer_model import CLIP_RGBA, UNDER_L, UNDER_RGBA, load_frame, load_master
from dualrgb.app.processing.pipeline import ChannelStack
from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, deliver
from dualrgb.core.metadata import Original

H, W = 24, 32


def _stack() -> ChannelStack:
    img = np.full((H, W, 3), 0.5, np.float32)
    img[2, 3] = 3.0                        # beyond the encoding's ceiling (2x the white): clipped
    img[5, 6] = 0.0                        # black: under-exposed
    img[:, 20:] *= np.linspace(0.2, 1.0, W - 20, dtype=np.float32)[None, :, None]
    return ChannelStack(img, ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0})


@pytest.fixture
def master(tmp_path):
    prof = make_profile(tmp_path / "cal")
    d = deliver(_stack(), prof, Original("東博-A-1"), tmp_path / "out", camera=prof.camera,
                dose=LightDoseRecord(36.0, 0.5))
    return d.sidecar


def _l_star(y_rel: float) -> float:
    """CIE 15 L* of Y / Yn, written out (not colour-science)."""
    f = y_rel ** (1 / 3) if y_rel > (6 / 29) ** 3 else y_rel / (3 * (6 / 29) ** 2) + 4 / 29
    return 116 * f - 16


def test_a_master_at_full_resolution_with_its_values(master):
    pic = load_master(master)
    assert pic.shape == (H, W)                                     # every delivered pixel, none resampled
    doc = json.loads(master.read_text(encoding="utf-8"))
    white = doc["encoding"]["white_xyz"]
    text = pic.values(10, 12)
    assert "camera RGB: R1 0.5" in text and "XYZ" in text and "L*a*b*" in text
    y_rel = float(pic.xyz[12, 10, 1]) / white[1]
    lab_l = float(text.split("L*a*b* ")[1].split()[0])
    assert abs(lab_l - _l_star(y_rel)) < 0.01
    assert pic.values(-1, 0) == "" and pic.values(W, 0) == ""


def test_the_overlay_marks_clipped_and_under_exposed_pixels(master):
    pic = load_master(master)
    assert pic.clipped[2, 3] and not pic.clipped[12, 10] and pic.clipped.sum() == 1
    assert pic.under[5, 6] and not pic.under[12, 10]
    rgba = pic.overlay()
    assert tuple(rgba[2, 3]) == CLIP_RGBA and tuple(rgba[5, 6]) == UNDER_RGBA
    assert rgba[12, 10, 3] == 0                                   # elsewhere: transparent
    assert "clipped" in pic.values(3, 2) and "near black (L* < 3)" in pic.values(6, 5)
    assert UNDER_L > 0


def test_a_raw_frame_in_raw_dn():
    from pathlib import Path

    from dualrgb.drivers.raw import load_raw

    path = Path(__file__).resolve().parents[1] / "data" / "raw" / "Blackmagic.dng"
    frame = load_raw(path)
    pic = load_frame(path)
    assert pic.shape == (frame.height // 2, frame.width // 2)     # one pixel per 2x2 Bayer cell
    assert pic.camera_unit == "DN" and pic.xyz is None
    assert "camera RGB (DN): R " in pic.values(0, 0) and "a delivered master has them" in pic.values(0, 0)


def test_the_viewer_zooms_and_shows_values(qtbot, make_window, master):
    from dualrgb.app.gui.image_viewer import ImageViewer

    w = make_window()
    viewer = ImageViewer(w.ctx)
    qtbot.addWidget(viewer)
    viewer.resize(800, 600)
    viewer.show()
    viewer.show_master(master)
    qtbot.waitUntil(lambda: viewer.picture is not None, timeout=60_000)
    assert "clipped 0.13" in viewer.title.text().replace("\u00a0", " ")      # 1 of 768 pixels
    for zoom in (1.0, 2.0, 4.0):
        viewer.set_zoom(zoom)
        assert viewer.zoom() == pytest.approx(zoom, rel=0.02)
    viewer.zoom_buttons["Fit"].click()
    (x0, x1), _ = viewer.box.viewRange()
    assert x1 - x0 >= W - 0.5
    viewer.clipping.setChecked(False)
    assert not viewer.overlay.isVisible()
    scene_point = viewer.box.mapViewToScene(viewer.box.mapSceneToView(viewer.box.sceneBoundingRect().center()))
    viewer._moved(scene_point)
    assert "XYZ" in viewer.values.text()
