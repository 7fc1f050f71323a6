"""Worlds (drivers/virtual/world.py): the nominal world renders bit for bit as before worlds; every other world
parameter changes the rendering as stated, checked against independent computations (colour-science's LED model,
hand formulas, the packaged CSVs); a bad world file is one line naming the file and the key."""
from __future__ import annotations

import hashlib
import json

import colour
import numpy as np
import pytest

from dualrgb import resources
from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.lab import VirtualLab
from dualrgb.drivers.virtual.scene import Scene
from dualrgb.drivers.virtual.world import World, WorldError, load_world, packaged_worlds, read_world
from dualrgb.simulation.camera_model import led_responses
from dualrgb.simulation.datasets import default_setup, load_camera
from dualrgb.simulation.grid import DEFAULT_GRID
from dualrgb.simulation.sphere import LowLevelResponse

# Recorded with the virtual lab as it was before worlds (commit 055eb80) by the procedure of _nominal_digest, one
# digest per scene: 4 renders each (2 lights, mosaic + live view) at 240x160, seed 3. numpy's Generator streams are
# stable across releases in practice; should a numpy release change them these digests change with them.
PRE_WORLDS_DIGESTS = {"train": "bca2254eb34f6f52ff009f2e8428360ee5770f84a3f557750411a614485a06ae",
                      "test": "d453425a537cbb3da41ce7849f35336228e1113b3204043f78e7f47efd22fb81",
                      "open-gate": "39f18609160d9af8214387885cf6fa74c702ae616cd6a797169a4b775eb1d79a",
                      "original:painting": "fae16eb11698609097d870749d6935a29b4fe670ec10db3f08028ab623f4026b"}
# Since issue 36 the ColorChecker Classic (the test target) is drawn in its real geometry (a dark body, 46-unit
# patches on a 52.5 pitch: simulation.chart_geometry) so that a detector finds it as on a real stand; its frames
# were recorded anew then (the other three scenes render as before worlds).
REAL_GEOMETRY_DIGESTS = {"test": "f6b263e561a37f0096fa9f094e0129b663277be18fefcdb2fa70fdf53133bd49"}
PRE_WORLDS_SCALE = 1622019.97928326
LIGHTS = [(np.r_[1, 0, 0, 0, 0, 1, 0, 1, 0, 0.0], np.zeros(10)), (np.linspace(0.05, 1, 10), np.linspace(0, 3, 10))]


def _nominal_digest(world) -> tuple[dict[str, str], float]:
    digests = {}
    with VirtualLab(frame_size=(240, 160), seed=3, world=world) as lab:
        cam = lab.camera
        for what in ("train", "test", "open-gate", "original:painting"):
            lab.place(what)
            hashes = []
            for levels, drift in LIGHTS:
                m = cam.render_mosaic(1 / 60, StaticLight(levels, drift))
                hashes += [hashlib.sha256(m.tobytes()).hexdigest(), hashlib.sha256(cam.preview().tobytes()).hexdigest()]
            digests[what] = hashlib.sha256("".join(hashes).encode()).hexdigest()
        scale = cam._scale
    return digests, scale


@pytest.mark.parametrize("world", [None, "nominal"])
def test_nominal_world_renders_bit_for_bit_as_before_worlds(world):
    digests, scale = _nominal_digest(world)
    assert scale == PRE_WORLDS_SCALE
    assert digests == {**PRE_WORLDS_DIGESTS, **REAL_GEOMETRY_DIGESTS}


def test_packaged_nominal_is_the_built_in_world():
    assert load_world("nominal").identity == World().identity == load_world(None).identity
    assert load_world("nominal").leds_nominal


def test_packaged_worlds_load_and_say_what_they_are():
    names = packaged_worlds()
    assert names[0] == "nominal"
    assert {"nikon-d700", "sony-ilce-7rm2", "mismatched-d700", "aged-leds"} <= set(names)
    identities = {load_world(n).identity for n in names}
    assert len(identities) == len(names)                 # no two worlds share an identity
    mis = load_world("mismatched-d700")
    assert sorted(set(np.abs(mis.led_peak_shift_nm))) == [3.0] and mis.flare == 0.005
    assert mis.camera_path.name == "nikon_d700_rawtoaces.csv"
    aged = load_world("aged-leds")
    assert aged.led_low_level == LowLevelResponse(0.008, 0.05, 1.6)
    assert min(aged.led_output_scale) >= 0.85 and max(aged.led_width_scale) <= 1.1


def test_rawtoaces_cameras_keep_source_licence_and_numbers():
    """The converted CSVs name source, commit and licence; the licence text ships beside them; the numbers are
    those published (first and last rows of the rawtoaces JSON, copied by hand)."""
    text = resources.path("cameras", "nikon_d700_rawtoaces.csv").read_text()
    for needle in ("AcademySoftwareFoundation/rawtoaces", "nikon_d700_380_780_5.json", "Apache-2.0",
                   "LICENSE-rawtoaces", "commit 300324c09fcc8bf19ac5066100c85d1022589b48"):
        assert needle in text
    assert "Apache License" in resources.path("cameras", "LICENSE-rawtoaces").read_text()
    from dualrgb.simulation.spectral_io import read_spectral_csv

    d700 = read_spectral_csv(resources.path("cameras", "nikon_d700_rawtoaces.csv"))
    assert d700.values[0].tolist() == [0.0087, 0.0123, 0.0156] and d700.wavelengths[[0, -1]].tolist() == [380, 780]
    sony = read_spectral_csv(resources.path("cameras", "sony_ilce_7rm2_rawtoaces.csv"))
    assert sony.values[0].tolist() == [0.01070351, 0.01611734, 0.00910183]


# ---- a world's parameters change the rendering as stated -------------------------------------------------
def _camera(world: World, scene: Scene | None = None) -> VirtualCamera:
    return VirtualCamera(lambda: StaticLight(np.zeros(10)), scene or Scene.open_gate(96, 64), world=world)


def _one(led: int, level: float = 1.0) -> StaticLight:
    lv = np.zeros(10)
    lv[led - 1] = level
    return StaticLight(lv)


def test_world_camera_renders_with_its_sensitivities():
    cam = _camera(load_world("nikon-d700"))
    expected = load_camera(resources.path("cameras", "nikon_d700_rawtoaces.csv"), DEFAULT_GRID)
    np.testing.assert_array_equal(cam.camera_sensitivities, expected)
    assert not np.allclose(cam.camera_sensitivities, default_setup().camera, atol=0.02)
    white = led_responses(cam.led_spectra(), np.ones((1, len(DEFAULT_GRID))), expected)[:, 0]
    np.testing.assert_allclose(cam.class_responses(_one(2))[0], white[1], rtol=1e-12)


def _ohno(peak: float, half_width: float, relative_peak: float) -> np.ndarray:
    """colour-science's LED model on the simulation grid, scaled to the LED's relative peak (Table 4.2)."""
    shape = colour.SpectralShape(380, 780, 1)
    sd = colour.sd_single_led(peak, shape=shape, half_spectral_width=half_width)
    v = sd.values / sd.values.max() * relative_peak
    return np.interp(DEFAULT_GRID.wavelengths, sd.wavelengths, v)


@pytest.mark.parametrize("led,shift,width", [(2, 3.0, 1.0), (5, -3.0, 1.0), (9, 0.0, 1.1), (4, 2.0, 0.9)])
def test_world_led_shape_matches_colour_science_led_model(led, shift, width):
    """A shift of s nm and a width scale w are colour's sd_single_led at peak + s with half width 25 w."""
    shifts, widths = np.zeros(10), np.ones(10)
    shifts[led - 1], widths[led - 1] = shift, width
    cam = _camera(World(led_peak_shift_nm=tuple(shifts), led_width_scale=tuple(widths)))
    peaks = (416, 448, 467, 491, 520, 545, 572, 597, 626, 680)
    rel = (0.88, 1.00, 0.663, 0.183, 0.198, 0.014, 0.003, 0.165, 0.300, 0.565)
    expected = _ohno(peaks[led - 1] + shift, 25.0 * width, rel[led - 1])
    np.testing.assert_allclose(cam.led_spectra()[led - 1], expected, atol=2e-3 * rel[led - 1])
    got = cam.class_responses(_one(led))[0]
    want = led_responses(expected[None, :], np.ones((1, len(DEFAULT_GRID))), cam.camera_sensitivities)[0, 0]
    np.testing.assert_allclose(got, want, rtol=5e-3)


def test_world_output_scale_and_low_level_response():
    out = np.ones(10)
    out[[0, 2, 5, 7]] = 0.8
    low = LowLevelResponse(0.008, 0.05, 1.6)
    cam = _camera(World(led_output_scale=tuple(out), led_low_level=low))
    nominal = _camera(World())
    full = nominal.class_responses(_one(3))[0]
    np.testing.assert_allclose(cam.class_responses(_one(3))[0], 0.8 * full, rtol=1e-12)
    assert cam.exposure_gain(1 / 60) == nominal.exposure_gain(1 / 60)   # the body's gain: not the LEDs' output
    for level, by_hand in ((0.005, 0.0), (0.02, 0.05 * (0.012 / 0.042) ** 1.6), (0.3, 0.3)):
        np.testing.assert_allclose(cam.class_responses(_one(3, level))[0], 0.8 * by_hand * full, rtol=1e-9,
                                   atol=1e-15)


def test_world_flare_adds_a_fraction_of_the_frames_mean_to_every_pixel():
    """The gap between patches gets flare x the frame's mean signal more (measured on the nominal frame)."""
    setup = default_setup()
    scene = Scene.with_target(setup.test, 240, 160, vignetting=0.0)
    light = StaticLight(np.r_[1, 0, 0, 0, 0, 1, 0, 1, 0, 0.0])
    frames = {}
    for flare in (0.0, 0.02):
        cam = _camera(World(flare=flare), scene)
        frames[flare] = cam.render_mosaic(1 / 60, light).astype(float) - 600
    plain = frames[0.0]
    gap = Scene.with_target(setup.test, 240, 160).labels(np.arange(160), np.arange(240)) == len(setup.test) + 1
    rows, cols = np.nonzero(gap)
    green = (rows + cols) % 2 == 1                                      # RGGB: G where row + col is odd
    frame_mean_green = plain[(np.arange(160)[:, None] + np.arange(240)[None, :]) % 2 == 1].mean()
    increase = frames[0.02][rows[green], cols[green]].mean() - plain[rows[green], cols[green]].mean()
    assert increase == pytest.approx(0.02 * frame_mean_green, rel=0.05)


def test_world_reference_error_is_a_seeded_gain_per_patch():
    world = World(reference_error_sd=0.01, seed=5)
    ref = default_setup().train
    true = world.true_target(ref)
    with np.errstate(invalid="ignore", divide="ignore"):
        gains = true.spectra / ref.spectra
    per_patch = np.nanmean(gains, axis=1)
    np.testing.assert_allclose(np.nanstd(gains, axis=1), 0.0, atol=1e-12)   # one gain per patch
    assert np.std(per_patch) == pytest.approx(0.01, rel=0.25)
    np.testing.assert_array_equal(World(reference_error_sd=0.01, seed=5).true_target(ref).spectra, true.spectra)
    assert not np.allclose(World(reference_error_sd=0.01, seed=6).true_target(ref).spectra, true.spectra)
    assert World().true_target(ref) is ref
    with VirtualLab(frame_size=(96, 64), world=world) as lab:
        np.testing.assert_array_equal(lab.place("train").shown_target.spectra, true.spectra)
        assert lab.target("train") is ref                      # the calibration keeps the packaged reference


# ---- bad world files: one line naming file and key --------------------------------------------------------
BAD = [
    ({"name": "x", "flair": 0.01}, "unknown key 'flair'"),
    ({"name": "x", "flare": 0.5}, "key 'flare': expected a number from 0 to 0.2"),
    ({"name": "x", "led_peak_shift_nm": [1, 2, 3]}, "key 'led_peak_shift_nm': expected a list of 10 numbers"),
    ({"name": "x", "led_width_scale": [1, 1, 1, 1, 1, 1, 1, 1, 1, "wide"]}, "key 'led_width_scale[9]'"),
    ({"name": "x", "led_low_level": {"dead_band": 0.05, "knee": 0.01}}, "key 'led_low_level.knee'"),
    ({"name": "x", "led_low_level": {"deadband": 0.05}}, "unknown key 'led_low_level.deadband'"),
    ({"name": "x", "seed": -1}, "key 'seed': expected a whole number"),
    ({"name": "x", "camera_csv": "no_such_camera.csv"}, "key 'camera_csv': expected a spectral CSV"),
    ({"name": "x", "format": "dualrgb-world/9"}, "key 'format'"),
    ({"flare": 0.01}, "key 'name'"),
    ([1, 2], "expected a JSON object"),
]


@pytest.mark.fault("input")
@pytest.mark.parametrize("doc,message", BAD)
def test_bad_world_file_is_one_line_naming_file_and_key(tmp_path, doc, message):
    path = tmp_path / "w.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(WorldError) as err:
        read_world(path)
    text = str(err.value)
    assert text.startswith(str(path)) and message in text and "\n" not in text


def test_world_file_errors_for_json_camera_and_names(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{"name": "x",\n "flare": }')
    with pytest.raises(WorldError, match=r"broken.json:2: not valid JSON"):
        load_world(path)
    bad_camera = tmp_path / "cam.csv"
    bad_camera.write_text("wavelength_nm,red,green\n400,1,1\n500,1,1\n")
    path.write_text(json.dumps({"name": "x", "camera_csv": "cam.csv"}))
    with pytest.raises(WorldError, match=r"broken.json: key 'camera_csv': .*3 data columns"):
        load_world(path)
    with pytest.raises(WorldError, match="not a packaged world .*nominal"):
        load_world("no-such-world")


def test_world_camera_csv_resolves_next_to_the_world_file(tmp_path):
    (tmp_path / "sub").mkdir()
    cam = resources.path("cameras", "sony_ilce_7rm2_rawtoaces.csv").read_text()
    (tmp_path / "sub" / "mine.csv").write_text(cam)
    path = tmp_path / "sub" / "mine.json"
    path.write_text(json.dumps({"name": "mine", "camera_csv": "mine.csv", "led_peak_shift_nm": [1] * 10}))
    world = load_world(str(path))
    assert world.camera_path == tmp_path / "sub" / "mine.csv" and world.led_peak_shift_nm == (1.0,) * 10
    assert world.led_width_scale == (1.0,) * 10                          # left out: nominal
