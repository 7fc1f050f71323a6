"""End to end: DNG files recorded in a CaptureSession -> darks, HDR whites, flat-fielded HDR stacks ->
patch values -> both matrices -> CSVs, report; checked against the simulation of the same light set. The session
is written with the old strings (meta 'target', light names in the light dict): the vocabulary's reader opens it."""
from __future__ import annotations

import json

import numpy as np
import pytest
from synthetic_frames import dark_frames, expose, mosaic_scene, vignette, write_dng

from dualrgb.app.processing.mosaic import mosaic_from_rgb
from dualrgb.app.processing.patches import PatchGrid
from dualrgb.app.workflow.calibration.session_processing import process_session
from dualrgb.app.workflow.calibration.targets import TargetSpec
from dualrgb.common.progress import Cancelled, CancelToken
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.vocabulary import Subject
from dualrgb.drivers.camera.base import RawCapture
from dualrgb.simulation.camera_model import channel_responses
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.objective import Evaluator

CELL = 5            # superpixel pixels per patch
LIGHTS = [LightSource((1, 6, 8), name="light 1"), LightSource((3, 5, 9), name="light 2")]
TIMES = (0.01, 0.1)


def chart_values(setup, target, light):
    """Per patch R, G, B of the camera under ``light``, relative to a perfect white under the same light."""
    spd = light.spectrum(setup.leds)
    v = channel_responses(spd, target.spectra, setup.camera)
    white = channel_responses(spd, np.ones((1, len(spd))), setup.camera)
    return v / white, white[0]


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory):
    setup = default_setup("reflective")
    root = tmp_path_factory.mktemp("pipe")
    s = CaptureSession.create(root / "session", {"object": "synthetic"})
    files = root / "dng"
    files.mkdir()
    n = [0]

    def shoot(mosaic, t, role, light=None, **meta):
        n[0] += 1
        p = write_dng(files / f"VIRT_{n[0]:04d}.dng", mosaic)
        s.record(RawCapture(p.read_bytes(), p.name, t), role, light=light, **meta)

    layouts = {"train": (10, 19), "test": (4, 6)}
    h, w = 2 * (10 * CELL + 2 * CELL), 2 * (19 * CELL + 2 * CELL)          # one sensor size for every frame
    for t in TIMES:
        for f in dark_frames(h, w, t, n=4, noise=1.5, spikes=0.01, seed=int(1000 * t))[0]:
            shoot(f, t, "dark")

    def full(m, fill):
        out = np.full((h, w), fill)
        out[: m.shape[0], : m.shape[1]] = m
        return out

    rng = np.random.default_rng(0)
    for light in LIGHTS:
        _, white_rgb = chart_values(setup, setup.test, light)
        colour = mosaic_from_rgb(np.broadcast_to(white_rgb / white_rgb.max(), (h // 2, w // 2, 3)))
        radiance = 250000.0 * vignette(h, w, 0.5) * colour         # the long exposure clips the white
        for t in TIMES:                                             # one HDR white per light
            dark = dark_frames(h, w, t, n=1, noise=0, seed=int(1000 * t))[1]
            shoot(expose(radiance, t, dark, noise=1.5, seed=int(rng.integers(1 << 30))), t, "flat", light=light)
        for key, target in (("train", setup.train), ("test", setup.test)):
            rows, cols = layouts[key]
            vals, _ = chart_values(setup, target, light)
            refl = np.zeros((rows * cols, 3))
            refl[: len(vals)] = vals
            scene = full(mosaic_scene(refl, rows, cols, cell=CELL, border=CELL), 0.05)
            for t in TIMES:
                dark = dark_frames(h, w, t, n=1, noise=0, seed=int(1000 * t))[1]
                shoot(expose(radiance * scene, t, dark, noise=1.5, seed=int(rng.integers(1 << 30))), t, "target",
                      light=light, target=key)
    return s.path, setup, layouts


def spec(setup, key, layouts, evaluator):
    rows, cols = layouts[key]
    target = setup.train if key == "train" else setup.test
    ps = evaluator.train if key == "train" else evaluator.test
    n = len(target)
    corners = np.array([[CELL, CELL], [CELL + cols * CELL, CELL], [CELL + cols * CELL, CELL + rows * CELL],
                        [CELL, CELL + rows * CELL]], float) - 0.5
    grid = PatchGrid(corners, rows, cols, 0.6)
    if rows * cols != n:                      # 190 patches on a 10 x 19 grid: exactly 190 cells
        raise AssertionError
    W = np.stack([light.weights() for light in LIGHTS])
    return TargetSpec(Subject.target(key), ps.xyz, target.patch_names, grid, target.layout,
                      ps.camera_values(W) if key == "train" else None, key)


def test_session_to_report_matches_simulation(session_dir, tmp_path):
    path, setup, layouts = session_dir
    ev = Evaluator(setup)
    s = CaptureSession.open(path)
    assert s.verify().valid
    seen = []
    res = process_session(s, tmp_path / "out", spec(setup, "train", layouts, ev), spec(setup, "test", layouts, ev),
                          progress=lambda f, m: seen.append(f))
    assert res.lights == ["light 1", "light 2"]
    W = np.stack([light.weights() for light in LIGHTS])
    sim_train, sim_test = ev.stats(W)
    ls = res.characterisation.results["least-squares"]
    # the captured-and-processed chain reproduces the simulated accuracy of this light set
    assert ls.train.mean == pytest.approx(sim_train.mean, abs=0.05)
    assert ls.test.mean == pytest.approx(sim_test.mean, abs=0.05)
    assert res.characterisation.results["de2000"].train.mean <= ls.train.mean
    rep = json.loads((tmp_path / "out" / "report.json").read_text())
    assert rep["best_method"] in ("least-squares", "de2000", "root-polynomial-2", "root-polynomial-3")
    # per pixel: the delivered model applied to each pixel of the captured charts, noisier than the patch means
    for target in ("train", "test"):
        assert rep["per_pixel_de00"][target]["mean"] > rep[target]["mean"]
        assert rep["per_pixel_de00"][target]["p90"] > rep["per_pixel_de00"][target]["mean"]
    assert rep["dn_validation"]["min_r2"] > 0.999                # captured DN are linear in simulated ones
    assert rep["standards"]["results"]["FADGI 2023"]["level"] is not None
    assert (tmp_path / "out" / "patches_train.csv").exists() and (tmp_path / "out" / "matrices.csv").exists()
    assert seen and seen[-1] == 1.0 and all(0 <= f <= 1 for f in seen)


def test_cancel_stops_processing(session_dir, tmp_path):
    path, setup, layouts = session_dir
    ev = Evaluator(setup)
    tok = CancelToken()
    calls = []

    def progress(f, m):
        calls.append(m)
        if len(calls) == 3:
            tok.cancel()

    with pytest.raises(Cancelled):
        process_session(CaptureSession.open(path), tmp_path / "out", spec(setup, "train", layouts, ev),
                        progress=progress, cancel=tok)
    assert not (tmp_path / "out" / "report.json").exists()


def test_partly_filled_last_grid_row_is_accepted_and_a_wrong_grid_is_not():
    from dualrgb.app.processing.patches import PatchGrid
    from dualrgb.app.processing.pipeline import ChannelStack
    from dualrgb.app.workflow.calibration.session_processing import sample_target

    class FakeProcessor:
        def stack(self, scenes, progress=None, cancel=None):
            data = np.zeros((40, 50, 3), np.float32)
            data[..., 0] = np.arange(50)[None, :]                      # column index as the value
            return ChannelStack(data, ["R1", "G1", "B1"], ["LS1"])

    frames = {"LS1": []}
    grid = PatchGrid(np.array([[0, 0], [49, 0], [49, 39], [0, 39]], float), 4, 5)
    spec = TargetSpec(Subject.target("test"), np.ones((18, 3)), [f"p{i}" for i in range(18)], grid=grid)
    values, _std, _ = sample_target(FakeProcessor(), spec, frames, None, None)
    assert values.shape == (18, 3)                                      # 18 patches on 4 x 5 cells
    assert values[0, 0] < values[4, 0]                                  # row-major: patch 4 is the last column
    bad = TargetSpec(Subject.target("test"), np.ones((12, 3)), [f"p{i}" for i in range(12)], grid=grid)
    with pytest.raises(ValueError, match="20 cells"):
        sample_target(FakeProcessor(), bad, frames, None, None)
