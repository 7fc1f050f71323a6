"""Frames of charts as the virtual camera shoots them, for the chart-detection tests: a chart (packaged or a file in
tests/data/charts) in its real geometry and a pose, rendered to a raw mosaic with the camera's noise and binned to
the superpixel RGB a capture's stack holds, with the scene's own corners in the same coordinates."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.chart_pose import ChartPose
from dualrgb.drivers.virtual.scene import Scene
from dualrgb.simulation.charts import Chart, packaged_chart, read_chart
from dualrgb.simulation.datasets import default_setup

CHARTS = Path(__file__).resolve().parents[1] / "data" / "charts"
POSE = ChartPose(rotation_deg=3, shift_x=0.04, shift_y=-0.03, scale=0.92)      # issue 36's pose
#: name -> (mode, role, file in tests/data/charts or None for the packaged target, layout)
KINDS = {"cc24": ("reflective", "test", None, None),
         "sg": ("reflective", "train", "sg140_layout.txt", "10x14"),
         "it87-1": ("transmissive", "train", None, None),
         "it87-2": ("reflective", "train", "it872_layout.cie", None),
         "grid": ("reflective", "train", None, None)}


def chart(kind: str) -> Chart:
    mode, role, name, layout = KINDS[kind]
    grid = default_setup(mode).grid
    return read_chart(CHARTS / name, grid, role=role, mode=mode, layout=layout) if name else \
        packaged_chart(mode, role, grid)


def shoot(c: Chart, pose: ChartPose | None, size: tuple[int, int] = (600, 400), seed: int = 0
          ) -> tuple[Scene, np.ndarray, np.ndarray]:
    """(scene, superpixel RGB above black (H/2, W/2, 3), the scene's corners in those pixels: x, y, centres at
    integer coordinates) of chart ``c`` under every LED, exposed below clipping."""
    scene = Scene.with_target(c.render_target(), *size, pose=pose)
    cam = VirtualCamera(lambda: StaticLight(np.ones(10)), scene, mode=c.kind, seed=seed)
    t = 1 / 30
    for _ in range(12):
        m = cam.render_mosaic(t).astype(float)
        if np.percentile(m, 99.9) < 12000:
            break
        t /= 2
    m -= cam.sensor.black_level
    rgb = np.dstack([m[0::2, 0::2], (m[0::2, 1::2] + m[1::2, 0::2]) / 2, m[1::2, 1::2]])
    corners = np.array([[col / 2 - 0.5, row / 2 - 0.5] for row, col in scene.corners()])
    return scene, rgb, corners
