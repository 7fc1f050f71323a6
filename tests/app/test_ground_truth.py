"""Delivery measured against per-pixel ground truth: the virtual originals captured as DNGs, processed like
any capture (master darks, eq 7.1 flats, a least-squares matrix fitted on the captured training chart) and
compared with app.lab.ground_truth; the shadow original's range needs the HDR bracket (thesis 8)."""
from __future__ import annotations

from pathlib import Path

import colour
import numpy as np
import pytest
from PIL import Image

from dualrgb.app.lab.ground_truth import bin_to_superpixels, block_max, compare_to_ground_truth, write_de_map_png
from dualrgb.app.processing.patches import PatchGrid
from dualrgb.app.processing.pipeline import CaptureProcessor, ExposureRef
from dualrgb.app.sequences.hdr import plan_hdr
from dualrgb.drivers.raw import load_raw
from dualrgb.drivers.virtual.camera import SHUTTER_SPEEDS, SensorModel, StaticLight, VirtualCamera
from dualrgb.drivers.virtual.clock import SkippableClock
from dualrgb.drivers.virtual.originals import ground_truth_xyz, original
from dualrgb.drivers.virtual.scene import Scene, original_scene
from dualrgb.simulation.colorimetry import delta_e_2000, tristimulus, white_point, xyz_to_lab
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.matrix_fit import fit_matrix
from dualrgb.simulation.studies.noise import NoiseModel

W, H = 600, 400
SETUP = default_setup("reflective")
WHITE = white_point(SETUP.illuminant, SETUP.cmfs)
MAX_LIGHT_S = 9.0                                        # thesis 4.3.2: 10 s on, minus settling
# A fixed light set, not a packaged preset (those follow the optimiser's objective: issue 14's expected-captured
# presets are dimmer, their shadow HDR is limited by the light-on time): the noise-free thesis-PSO reflective pair.
LIGHTS = (LightSource((1, 6, 7), (0.002242, 0.416392, 1.0)), LightSource((3, 5, 9), (0.660548, 0.393056, 1.0)))


class Rig:
    """A virtual camera under a fixed light set, writing every capture as a DNG file (read back by rawpy)."""

    def __init__(self, folder: Path, sensor: SensorModel | None = None, seed: int = 3):
        self.W = np.stack([s.weights() for s in LIGHTS])
        self.times = [min(SHUTTER_SPEEDS, key=lambda v, t=t: abs(np.log(v / t)))
                      for t in NoiseModel(SETUP).exposures(self.W)]
        self.lights = [f"light {i + 1}" for i in range(len(self.W))]
        self.state = StaticLight(np.zeros(10))
        # the virtual lab's clock: a lit exposure (up to 9 s here) passes at once instead of being waited out
        self.cam = VirtualCamera(lambda: self.state, Scene.lens_cap(W, H), sensor=sensor, seed=seed,
                                 clock=SkippableClock())
        self.cam.open()
        self.folder, self.n = folder, 0

    def shoot(self, scene: Scene, light: int, exposures, frames: int = 1) -> list[ExposureRef]:
        self.cam.scene, self.state.levels = scene, self.W[light]
        refs = []
        for t in exposures:
            for _ in range(frames):
                raw = self.cam.capture(t)
                self.n += 1
                path = self.folder / f"VIRT_{self.n:04d}.DNG"
                path.write_bytes(raw.data)
                refs.append(ExposureRef(path, t))
        return refs

    def calibrate(self, extra_exposures: dict[int, list[float]] | None = None) -> tuple[CaptureProcessor, dict]:
        """Darks (4 per exposure), one white per light, the training and test charts, the fitted matrix."""
        darks, charts = [], {"train": {}, "test": {}}
        scenes = {k: Scene.with_target(getattr(SETUP, k), W, H) for k in charts}
        for li in range(len(self.lights)):
            for t in sorted({self.times[li], *(extra_exposures or {}).get(li, [])}):
                darks += self.shoot(Scene.lens_cap(W, H), li, [t], frames=4)
        proc = CaptureProcessor(dark_frames=darks, white_level=self.cam.sensor.white_level, cfa="RGGB")
        for li, name in enumerate(self.lights):
            proc.set_white(name, self.shoot(Scene.open_gate(W, H), li, [self.times[li]]))
            for key, scene in scenes.items():
                charts[key][name] = self.shoot(scene, li, [self.times[li]])
        values = {}
        for key, scene in scenes.items():
            corners = np.array([[c / 2.0 - 0.5, r / 2.0 - 0.5] for r, c in scene.corners()])
            stack = proc.stack(charts[key]).data
            values[key] = PatchGrid(corners, *scene.layout, 0.6).sample(stack).mean[:scene.n_patches]
        xyz = {k: tristimulus(getattr(SETUP, k).spectra, SETUP.illuminant, SETUP.cmfs) for k in values}
        matrix = fit_matrix(values["train"], xyz["train"])
        errors = {k: float(delta_e_2000(xyz_to_lab(xyz[k], WHITE), xyz_to_lab(matrix.apply(values[k]), WHITE)).mean())
                  for k in values}
        return proc, {"matrix": matrix, **errors}

    def deliver(self, proc: CaptureProcessor, matrix, name: str, exposures: dict[int, list[float]]) -> np.ndarray:
        scene = original_scene(name, W, H)
        refs = {ln: self.shoot(scene, li, exposures[li]) for li, ln in enumerate(self.lights)}
        return proc.stack(refs).data @ matrix.matrix.astype(np.float32)


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    rig = Rig(tmp_path_factory.mktemp("noisy"))
    meter = {li: plan_hdr(load_raw(rig.shoot(original_scene("shadow", W, H), li, [t])[0].source), t,
                          list(original("shadow").region_boxes(H, W).values()), SHUTTER_SPEEDS,
                          max_exposure_s=MAX_LIGHT_S) for li, t in enumerate(rig.times)}
    proc, cal = rig.calibrate({li: p.exposures for li, p in meter.items()})
    base = {li: [t] for li, t in enumerate(rig.times)}
    return {"rig": rig, "cal": cal, "meter": meter,
            "painting": rig.deliver(proc, cal["matrix"], "painting", base),
            "shadow_single": rig.deliver(proc, cal["matrix"], "shadow", base),
            "shadow_hdr": rig.deliver(proc, cal["matrix"], "shadow", {li: p.exposures for li, p in meter.items()})}


def test_painting_per_pixel_de00_against_truth_matches_the_chart_test_error(tmp_path):
    """A low-noise sensor isolates colour error and geometry: the per-pixel map's mean is the chart's test
    error (painting 0.36 vs test chart 0.32 with the dual-RGB-PSO preset), and no edge pixel stands out, so
    the truth is aligned with the delivered superpixels."""
    rig = Rig(tmp_path, sensor=SensorModel(electrons_per_dn_iso100=1e5, read_noise_dn=0.0, dark_current_e_per_s=0.0))
    proc, cal = rig.calibrate()
    xyz = rig.deliver(proc, cal["matrix"], "painting", {li: [t] for li, t in enumerate(rig.times)})
    assert xyz.shape == (H // 2, W // 2, 3)
    res = compare_to_ground_truth(xyz, ground_truth_xyz("painting", H, W), WHITE)
    assert res.n_invalid == 0 and res.n_pixels == (H // 2) * (W // 2)
    assert res.mean == pytest.approx(cal["test"], abs=0.15)
    assert res.max < 2.0                                    # a one-superpixel misalignment gives > 10 at edges
    assert res.material_mean == pytest.approx(res.mean, abs=0.05)


def test_noise_adds_to_the_per_pixel_error_but_not_to_the_material_means(noisy):
    """Single 14-bit frames: the material means keep the chart's accuracy (0.36 vs 0.32); per pixel, sensor
    noise through the 6x3 matrix adds ~0.7 dE00 (mean ~1.0)."""
    res = compare_to_ground_truth(noisy["painting"], ground_truth_xyz("painting", H, W), WHITE)
    assert res.material_mean == pytest.approx(noisy["cal"]["test"], abs=0.15)
    assert res.mean > res.material_mean + 0.3
    assert res.p90 > res.mean and res.max >= res.p90
    assert res.de_map.shape == (H // 2, W // 2)


def test_shadow_metered_range_exceeds_the_linear_range_and_hdr_recovers_it(noisy):
    linear_range = (11000.0 - 600.0) / 100.0                # linear limit / plan_hdr's minimum signal (DN)
    for plan in noisy["meter"].values():
        assert plan.darkest_dn < 20 and plan.dynamic_range > 5 * linear_range
        assert len(plan.exposures) >= 2 and not plan.limited_by_light_time
    truth = ground_truth_xyz("shadow", H, W)
    r0, r1, c0, c1 = original("shadow").region_boxes(H, W)["deep shadow"]
    mask = np.zeros((H // 2, W // 2), bool)
    mask[r0 // 2:r1 // 2, c0 // 2:c1 // 2] = True
    single = compare_to_ground_truth(noisy["shadow_single"], truth, WHITE, mask=mask)
    hdr = compare_to_ground_truth(noisy["shadow_hdr"], truth, WHITE, mask=mask)
    assert hdr.mean < 0.3 * single.mean                     # ~0.5 vs ~3.6 dE00 per pixel in the deep shadow


def test_painting_and_film_fit_one_exposure(tmp_path):
    rig = Rig(tmp_path)
    for name in ("painting", "film"):
        for li, t in enumerate(rig.times):
            frame = load_raw(rig.shoot(original_scene(name, W, H), li, [t])[0].source)
            plan = plan_hdr(frame, t, list(original(name).region_boxes(H, W).values()), SHUTTER_SPEEDS,
                            max_exposure_s=MAX_LIGHT_S)
            assert plan.exposures == [t], (name, li)


# ---------------------------------------------------------------- the comparison itself
def test_de00_agrees_with_colour_science_and_truth_is_binned():
    rng = np.random.default_rng(1)
    truth_sp = rng.uniform(1, 90, (6, 8, 3)).astype(np.float32)
    est = truth_sp * rng.uniform(0.95, 1.05, truth_sp.shape).astype(np.float32)
    truth_sensor = np.repeat(np.repeat(truth_sp, 2, axis=0), 2, axis=1)
    res = compare_to_ground_truth(est, truth_sensor, WHITE)                 # sensor-size truth: binned here
    ref = colour.delta_E(colour.XYZ_to_Lab(truth_sp / 100.0, colour.XYZ_to_xy(WHITE / 100.0)),
                         colour.XYZ_to_Lab(est / 100.0, colour.XYZ_to_xy(WHITE / 100.0)), method="CIE 2000")
    np.testing.assert_allclose(res.de_map, ref, rtol=1e-4, atol=1e-5)
    assert res.mean == pytest.approx(ref.mean(), rel=1e-5) and res.max == pytest.approx(ref.max(), rel=1e-5)
    assert res.p90 == pytest.approx(np.percentile(ref, 90), rel=1e-4)
    np.testing.assert_array_equal(bin_to_superpixels(truth_sensor), truth_sp)
    assert compare_to_ground_truth(truth_sp, truth_sp, WHITE).max == 0


def test_material_means_average_noise_out_and_invalid_pixels_are_counted():
    truth = np.zeros((20, 20, 3), np.float32)
    truth[:, :10] = (20.0, 21.0, 22.0)
    truth[:, 10:] = (60.0, 50.0, 30.0)
    rng = np.random.default_rng(0)
    noise = rng.normal(0, 1.0, truth.shape).astype(np.float32)
    noise -= noise.reshape(2, 10, 2, 10, 3).mean(axis=(1, 3)).repeat(10, 0).repeat(10, 1)   # zero-mean per side
    est = truth + noise
    est[0, 0] = np.nan
    res = compare_to_ground_truth(est, truth, WHITE)
    assert res.n_invalid == 1 and res.n_pixels == 399 and np.isnan(res.de_map[0, 0])
    assert res.n_materials == 2 and res.material_mean < 0.05 < res.mean


def test_mismatched_sizes_are_one_line_errors():
    with pytest.raises(ValueError, match="does not match the delivered image 8x6"):
        compare_to_ground_truth(np.ones((6, 8, 3)), np.ones((10, 10, 3)), WHITE)
    with pytest.raises(ValueError, match=r"expected \(H, W, 3\)"):
        compare_to_ground_truth(np.ones((6, 8)), np.ones((6, 8, 3)), WHITE)


def test_de_map_png_and_its_reduction_keep_one_bad_pixel_visible(tmp_path):
    big = np.zeros((2400, 3600), np.float32)                  # a 24 MP superpixel map is 2014 x 3040
    big[601, 843] = 40.0
    big[:12, :24] = np.nan
    small = block_max(big, 300)
    assert small.shape == (200, 300) and small[601 // 12, 843 // 12] == 40.0 and np.nansum(small) == 40.0
    assert np.isnan(small[0, :2]).all() and not np.isnan(small[0, 2])
    for path in (write_de_map_png(tmp_path / "a.png", small, title="painting"),
                 write_de_map_png(tmp_path / "b.png", big)):
        img = np.asarray(Image.open(path).convert("RGB"))
        assert img.shape[0] > 300 and img.shape[1] > 400
