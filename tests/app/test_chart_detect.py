"""Patches found as at a physical stand (issue 36): app.processing.chart_detect finds the ColorChecker Classic, the
Digital SG, the IT8.7/1 (film) and IT8.7/2 and the lab's generic grid in the virtual camera's frames from the
chart's layout alone, wherever the chart lies, within a fraction of a pixel of the scene's own corners; ArgyllCMS
scanin, run as the external program it is, agrees where it recognises the chart; a real photograph of a Classic
(tests/data/photos) is found with every sampling window inside the patch its author labelled by hand; a mirrored
chart, an empty frame and the wrong layout are refused in one line."""
from __future__ import annotations

import numpy as np
import pytest
from chart_frames import CHARTS, POSE, chart, shoot

from dualrgb.app.processing.chart_detect import ChartNotFound, detect_chart
from dualrgb.app.processing.placement import fit_residual
from dualrgb.app.processing.scanin import ScaninUnavailable, patch_index, scanin_grid, template_for
from dualrgb.app.workflow.calibration.targets import reference_xyz
from dualrgb.drivers.virtual.chart_pose import ChartPose
from dualrgb.simulation.chart_geometry import classic24, digital_sg, geometry_of, it8

CORNER_TOLERANCE = 1.0          # superpixels; measured 0.05-0.5 (docs/explanation/chart-detection.md)


def _detect(c, img, **kw):
    xyz, _ = reference_xyz(c.kind, c.role, chart=c)
    return detect_chart(img, geometry_of(c), reference=xyz, cells=c.used_cells, **kw)


@pytest.mark.parametrize("kind, pose", [
    ("cc24", POSE), ("cc24", ChartPose(rotation_deg=178, scale=0.9)), ("cc24", ChartPose(rotation_deg=90, scale=0.6)),
    ("sg", POSE), ("sg", ChartPose(rotation_deg=-7, shift_x=-0.05, shift_y=0.04, scale=0.8)),
    ("it87-1", POSE), ("it87-1", None), ("it87-2", POSE), ("grid", POSE)])
def test_the_chart_is_found_wherever_it_lies(kind, pose):
    c = chart(kind)
    _scene, img, truth = shoot(c, pose)
    grid = _detect(c, img)
    err = np.linalg.norm(grid.corners - truth, axis=1)
    print(f"{kind} {pose}: corner error max {err.max():.2f} px, mean {err.mean():.2f} px")
    assert err.max() < CORNER_TOLERANCE
    assert (grid.rows, grid.cols) == c.layout


def test_a_small_frame_is_searched_enlarged():
    """240 x 160 sensor pixels (the CLI tests' frames): the SG's patches are 5 superpixels, its gaps one."""
    c = chart("sg")
    _scene, img, truth = shoot(c, POSE, size=(240, 160))
    assert np.linalg.norm(_detect(c, img).corners - truth, axis=1).max() < CORNER_TOLERANCE


@pytest.mark.fault("input")
def test_a_mirrored_chart_is_refused():
    c = chart("it87-1")
    _scene, img, _ = shoot(c, POSE)
    with pytest.raises(ChartNotFound, match="seen mirrored.*turn it over"):
        _detect(c, img[:, ::-1], label="train target")


@pytest.mark.fault("input")
def test_no_chart_or_another_layout_is_refused_in_one_line():
    noise = np.random.default_rng(0).uniform(100, 4000, (200, 300, 3))
    with pytest.raises(ChartNotFound, match="is not in the frame") as exc:
        detect_chart(noise, classic24(), label="test target")
    assert "\n" not in str(exc.value) and str(exc.value).startswith("test target: the ColorChecker Classic")
    c = chart("cc24")
    _scene, img, _ = shoot(c, POSE)
    sg = chart("sg")
    xyz, _ = reference_xyz("reflective", "train", chart=sg)
    try:
        grid = detect_chart(img, digital_sg(), reference=xyz, cells=sg.used_cells)
    except ChartNotFound:
        return                                              # refused at once
    # found "something": its values do not follow the SG's reference (the placement check refuses it)
    assert fit_residual(grid.sample(img).mean[sg.used_cells], xyz) > 0.35


def test_without_a_reference_the_upright_chart_is_taken():
    c = chart("cc24")
    _scene, img, truth = shoot(c, POSE)
    grid = detect_chart(img, geometry_of(c))
    assert np.linalg.norm(grid.corners - truth, axis=1).max() < CORNER_TOLERANCE


# ---------------------------------------------------------------- ArgyllCMS scanin, the independent check
def _scanin_or_skip(geometry):
    try:
        template_for(geometry)
    except ScaninUnavailable as exc:
        pytest.skip(str(exc))


@pytest.mark.parametrize("kind", ["cc24", "it87-1", "it87-2"])
def test_scanin_finds_the_same_patches(kind):
    """scanin's recognition (its own edge lists and templates) against ours on the same posed frame: the corners
    agree within 2 superpixels (scanin's sampled areas are whole pixels; measured 0.4-1.6)."""
    c = chart(kind)
    geometry = geometry_of(c)
    _scanin_or_skip(geometry)
    _scene, img, truth = shoot(c, POSE)
    theirs = scanin_grid(img, geometry)
    ours = _detect(c, img)
    gap = np.linalg.norm(theirs.corners - ours.corners, axis=1).max()
    print(f"{kind}: scanin against ours {gap:.2f} px, against the scene "
          f"{np.linalg.norm(theirs.corners - truth, axis=1).max():.2f} px")
    assert gap < 2.0 and np.linalg.norm(theirs.corners - truth, axis=1).max() < 2.0


def test_scanin_missing_names_its_debian_package(monkeypatch):
    import shutil

    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(ScaninUnavailable, match="Debian package 'argyll'"):
        template_for(classic24())


def test_scanin_patch_names_map_to_the_geometry():
    assert patch_index(classic24(), "A1") == 0 and patch_index(classic24(), "D6") == 23
    assert patch_index(classic24(), "B1") == 6                              # rows A-D
    assert patch_index(digital_sg(), "B1") == 1 and patch_index(digital_sg(), "A2") == 14     # columns A-N
    g = it8()
    assert patch_index(g, "A01") == 0 and patch_index(g, "L22") == 263 and patch_index(g, "GS23") == 287
    assert patch_index(g, "M01") is None and patch_index(g, "GS24") is None


def test_scanin_is_asked_when_the_own_search_finds_nothing(monkeypatch):
    from dualrgb.app.processing import chart_detect

    c = chart("it87-1")
    _scanin_or_skip(geometry_of(c))
    _scene, img, truth = shoot(c, POSE)

    def nothing(*args, **kwargs):
        raise ChartNotFound("the own search found nothing")
    monkeypatch.setattr(chart_detect, "_own_search", nothing)
    grid = _detect(c, img)
    assert np.linalg.norm(grid.corners - truth, axis=1).max() < 2.0
    monkeypatch.setattr("shutil.which", lambda name: None)                   # and without scanin: the own line
    with pytest.raises(ChartNotFound, match="the own search found nothing"):
        _detect(c, img)


def test_a_photograph_of_a_real_classic_is_found():
    """A ColorChecker Classic photographed in perspective on a dotted backdrop (B. Llanos, Boost licence; see
    tests/data/photos/README.md), display-encoded (taken as gamma 2.2): every sampling window lies inside the patch
    the photograph's author labelled by hand (scanin does not recognise this one)."""
    from PIL import Image

    photos = CHARTS.parent / "photos"
    rgb = np.asarray(Image.open(photos / "colorchecker_classic_llanos.png"), dtype=float)
    labels = np.asarray(Image.open(photos / "colorchecker_classic_llanos_labels.png"))
    c = chart("cc24")
    grid = _detect(c, (rgb / 255) ** 2.2, label="photo")
    inside = [float((labels[rs, cs][m] == k + 1).mean()) for k, (rs, cs, m) in enumerate(grid.masks(labels.shape))]
    print(f"photograph: corners {np.round(grid.corners, 1).tolist()}; window pixels in their labelled patch: "
          f"{min(inside):.3f} at worst")
    assert min(inside) == 1.0
