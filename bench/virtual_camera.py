"""Benchmark of the virtual lab camera at full D610 size: render, DNG write, cached re-render, preview.

``bench_render()`` returns a dict of timings (s) and peak memory (MiB), with ``bench_original()`` (the
virtual painting at 24 MP and 600x400, and its ground truth) under "painting".
Run alone: ``python -m bench.virtual_camera``.
"""
from __future__ import annotations

import json
import logging
import time
import tracemalloc
from functools import partial

import numpy as np

from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.dng import DngInfo, dng_bytes
from dualrgb.drivers.virtual.originals import ground_truth_xyz
from dualrgb.drivers.virtual.scene import Scene, original_scene
from dualrgb.simulation.datasets import default_setup

log = logging.getLogger(__name__)


def bench_render(width: int = 6080, height: int = 4028, mode: str = "transmissive") -> dict[str, float | int | str]:
    """Render the training target (ND half on) at ``width`` x ``height``: first (cold caches) and second
    capture, a capture under a drifted light (per-LED responses recomputed), the DNG write and a preview.

    Peak memory is numpy's + Python's allocations during the run (tracemalloc), which is what the render
    adds on top of the interpreter.
    """
    levels = np.zeros(10)
    levels[[0, 5, 7]] = 1.0
    snap = StaticLight(levels)
    target = default_setup(mode).train
    cam = VirtualCamera(lambda: snap, Scene.with_target(target, width, height, nd_filter=True), mode=mode, seed=1)
    cam.open()
    out: dict[str, float | int | str] = {"width": width, "height": height, "megapixels": round(width * height / 1e6, 2),
                                         "patches": len(target)}
    tracemalloc.start()
    t0 = time.perf_counter()
    mosaic = cam.render_mosaic(1 / 60)
    out["render_cold_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    mosaic = cam.render_mosaic(1 / 60)
    out["render_warm_s"] = time.perf_counter() - t0
    snap.peak_shift_nm = np.linspace(0.0, 7.0, 10)
    t0 = time.perf_counter()
    cam.render_mosaic(1 / 60)
    out["render_new_drift_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    data = dng_bytes(mosaic, DngInfo(exposure_s=1 / 60, iso=50, aperture=8.0))
    out["dng_write_s"] = time.perf_counter() - t0
    out["dng_mib"] = round(len(data) / 2**20, 1)
    del data
    t0 = time.perf_counter()
    cam.capture(1 / 60)
    out["capture_total_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    cam.preview()
    out["preview_s"] = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    out["peak_traced_mib"] = round(peak / 2**20, 1)
    cam.close()
    for k, v in out.items():
        if k.endswith("_s"):
            out[k] = round(float(v), 3)
    out["painting"] = bench_original("painting")
    return out


def bench_original(name: str = "painting", sizes: tuple[tuple[int, int], ...] = ((6080, 4028), (600, 400))
                   ) -> dict[str, dict[str, float]]:
    """An original (drivers/virtual/originals.py) per frame size: first render (class map painted), second
    render, a whole capture (render + DNG) and the per-pixel ground truth (float32 XYZ at sensor size)."""
    levels = np.zeros(10)
    levels[[0, 5, 7]] = 1.0
    snap = StaticLight(levels)
    out: dict[str, dict[str, float]] = {}
    for width, height in sizes:
        cam = VirtualCamera(lambda: snap, original_scene(name, width, height), seed=1)
        cam.open()
        r: dict[str, float] = {"megapixels": round(width * height / 1e6, 2)}
        for key, fn in (("render_cold_s", partial(cam.render_mosaic, 1 / 60)),
                        ("render_warm_s", partial(cam.render_mosaic, 1 / 60)),
                        ("capture_total_s", partial(cam.capture, 1 / 60)),
                        ("ground_truth_s", partial(ground_truth_xyz, name, height, width))):
            t0 = time.perf_counter()
            fn()
            r[key] = round(time.perf_counter() - t0, 4)
        cam.close()
        out[f"{width}x{height}"] = r
    return out


if __name__ == "__main__":
    print(json.dumps(bench_render(), indent=2))
