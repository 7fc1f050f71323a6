"""PatchGrid on rotated / perspective quadrilaterals, robust means, and the optional CC24 detector."""
from __future__ import annotations

import builtins
import importlib.util
import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dualrgb.app.processing import patches as patches_mod
from dualrgb.app.processing.patches import PatchGrid, detect_cc24, homography

# find_spec, not importorskip: importing the package directly would let OpenCV repoint Qt's plugin path in
# this pytest process (what detect_cc24 guards against) and break Qt tests that run after these
needs_ccd = pytest.mark.skipif(importlib.util.find_spec("colour_checker_detection") is None,
                               reason="colour-checker-detection not installed (optional extra 'detect')")


def render_chart(corners: np.ndarray, rows: int, cols: int, values: np.ndarray, shape: tuple[int, int],
                 gap: float = 0.1, background: float = -1.0) -> np.ndarray:
    """Image of a target whose patch area maps to ``corners`` (TL, TR, BR, BL): every pixel takes the value of
    the cell it falls in (gaps of ``gap`` cell fraction between patches get ``background``)."""
    h = homography(corners, np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float))
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    p = np.c_[xx.ravel(), yy.ravel(), np.ones(xx.size)] @ h.T
    u, v = p[:, 0] / p[:, 2] * cols, p[:, 1] / p[:, 2] * rows
    inside = (u >= 0) & (u < cols) & (v >= 0) & (v < rows)
    cu, cv = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - cu, v - cv
    patch = inside & (fu > gap / 2) & (fu < 1 - gap / 2) & (fv > gap / 2) & (fv < 1 - gap / 2)
    C = values.shape[1]
    img = np.full((xx.size, C), background, dtype=float)
    idx = (cv * cols + cu)[patch]
    img[patch] = values[idx]
    return img.reshape(shape + (C,))


def rotated_corners(cx, cy, w, h, angle_deg, skew=0.0):
    a = np.deg2rad(angle_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    local = np.array([[-w / 2, -h / 2], [w / 2, -h / 2 + skew], [w / 2, h / 2 - skew], [-w / 2, h / 2]])
    return local @ R.T + [cx, cy]


def test_patch_grid_on_rotated_perspective_quadrilateral():
    rows, cols = 4, 6
    rng = np.random.default_rng(0)
    values = rng.uniform(0.05, 0.9, (rows * cols, 3))
    corners = rotated_corners(160, 120, 220, 150, 23.0, skew=12.0)      # rotated, one side shorter (perspective)
    img = render_chart(corners, rows, cols, values, (240, 320))
    # dirt: hot pixels and NaN (no flat field) inside the patches must not move the robust mean
    hot = rng.random(img.shape[:2]) < 0.01
    img[hot] = 50.0
    img[rng.random(img.shape[:2]) < 0.01] = np.nan
    grid = PatchGrid(corners, rows, cols, fraction=0.6)
    pv = grid.sample(img)
    assert pv.mean.shape == (24, 3) and (pv.count > 40).all()
    assert np.allclose(pv.mean, values, atol=1e-9)                       # hot pixels trimmed away, NaN ignored
    # centres land inside the right patches, in row-major order from the target's top-left
    cen = grid.centres()
    back = grid.to_target(cen)
    assert np.allclose(back[:, 0] * cols % 1, 0.5) and np.allclose(back[:, 1] * rows % 1, 0.5)
    assert grid.sample_polygons().shape == (24, 4, 2)


def test_patch_grid_any_corner_orientation_and_scaling():
    rows, cols = 2, 3
    values = np.arange(6, dtype=float)[:, None] + 1
    corners = np.array([[10, 10], [70, 10], [70, 50], [10, 50]], float)
    img = render_chart(corners, rows, cols, values, (64, 80))
    assert np.allclose(PatchGrid(corners, rows, cols).sample(img).mean[:, 0], values[:, 0])
    # the target photographed upside down: give its corners in the target's own order
    flipped = corners[[2, 3, 0, 1]]
    assert np.allclose(PatchGrid(flipped, rows, cols).sample(img).mean[:, 0], values[::-1, 0])
    # a grid placed on the full mosaic, used on the half-size superpixel image
    small = img[::2, ::2]
    g = PatchGrid(corners, rows, cols, 0.5).scaled(0.5)
    assert np.allclose(g.sample(small).mean[:, 0], values[:, 0])


def test_patch_grid_validation_and_outside_cells(caplog):
    with pytest.raises(ValueError, match="convex quadrilateral"):
        PatchGrid(np.array([[0, 0], [10, 10], [10, 0], [0, 10]]), 2, 2)
    with pytest.raises(ValueError, match="fraction"):
        PatchGrid(np.array([[0, 0], [10, 0], [10, 10], [0, 10]]), 2, 2, fraction=0)
    g = PatchGrid(np.array([[-40, 0], [20, 0], [20, 20], [-40, 20]]), 1, 3)
    with caplog.at_level(logging.WARNING):
        pv = g.sample(np.ones((30, 30)))
    assert pv.count[0] == 0 and np.isnan(pv.mean[0, 0]) and pv.mean[2, 0] == 1.0
    assert "no usable pixels" in caplog.text


def test_detect_cc24_without_the_package_returns_none(monkeypatch, caplog):
    real_import = builtins.__import__

    def no_ccd(name, *args, **kwargs):
        if name.startswith("colour_checker_detection"):
            raise ImportError("No module named 'colour_checker_detection'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ccd)
    with caplog.at_level(logging.INFO):
        assert detect_cc24(np.zeros((50, 60, 3))) is None
    assert "detection unavailable" in caplog.text


def cc24_srgb_linear() -> np.ndarray:
    import colour

    cc = colour.CCS_COLOURCHECKERS["ColorChecker24 - After November 2014"]
    xyz = colour.xyY_to_XYZ(np.array(list(cc.data.values())))
    return np.clip(colour.XYZ_to_sRGB(xyz, apply_cctf_encoding=False), 0, 1)


@needs_ccd
def test_detect_cc24_finds_a_rendered_chart():
    rgb = cc24_srgb_linear()
    corners = rotated_corners(520, 380, 660, 440, 4.0)
    img = render_chart(corners, 4, 6, rgb, (760, 1040), gap=0.15, background=0.03)
    img = np.where(img < 0, 0.03, img)
    det = detect_cc24(img)
    assert det is not None
    # the fitted grid samples the right patches of the original image
    pv = det.grid.sample(img)
    assert np.allclose(pv.mean, rgb, atol=0.02)
    assert det.swatches.shape == (24, 3)


@needs_ccd
def test_detect_cc24_no_chart_returns_none():
    assert detect_cc24(np.random.default_rng(0).uniform(0, 1, (200, 300, 3))) is None
    assert patches_mod.detect_cc24(np.zeros((50, 60, 3))) is None


@needs_ccd
def test_detector_import_keeps_qt_plugin_path():
    code = ("import os\nfrom dualrgb.app.processing.patches import _import_detection\n_import_detection()\n"
            "print(os.environ.get('QT_QPA_PLATFORM_PLUGIN_PATH'))")
    env = {k: v for k, v in os.environ.items() if k not in ("QT_QPA_PLATFORM_PLUGIN_PATH", "QT_QPA_FONTDIR")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env,
                         cwd=str(Path(__file__).resolve().parents[2]))
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "None"
    assert "QT_QPA_PLATFORM_PLUGIN_PATH" not in os.environ      # and detect_cc24 above left this process alone
