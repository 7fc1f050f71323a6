"""Capture a light set's training and test targets in the virtual lab and measure the captured accuracy.

The chain is the real one, with small frames: drivers.virtual.camera.VirtualCamera renders raw mosaics of the
lens cap (master darks), the open gate (white) and each target under each light at the exposure that light
needs (simulation.studies.noise: open gate's brightest channel at 80 % of the linear limit, snapped to the
camera's shutter speeds); app.processing.pipeline.CaptureProcessor subtracts the darks, flat-fields (eq 7.1)
and stacks the lights' superpixel RGBs; app.processing.patches.PatchGrid takes trimmed patch means at the
scene's patch positions; a least-squares characterisation is fitted on the captured training target and
evaluated (float64 CIEDE2000) on the captured training and test targets, as patch means and per pixel (the matrix
applied to each superpixel of each patch, simulation.pixel_error).

Used by ``dualrgb study stability`` to check which objective predicts the captured error (it lives in app/
because it drives drivers/ and app.processing, which simulation/ must not import).
"""
from __future__ import annotations

import logging

import numpy as np

from dualrgb.app.processing.patches import PatchGrid
from dualrgb.app.processing.pipeline import CaptureProcessor, ExposureRef
from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.scene import Scene
from dualrgb.simulation.colorimetry import delta_e_2000, tristimulus, white_point, xyz_to_lab
from dualrgb.simulation.datasets import SimulationSetup
from dualrgb.simulation.matrix_fit import fit_matrix
from dualrgb.simulation.pixel_error import pixel_errors

log = logging.getLogger(__name__)


def capture_patch_values(setup: SimulationSetup, W: np.ndarray, exposures_s: np.ndarray, *, width: int = 600,
                         height: int = 400, dark_frames: int = 4, seed: int = 0,
                         pixels: dict[str, list[np.ndarray]] | None = None) -> dict[str, np.ndarray]:
    """Flat-fielded patch means (n, 3L) of the training and test targets under light set W (L, K); ``pixels``,
    when given, gets each target's per-patch (m, 3L) superpixels."""
    state = StaticLight(np.zeros(W.shape[1]))
    cam = VirtualCamera(lambda: state, Scene.lens_cap(width, height), mode=setup.mode, grid=setup.grid, seed=seed)
    cam.open()
    lights = [f"light {i + 1}" for i in range(W.shape[0])]
    frames: dict[str, dict[str, list[ExposureRef]]] = {"train": {}, "test": {}}
    darks: list[ExposureRef] = []
    whites: dict[str, list[ExposureRef]] = {}
    scenes = {k: Scene.with_target(t, width, height) for k, t in (("train", setup.train), ("test", setup.test))}
    try:
        for li, name in enumerate(lights):
            state.levels = np.asarray(W[li], dtype=float)
            t = float(exposures_s[li])
            cam.scene = Scene.lens_cap(width, height)
            darks += [ExposureRef(cam.render_mosaic(t), t, f"dark {name}") for _ in range(dark_frames)]
            cam.scene = Scene.open_gate(width, height)
            whites[name] = [ExposureRef(cam.render_mosaic(t), t, f"white {name}")]
            for key, scene in scenes.items():
                cam.scene = scene
                frames[key][name] = [ExposureRef(cam.render_mosaic(t), t, f"{key} {name}")]
    finally:
        cam.close()
    sensor = cam.sensor
    hdr_log = logging.getLogger("dualrgb.app.processing.hdr")
    level = hdr_log.level
    hdr_log.setLevel(logging.ERROR)       # hot pixels in long exposures trigger its "exceed the linear limit"
    try:
        return _process(setup, lights, darks, whites, frames, scenes, sensor, pixels)
    finally:
        hdr_log.setLevel(level)


GRID_FRACTION = 0.6          # the central part of each patch cell sampled here


def capture_model(setup: SimulationSetup, *, width: int = 600, height: int = 400, dark_frames: int = 4):
    """The expected-captured objective's model of this capture: its patch sizes (superpixels sampled per
    patch, median), its dark frames and its single white frame (simulation.capture_model)."""
    from dataclasses import replace

    from dualrgb.simulation.capture_model import CaptureModel

    pixels = []
    for target in (setup.train, setup.test):
        scene = Scene.with_target(target, width, height)
        counts = _patch_grid(scene).sample(np.zeros((height // 2, width // 2, 1))).count[:scene.n_patches]
        pixels.append(max(1, int(np.median(counts))))
    cap = CaptureModel.virtual_lab(setup.mode)
    return replace(cap, camera=replace(cap.camera, pixels_per_patch=pixels[0], dark_frames=dark_frames, flat_frames=1),
                   test_pixels_per_patch=pixels[1])


def _patch_grid(scene: Scene) -> PatchGrid:
    """The scene's patch grid on the superpixel stack (scene corners are (row, col) on the sensor; a chart drawn
    in its real geometry has each cell where its patch is: an IT8's grey scale below its patches)."""
    rows, cols = scene.layout
    corners = np.array([[c / 2.0 - 0.5, r / 2.0 - 0.5] for r, c in scene.corners()])
    boxes = scene.geometry.unit_boxes() if scene.placement is not None and scene.geometry is not None else None
    return PatchGrid(corners, rows, cols, GRID_FRACTION, cell_boxes=boxes)


def _process(setup, lights, darks, whites, frames, scenes, sensor, pixels=None) -> dict[str, np.ndarray]:
    proc = CaptureProcessor(dark_frames=darks, white_level=sensor.white_level, black_level=sensor.black_level,
                            cfa="RGGB", mode=setup.mode)
    for name in lights:
        proc.set_white(name, whites[name])
    out = {}
    for key, scene in scenes.items():
        stack = proc.stack(frames[key])
        grid = _patch_grid(scene)
        out[key] = grid.sample(stack.data).mean[:scene.n_patches]
        if pixels is not None:
            from dualrgb.app.workflow.calibration.session_processing import patch_pixels

            pixels[key] = patch_pixels(grid, stack.data, range(scene.n_patches))
    return out


def captured_errors(setup: SimulationSetup, W: np.ndarray, exposures_s: np.ndarray, *, repeats: int = 2,
                    width: int = 600, height: int = 400, dark_frames: int = 4, seed: int = 0) -> dict:
    """Mean dE00 of ``repeats`` virtual-lab captures (fit on the captured training target), as patch means and
    per pixel (``per_pixel_*``: the matrix on each superpixel; mean, and the test chart's p90)."""
    white = white_point(setup.illuminant, setup.cmfs)
    xyz = {k: tristimulus(t.spectra, setup.illuminant, setup.cmfs) for k, t in (("train", setup.train),
                                                                               ("test", setup.test))}
    acc: dict[str, list[float]] = {k: [] for k in ("train", "test", "per_pixel_train", "per_pixel_test",
                                                     "per_pixel_test_p90")}
    for r in range(repeats):
        pixels: dict[str, list[np.ndarray]] = {}
        v = capture_patch_values(setup, W, exposures_s, width=width, height=height, dark_frames=dark_frames,
                                 seed=seed * 1000 + r, pixels=pixels)
        A = fit_matrix(v["train"], xyz["train"])
        for key in ("train", "test"):
            acc[key].append(float(delta_e_2000(xyz_to_lab(xyz[key], white), xyz_to_lab(A.apply(v[key]), white)).mean()))
            px = pixel_errors(A.apply, pixels[key], xyz[key], white)
            acc[f"per_pixel_{key}"].append(px.mean)
            if key == "test":
                acc["per_pixel_test_p90"].append(px.p90)
    return {**{k: float(np.mean(v)) for k, v in acc.items()}, "train_sd": float(np.std(acc["train"])),
            "test_sd": float(np.std(acc["test"])), "repeats": repeats, "frame": [width, height],
            "dark_frames": dark_frames}
