"""The virtual lab camera and its scene: DNG round trip, sensor physics, the thesis' checks, the interface."""
from __future__ import annotations

import io
from dataclasses import dataclass, field, replace

import numpy as np
import pytest
import rawpy
import tifffile

from dualrgb.drivers.camera.base import CameraError, CameraSettings
from dualrgb.drivers.virtual.camera import CAMERA_NAME, SensorModel, VirtualCamera, parse_shutter
from dualrgb.drivers.virtual.clock import SkippableClock
from dualrgb.drivers.virtual.dng import DngInfo, dng_bytes
from dualrgb.drivers.virtual.scene import Scene
from dualrgb.simulation.camera_model import channel_responses
from dualrgb.simulation.datasets import Target, default_setup

BLACK, WHITE = 600, 15520


@dataclass
class Snap:
    """Same fields as drivers.virtual.sphere_emulator.SphereSnapshot."""

    levels: np.ndarray
    peak_shift_nm: np.ndarray = field(default_factory=lambda: np.zeros(10))
    light_on: bool = True


def full_intensity(*leds: int) -> Snap:
    levels = np.zeros(10)
    levels[[n - 1 for n in leds]] = 1.0
    return Snap(levels)


@pytest.fixture
def snap() -> Snap:
    return full_intensity(1, 6, 8)


def make_camera(snap: Snap, scene: Scene | None = None, **kw) -> VirtualCamera:
    cam = VirtualCamera(lambda: snap, scene if scene is not None else Scene.open_gate(240, 160), **kw)
    cam.open()
    return cam


def plane(mosaic: np.ndarray, ch: str) -> np.ndarray:
    """One RGGB plane: 'R', 'G' (the first green), 'B'."""
    py, px = {"R": (0, 0), "G": (0, 1), "B": (1, 1)}[ch]
    return mosaic[py::2, px::2]


def centre_mean(mosaic: np.ndarray, ch: str, size: int = 20) -> float:
    p = plane(mosaic, ch).astype(float)
    h, w = p.shape
    return float(p[h // 2 - size // 2:h // 2 + size // 2, w // 2 - size // 2:w // 2 + size // 2].mean())


def patch_means(mosaic: np.ndarray, scene: Scene, shrink: float = 0.25) -> np.ndarray:
    """(n_patches, 3) mean DN above black of R, G (both greens), B inside each patch's inner box."""
    out = []
    for r0, r1, c0, c1 in scene.patch_boxes():
        dr, dc = int((r1 - r0) * shrink), int((c1 - c0) * shrink)
        box = mosaic[r0 + dr:r1 - dr, c0 + dc:c1 - dc].astype(float)
        rr, cc = np.meshgrid(np.arange(r0 + dr, r1 - dr) % 2, np.arange(c0 + dc, c1 - dc) % 2, indexing="ij")
        out.append([box[(rr == 0) & (cc == 0)].mean(), box[rr != cc].mean(), box[(rr == 1) & (cc == 1)].mean()])
    return np.array(out) - BLACK


def r_squared(x: np.ndarray, y: np.ndarray) -> float:
    slope, intercept = np.polyfit(x, y, 1)
    resid = y - (slope * x + intercept)
    return 1.0 - float(resid @ resid) / float(((y - y.mean()) ** 2).sum())


def grey_target(n: int = 12, value: float = 0.5, layout=(3, 4)) -> Target:
    n_wl = len(default_setup().grid)
    return Target("grey", np.full((n, n_wl), value), [f"g{i}" for i in range(n)], layout)


# --- the DNG file ---------------------------------------------------------------------------------------------
def test_dng_round_trips_bit_exact_through_rawpy(snap):
    scene = Scene.with_target(default_setup().test, 240, 160)
    expected = make_camera(snap, scene, seed=7).render_mosaic(1 / 125)
    cap = make_camera(snap, scene, seed=7).capture(1 / 125)
    with rawpy.imread(io.BytesIO(cap.data)) as raw:
        np.testing.assert_array_equal(raw.raw_image_visible, expected)
        assert raw.raw_image_visible.dtype == np.uint16
        assert list(raw.black_level_per_channel) == [BLACK] * 4
        assert raw.white_level == WHITE
        desc = raw.color_desc.decode()
        assert "".join(desc[i] for i in raw.raw_pattern.reshape(-1)) == "RGGB"
    assert expected.max() <= WHITE and expected.dtype == np.uint16


def test_dng_stores_exposure_iso_aperture_and_camera_name(snap):
    cam = make_camera(snap)
    cam.apply(CameraSettings(iso=100, aperture=5.6))
    cap = cam.capture(1 / 60)
    with tifffile.TiffFile(io.BytesIO(cap.data)) as tif:
        tags = {t.name: t.value for t in tif.pages[0].tags.values()}
    tags.update(tags.pop("ExifTag"))                            # the shooting tags sit in the EXIF IFD
    assert tags["ExposureTime"] == (1, 60)
    assert tags["FNumber"] == (28, 5)
    assert tags["ISOSpeedRatings"] == 100                       # tag 34855 (PhotographicSensitivity)
    assert tags["UniqueCameraModel"] == CAMERA_NAME
    assert tags["BitsPerSample"] == 16 and tags["Compression"] == 1
    assert (cap.exposure_s, cap.iso, cap.aperture, cap.camera) == (1 / 60, 100, 5.6, CAMERA_NAME)


def test_dng_loads_with_the_projects_raw_loader(snap, tmp_path):
    from dualrgb.drivers.raw import load_raw

    cap = make_camera(snap).capture(1 / 60)
    path = tmp_path / cap.filename
    path.write_bytes(cap.data)
    frame = load_raw(path)
    assert frame.mosaic.shape == (160, 240)
    assert frame.white_level == WHITE and set(frame.black_levels) == {BLACK}
    assert frame.exposure_s == pytest.approx(1 / 60)


def test_dng_writer_rejects_non_uint16():
    with pytest.raises(ValueError, match="uint16"):
        dng_bytes(np.zeros((4, 4), np.float32), DngInfo(exposure_s=1, iso=100, aperture=8))


# --- sensor physics -------------------------------------------------------------------------------------------
def test_lens_cap_gives_black_level_plus_read_noise(snap):
    cam = make_camera(snap, Scene.lens_cap(240, 160))
    m = cam.render_mosaic(1 / 60).astype(float)
    body = np.sort(m.reshape(-1))[:-10]                         # a few hot pixels aside
    assert body.mean() == pytest.approx(BLACK, abs=0.3)
    assert 2.0 < body.std() < 3.2


def test_hot_pixels_show_in_long_dark_frames(snap):
    cam = make_camera(snap, Scene.lens_cap(240, 160))
    m = cam.render_mosaic(30.0)
    assert 1 <= int((m > BLACK + 100).sum()) <= 10


def test_light_off_is_dark(snap):
    snap.light_on = False
    m = make_camera(snap).render_mosaic(1 / 60).astype(float)
    assert np.median(m) == pytest.approx(BLACK, abs=1)


def test_open_gate_calibration_follows_table_7_1(snap):
    m = make_camera(snap).render_mosaic(1 / 60)
    brightest = max(centre_mean(m, c) for c in "RGB")
    assert 10000 < brightest < 11000                            # just under the knee at 1/60 s, ISO 50


def test_linear_below_knee_compressive_above_and_clipped(snap):
    cam = make_camera(snap)
    means = {t: {c: centre_mean(cam.render_mosaic(t), c) - BLACK for c in "RGB"} for t in (1 / 250, 1 / 125, 1 / 30)}
    means[1 / 60] = {c: centre_mean(cam.render_mosaic(1 / 60), c) - BLACK for c in "RGB"}
    for c in "RGB":
        assert means[1 / 125][c] / means[1 / 250][c] == pytest.approx(2.0, rel=0.01)
    # the brightest channel (B under (1,6,8)) passes the knee when doubled from 1/60 s to 1/30 s
    assert means[1 / 30]["B"] / means[1 / 60]["B"] < 1.6
    # a channel still under ~11 000 DN at 1/30 s doubles
    assert means[1 / 30]["G"] + BLACK < 11000
    assert means[1 / 30]["G"] / means[1 / 60]["G"] == pytest.approx(2.0, rel=0.01)
    m = cam.render_mosaic(1 / 4)
    assert m.max() == WHITE and centre_mean(m, "B") == WHITE


def test_soft_knee_is_continuous_and_monotonic():
    sn = SensorModel()
    x = np.linspace(0, 40000, 4001, dtype=np.float32)
    y = sn.knee(x.copy())
    lin = sn.linear_limit_dn - sn.black_level
    np.testing.assert_array_equal(y[x <= lin], x[x <= lin])
    assert np.all(np.diff(y) > 0)
    assert y.max() > sn.white_level - sn.black_level            # reaches white (then clipped) at finite signal


def test_vignetting_darkens_corners_by_a_few_percent(snap):
    cam = make_camera(snap, Scene.open_gate(240, 160, vignetting=0.04))
    g = plane(cam.render_mosaic(1 / 125), "G").astype(float) - BLACK
    corner, centre = g[:8, :8].mean(), g[36:44, 56:64].mean()
    assert 0.94 < corner / centre < 0.98


def test_same_seed_same_frame_each_capture_advances_the_noise(snap):
    a, b = make_camera(snap, seed=3), make_camera(snap, seed=3)
    m1, m2 = a.render_mosaic(1 / 60), b.render_mosaic(1 / 60)
    np.testing.assert_array_equal(m1, m2)
    assert not np.array_equal(m1, a.render_mosaic(1 / 60))


# --- the thesis' checks ---------------------------------------------------------------------------------------
def test_nd_half_is_a_hundred_times_darker(snap):
    scene = Scene.with_target(grey_target(), 240, 160, nd_filter=True, vignetting=0.0)
    cam = make_camera(snap, scene)
    means = patch_means(cam.render_mosaic(1 / 60), scene)
    nd = scene.nd_patches()
    assert nd.sum() == 6 and nd.reshape(3, 4)[:, :2].all()
    ratio = means[nd].mean(axis=0) / means[~nd].mean(axis=0)
    np.testing.assert_allclose(ratio, 0.01, rtol=0.05)


@pytest.mark.parametrize("mode", ["reflective", "transmissive"])
def test_patch_means_follow_the_simulation(snap, mode):
    """Thesis Fig 7.4: simulated per-patch responses vs measured patch means, R^2 > 0.99 per channel."""
    setup = default_setup(mode)
    scene = Scene.with_target(setup.test, 360, 240)
    cam = make_camera(snap, scene, mode=mode)
    sim = cam.simulated_patch_responses()
    measured = patch_means(cam.render_mosaic(1 / 125), scene)
    for c in range(3):
        assert r_squared(sim[:, c], measured[:, c]) > 0.99


def test_responses_are_eq_5_10_under_the_mixed_light(snap):
    setup = default_setup()
    cam = make_camera(snap, Scene.with_target(setup.test, 240, 160))
    np.testing.assert_allclose(cam.led_spectra(), setup.leds, rtol=1e-12, atol=1e-15)
    light = snap.levels @ setup.leds
    np.testing.assert_allclose(cam.simulated_patch_responses(), channel_responses(light, setup.test.spectra,
                                                                                  setup.camera), rtol=1e-10)


def test_led_drift_changes_the_capture(snap):
    setup = default_setup()
    scene = Scene.with_target(setup.test, 240, 160)
    still = make_camera(snap, scene, seed=1)
    drifted_snap = replace(snap, peak_shift_nm=np.full(10, 6.0))
    drifted = make_camera(drifted_snap, scene, seed=1)
    sim_change = drifted.simulated_patch_responses() / still.simulated_patch_responses() - 1
    a, b = patch_means(still.render_mosaic(1 / 125), scene), patch_means(drifted.render_mosaic(1 / 125), scene)
    meas_change = b / a - 1
    assert np.abs(sim_change).max() > 0.05
    big = np.abs(sim_change) > 0.02
    assert np.all(np.sign(meas_change[big]) == np.sign(sim_change[big]))
    assert r_squared(sim_change.reshape(-1), meas_change.reshape(-1)) > 0.95


def test_drift_recomputes_only_when_it_changes(snap):
    cam = make_camera(snap, Scene.with_target(default_setup().test, 240, 160))
    first = cam.class_responses()
    cached = cam._cache.per_led
    assert cam.class_responses() is not first and cam._cache.per_led is cached
    snap.peak_shift_nm = np.arange(10.0)
    assert not np.allclose(cam.class_responses(), first)
    assert cam._cache.per_led is not cached


def test_bumps_switch_on_and_off(snap):
    def centre(cam, t):
        return np.mean([centre_mean(cam.render_mosaic(t), c) - BLACK for c in "RG"])

    off = make_camera(snap, seed=2)
    on = make_camera(snap, seed=2, bumps_enabled=True)
    assert on.bumps == {1 / 60: 0.03, 1 / 8: -0.02}
    assert centre(on, 1 / 60) / centre(off, 1 / 60) == pytest.approx(1.03, abs=0.005)
    assert centre(on, 1 / 125) / centre(off, 1 / 125) == pytest.approx(1.0, abs=0.005)
    on.bumps_enabled = False
    assert centre(on, 1 / 60) / centre(off, 1 / 60) == pytest.approx(1.0, abs=0.005)
    custom = make_camera(snap, bumps={1 / 125: -0.05}, bumps_enabled=True)
    assert custom.bump(1 / 125) == -0.05 and custom.bump(1 / 60) == 0.0
    assert custom.capture(1 / 125).extra["delivered_exposure_s"] == pytest.approx(0.95 / 125)


# --- scene geometry -------------------------------------------------------------------------------------------
def test_patch_boxes_match_the_label_image():
    scene = Scene.with_target(default_setup("transmissive").train, 600, 400, nd_filter=True)
    assert scene.layout == (14, 22)                       # 12x22 + 24 greys -> rows grow
    boxes = scene.patch_boxes()
    assert len(boxes) == 288
    labels = scene.labels(np.arange(400), np.arange(600))
    n = scene.n_patches
    nd = scene.nd_patches()
    for i, (r0, r1, c0, c1) in enumerate(boxes):
        assert 0 <= r0 < r1 <= 400 and 0 <= c0 < c1 <= 600
        assert np.all(labels[r0:r1, c0:c1] == i + (n + 2) * nd[i])
    assert labels[0, 0] == n and labels[-1, -1] == n       # surround
    # an IT8.7 in its real geometry (simulation.chart_geometry): the 24-step grey scale below the 12 x 22 patches,
    # wider than they; the corners are the patch area's: A01's top, the grey scale's sides and bottom
    (top, left), (_, right), (bottom, _), _ = scene.corners()
    assert boxes[264][0] > boxes[263][1] and boxes[264][2] < boxes[0][2] and boxes[287][3] > boxes[21][3]
    assert top == pytest.approx(boxes[0][0], abs=1.5) and left == pytest.approx(boxes[264][2], abs=1.5)
    assert right == pytest.approx(boxes[287][3], abs=1.5) and bottom == pytest.approx(boxes[287][1], abs=1.5)


def test_open_gate_and_lens_cap_have_no_patches():
    for scene in (Scene.open_gate(), Scene.lens_cap()):
        assert scene.patch_boxes() == [] and scene.corners() == [] and scene.n_classes == 1


@pytest.mark.parametrize("kw, message", [
    (dict(kind="target"), "needs a target"),
    (dict(kind="open_gate", width=601), "even"),
    (dict(kind="paper"), "expected one of"),
])
def test_scene_validation(kw, message):
    with pytest.raises(ValueError, match=message):
        Scene(**kw)


def test_scene_too_small_for_the_grid():
    with pytest.raises(ValueError, match="too small"):
        Scene.with_target(default_setup("transmissive").train, 40, 30)


def test_scene_swap_on_the_copy_stand(snap):
    cam = make_camera(snap)
    bright = cam.render_mosaic(1 / 125).mean()
    cam.scene = Scene.lens_cap(240, 160)
    assert cam.render_mosaic(1 / 125).mean() < BLACK + 2 < bright
    with pytest.raises(TypeError):
        cam.scene = "lens cap"


# --- the camera interface -------------------------------------------------------------------------------------
def test_shutter_list_is_the_nikon_third_stop_list(snap):
    speeds = make_camera(snap).shutter_speeds()
    assert len(speeds) == 52 and speeds == sorted(speeds)
    assert speeds[0] == 1 / 4000 and speeds[-1] == 30.0
    for label in ("1/60", "1/13", "1/2.5", "1.3", "15"):
        assert parse_shutter(label) in speeds
    assert parse_shutter("30,0000s") == 30.0


def test_apply_snaps_to_offered_values(snap):
    cam = make_camera(snap)
    got = cam.apply(CameraSettings(iso=55, shutter_s=0.0172, aperture=7.9, image_quality="NEF (Raw)",
                                   capture_target="Memory card"))
    assert (got.iso, got.shutter_s, got.aperture, got.capture_target) == (50, 1 / 60, 8.0, "Memory card")
    assert cam.settings() == got
    assert cam.apply(CameraSettings(shutter_s=0.42)).shutter_s == 0.4
    assert cam.apply(CameraSettings(shutter_s=45.0)).shutter_s == 45.0        # bulb


@pytest.mark.parametrize("settings, message", [
    (CameraSettings(image_quality="JPEG Fine"), "NEF"),
    (CameraSettings(capture_target="Cloud"), "capture target"),
    (CameraSettings(shutter_s=-1.0), "positive"),
])
def test_apply_rejects_what_the_camera_cannot_do(snap, settings, message):
    with pytest.raises(CameraError, match=message):
        make_camera(snap).apply(settings)


def test_capture_metadata_and_bulb(snap):
    clock = SkippableClock()              # the virtual lab's clock: the lit 40 s exposures pass at once, not in 80 s
    cam = make_camera(snap, Scene.lens_cap(240, 160), clock=clock)
    first, second = cam.capture(1 / 61), cam.capture(40.0)
    assert clock.skipped_s == pytest.approx(1 / 60 + 40.0)               # each held for its shutter time
    assert (first.filename, second.filename) == ("VIRT_0001.DNG", "VIRT_0002.DNG")
    assert first.exposure_s == 1 / 60 and not first.extra["bulb"]
    assert second.exposure_s == 40.0 and second.extra["bulb"]
    assert first.camera == CAMERA_NAME and first.iso == 50 and first.aperture == 8.0
    assert first.extra["scene"] == "lens_cap" and first.extra["light_levels"][0] == 1.0
    assert cam.capture().exposure_s == 40.0                   # current setting when none is given
    assert clock.skipped_s == pytest.approx(1 / 60 + 80.0)


def test_closed_camera_refuses_to_capture(snap):
    cam = VirtualCamera(lambda: snap, Scene.open_gate(240, 160))
    with pytest.raises(CameraError, match="not open"):
        cam.capture()
    with cam:
        assert cam.capture(1 / 250).data[:4] == b"II*\x00"
    assert not cam.is_open


def test_preview_is_small_rgb(snap):
    cam = make_camera(snap, Scene.with_target(default_setup().test, 1200, 800, nd_filter=True))
    img = cam.preview()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3 and img.shape[1] <= 640
    assert 0 < img.mean() < 255
    snap.light_on = False
    assert cam.preview().max() == 0


def test_config_summary_and_name(snap):
    cam = make_camera(snap)
    d = cam.config_summary()
    assert cam.name == "Virtual D610"
    assert d["camera"] == CAMERA_NAME and d["scene"]["kind"] == "open_gate" and d["iso"] == 50


def test_bad_snapshot_is_refused(snap):
    cam = make_camera(Snap(np.ones(3)))
    with pytest.raises(ValueError, match="10"):
        cam.capture()


def test_reads_the_sphere_emulator_live():
    """Integration with drivers.virtual.sphere_emulator: levels, light switch and warm-up drift reach the frame."""
    from dualrgb.drivers.led_sphere import protocol as P
    from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator

    now = [0.0]
    sphere = SphereEmulator(clock=lambda: now[0])
    cam = VirtualCamera(sphere.snapshot, Scene.with_target(default_setup().test, 240, 160), seed=5)
    cam.open()
    assert cam.render_mosaic(1 / 60).mean() < BLACK + 2                      # light off
    pwms = tuple(P.PWM_MAX if n in (1, 6, 8) else 0 for n in range(1, 11))
    sphere.handle(P.COMMANDS["set_levels"].encode(pwms=pwms).strip())
    sphere.handle(P.COMMANDS["set_light"].encode(state=1).strip())
    fresh = cam.simulated_patch_responses()
    np.testing.assert_allclose(fresh, cam.simulated_patch_responses(full_intensity(1, 6, 8)))
    for _ in range(120):                                                      # 40 min on, keeping the watchdog fed
        now[0] += 20.0
        sphere.handle(b"PING")
    assert sphere.snapshot().peak_shift_nm.max() > 2
    warm = cam.simulated_patch_responses()
    assert np.abs(warm / fresh - 1).max() > 0.02
    scene = cam.scene
    measured = patch_means(cam.render_mosaic(1 / 125), scene)
    assert min(r_squared(warm[:, c], measured[:, c]) for c in range(3)) > 0.99
