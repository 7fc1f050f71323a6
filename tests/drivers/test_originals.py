"""The virtual lab's originals: measured spectra, per-pixel ground truth, rendering like a chart, the copy stand."""
from __future__ import annotations

import colour
import numpy as np
import pytest
from colour.quality import SDS_TCS, SDS_VS

from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.originals import (
    OHTA_NEUTRALS,
    ORIGINALS,
    ground_truth_xyz,
    measured_spectra,
    original,
    original_name,
)
from dualrgb.drivers.virtual.scene import Scene, original_scene
from dualrgb.simulation.camera_model import channel_responses
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.grid import DEFAULT_GRID

BLACK = 600


def light(*leds: int) -> StaticLight:
    levels = np.zeros(10)
    levels[[n - 1 for n in leds]] = 1.0
    return StaticLight(levels)


def colour_xyz(sd: colour.SpectralDistribution, scale: float = 1.0) -> np.ndarray:
    """Independent eq 4.2: colour-science's integration on the 410-780 nm / 10 nm grid, D65, CIE 1931 2 deg."""
    shape = colour.SpectralShape(410, 780, 10)
    sd = sd.copy().align(shape)                  # 5 nm data: the 10 nm samples are measured values
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape)
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(shape)
    return colour.sd_to_XYZ(sd * scale, cmfs, d65, method="Integration")


def region_values(truth: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    r0, r1, c0, c1 = box
    return truth[r0:r1, c0:c1].reshape(-1, 3)


# ---------------------------------------------------------------- ground truth
@pytest.mark.parametrize("name, region, sd, scale", [
    ("painting", "near-white", colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"][OHTA_NEUTRALS["white 9.5"]], 1.0),
    ("painting", "dark", colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"][OHTA_NEUTRALS["black 2"]], 1.0),
    ("painting", "red", SDS_TCS["CIE 1995"]["TCS09"], 1.0),
    ("shadow", "deep shadow", colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"][OHTA_NEUTRALS["black 2"]], 0.03),
])
def test_a_pure_material_region_has_the_tristimulus_of_its_measured_spectrum(name, region, sd, scale):
    truth = ground_truth_xyz(name, 400, 600)
    values = region_values(truth, original(name).region_boxes(400, 600)[region])
    assert np.ptp(values, axis=0).max() == 0                                  # one material: one value
    np.testing.assert_allclose(values[0], colour_xyz(sd, scale), rtol=2e-5, atol=1e-6)


def test_clear_film_base_has_y_of_its_transmittance():
    """Hand check: a flat transmittance T has XYZ = T x the white's XYZ; the base density is 0.05."""
    truth = ground_truth_xyz("film", 400, 600)
    values = region_values(truth, original("film").region_boxes(400, 600)["near-white"])
    setup = default_setup("transmissive", DEFAULT_GRID)            # the grid ground_truth_xyz used
    white = 100.0 * (setup.illuminant @ setup.cmfs) / (setup.illuminant @ setup.cmfs[:, 1])
    np.testing.assert_allclose(values, np.broadcast_to(10 ** -0.05 * white, values.shape), rtol=1e-5)


def test_truth_is_one_value_per_bayer_cell_rows_down_columns_right():
    truth = ground_truth_xyz("painting", 400, 600)
    assert truth.shape == (400, 600, 3) and truth.dtype == np.float32
    for dy, dx in ((0, 1), (1, 0), (1, 1)):
        np.testing.assert_array_equal(truth[dy::2, dx::2], truth[0::2, 0::2])
    boxes = original("painting").region_boxes(400, 600)
    assert boxes["near-white"][0] < boxes["dark"][0]                          # the sun is above the pool ...
    assert boxes["near-white"][2] > boxes["dark"][2]                          # ... and right of it
    assert all(v % 2 == 0 for box in boxes.values() for v in box)


@pytest.mark.parametrize("name", list(ORIGINALS))
def test_each_original_has_structure_a_near_white_and_a_dark_area(name):
    o = original(name)
    truth = ground_truth_xyz(name, 400, 600)
    y = truth[..., 1]
    assert o.n_classes > 200                                                  # gradients: many steps
    assert len(np.unique(y)) > 100
    assert y.max() > 85                                                      # near-white
    assert y.min() < (1.0 if name == "shadow" else 6.0)                       # dark (deep for 'shadow')
    rows_changes = np.count_nonzero(np.diff(y[::2, ::2], axis=1) != 0, axis=1)
    assert rows_changes.max() > 40                                            # fine lines / ramps across a row
    assert np.all(o.spectra >= 0) and np.all(o.spectra <= 1.0)


def test_measured_spectra_come_from_colour_science_on_the_grid():
    m = measured_spectra()
    assert {f"TCS{k:02d}" for k in range(1, 15)} <= set(m) and {f"VS{k}" for k in range(1, 16)} <= set(m)
    assert all(v.shape == (len(DEFAULT_GRID),) for v in m.values())
    tcs = SDS_TCS["CIE 1995"]["TCS05"]
    np.testing.assert_allclose(m["TCS05"], [tcs[w] for w in DEFAULT_GRID.wavelengths])
    np.testing.assert_allclose(m["VS3"][0], SDS_VS["NIST CQS 9.0"]["VS3"][410.0])


def test_class_map_is_cached_read_only_and_scales_with_the_frame():
    o = original("painting")
    small = o.class_map(400, 600)
    assert small is o.class_map(400, 600) and not small.flags.writeable
    big = o.class_map(800, 1200)
    # same picture at twice the size: the large map sampled every other superpixel matches most cells
    assert np.mean(big[::2, ::2] == small) > 0.9


# ---------------------------------------------------------------- rendering
def test_bayer_planes_and_previews_see_the_class_map():
    o = original("painting")
    scene = Scene.with_original(o, 600, 400)
    cmap = o.class_map(400, 600)
    for py, px in ((0, 0), (0, 1), (1, 0), (1, 1)):
        np.testing.assert_array_equal(scene.labels(np.arange(py, 400, 2), np.arange(px, 600, 2)), cmap)
    np.testing.assert_array_equal(scene.labels(np.arange(0, 400, 4), np.arange(0, 600, 4)), cmap[::2, ::2])
    assert scene.n_classes == o.n_classes and scene.n_patches == 0
    assert scene.describe()["original"] == "painting"


@pytest.mark.parametrize("name", list(ORIGINALS))
def test_region_means_follow_eq_5_10_like_chart_patches(name):
    """Raw region means over the open gate's equal the simulated response ratio (independent eq 5.10)."""
    snap = light(1, 6, 8)
    cam = VirtualCamera(lambda: snap, Scene.open_gate(600, 400, vignetting=0.0), seed=4)
    cam.open()
    gate = cam.render_mosaic(1 / 60).astype(float) - BLACK
    cam.scene = original_scene(name, 600, 400, vignetting=0.0)
    frame = cam.render_mosaic(1 / 60).astype(float) - BLACK
    setup = default_setup(original(name).mode, DEFAULT_GRID)          # the camera's and the original's grid
    spd = snap.levels @ setup.leds
    o = original(name)
    for region, (r0, r1, c0, c1) in o.region_boxes(400, 600).items():
        expected = (channel_responses(spd, o.spectra[o.region_class(region)], setup.camera)
                    / channel_responses(spd, np.ones(len(spd)), setup.camera))[0]
        for ch, (py, px) in enumerate(((0, 0), (0, 1), (1, 1))):
            measured = frame[r0 + py:r1:2, c0 + px:c1:2].mean() / gate[r0 + py:r1:2, c0 + px:c1:2].mean()
            assert measured == pytest.approx(expected[ch], rel=0.02, abs=0.002), (region, ch)


def test_light_drift_reaches_an_original():
    snap = light(1, 6, 8)
    cam = VirtualCamera(lambda: snap, original_scene("painting", 240, 160), seed=1)
    cam.open()
    fresh = cam.class_responses()
    snap.peak_shift_nm = np.full(10, 6.0)
    warm = cam.class_responses()
    assert np.abs(warm / fresh - 1).max() > 0.02
    r0, r1, c0, c1 = original("painting").region_boxes(160, 240)["red"]
    red = cam.render_mosaic(1 / 60)[r0:r1:2, c0:c1:2].astype(float).mean() - BLACK
    cls = original("painting").region_class("red")
    assert red == pytest.approx(warm[cls, 0] * cam.exposure_gain(1 / 60), rel=0.03)   # (centre: vignetting ~1 %)


# ---------------------------------------------------------------- names and refusals
def test_names_and_refusals():
    assert original_name("original:film") == "film" and original_name("shadow") == "shadow"
    with pytest.raises(ValueError, match="unknown original 'original:statue'.*original:painting"):
        original_name("original:statue")
    with pytest.raises(ValueError, match="ND filter over original 'painting'"):
        original_scene("original:painting", 600, 400, nd_filter=True)
    with pytest.raises(ValueError, match="needs an original"):
        Scene(kind="original")
    with pytest.raises(ValueError, match="at 601x400: expected an even number"):
        ground_truth_xyz("painting", 400, 601)


def test_virtual_lab_places_originals_and_gives_their_truth():
    from dualrgb.drivers.virtual.lab import VirtualLab

    with VirtualLab(frame_size=(240, 160), timeout_s=0.3) as lab:
        scene = lab.place("original:painting")
        assert lab.camera.scene is scene and scene.kind == "original" and lab.placed == "original:painting"
        assert lab.place("train").kind == "target" and lab.place("lens-cap").kind == "lens_cap"
        assert lab.scene_for("original:shadow").original.name == "shadow"
        truth = lab.ground_truth_xyz("original:painting", 160, 240)
        np.testing.assert_array_equal(truth, ground_truth_xyz("painting", 160, 240))
        assert lab.ground_truth_xyz("film").shape == (160, 240, 3)
        with pytest.raises(ValueError, match="cannot place 'statue'.*original:painting"):
            lab.place("statue")
