"""What the virtual lab knows about the targets it holds, for the front ends that run it (never for the
production workflow, which finds the patches in the image or takes them from the person at the stand):

* :func:`scene_grid`: the patch grid of a lab scene, in the processed stack's coordinates;
* :func:`lab_grids`: the training and test targets' grids as the lab lays them in a frame of a given size, what
  a person would place by hand (``calibrate --train-grid``) - the `--virtual-lab` shorthand hands them to the
  calibration until the patches are found in the image;
* :func:`virtual_target_spec`: a target's spec with the lab's own grid and ND filter (the demo's study);
* :data:`LAB_TARGET_WIDTH_MM`: the width of the lab's test target, what the user would type as
  ``--target-width-mm``.
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from dualrgb.app.processing.patches import PatchGrid
from dualrgb.app.workflow.targets import NdFilter, TargetSpec, target_spec
from dualrgb.app.workflow.vocabulary import Subject

if TYPE_CHECKING:
    from dualrgb.drivers.virtual.lab import VirtualLab
    from dualrgb.simulation.charts import Chart

log = logging.getLogger(__name__)

LAB_TARGET_WIDTH_MM = 280.0     # the lab's test target, outer corners of its corner patches


def scene_grid(scene: Any, fraction: float = 0.5) -> PatchGrid:
    """The patch grid of a virtual-lab scene in stack (superpixel) coordinates (a chart drawn in its real geometry
    or a pose: its patch area's corners and each cell where its patch is)."""
    corners_rc = np.asarray(scene.corners(), dtype=float)
    rows, cols = scene.layout
    boxes = scene.geometry.unit_boxes() if scene.placement is not None else None
    return PatchGrid(corners_rc[:, ::-1], rows, cols, fraction=fraction,                 # (row, col) -> (x, y)
                     cell_boxes=boxes).scaled(0.5)


def lab_scene(mode: str, role: str, frame_size: tuple[int, int], chart: Chart | None = None, nd: bool = False) -> Any:
    """The scene the lab lays for target ``role`` ('train' / 'test') in a ``frame_size`` (W, H) frame: the chart's
    every cell (the stand's own chart, else the packaged target)."""
    from dualrgb.drivers.virtual.scene import Scene
    from dualrgb.simulation.datasets import default_setup

    width, height = (int(v) // 2 * 2 for v in frame_size)
    target = chart.render_target() if chart is not None else getattr(default_setup(mode), role)
    return Scene.with_target(target, width=width, height=height, nd_filter=nd)


def lab_grids(mode: str, frame_size: tuple[int, int], charts: dict[str, Chart] | None = None) -> dict[str, PatchGrid]:
    """The training and test targets' patch grids as the lab lays them (:func:`lab_scene`)."""
    return {role: scene_grid(lab_scene(mode, role, frame_size, (charts or {}).get(role))) for role in ("train", "test")}


def too_small_to_find(mode: str, frame_size: tuple[int, int], charts: dict[str, Chart] | None = None
                      ) -> dict[str, tuple[PatchGrid, float]]:
    """The targets whose patches the lab lays smaller than a finder can sample in a ``frame_size`` frame
    (app.processing.chart_detect.MIN_PATCH_PX): role -> (the grid as the lab lays it, the smallest patch's size in
    stack pixels). On a physical stand such a chart is placed by hand; the `--virtual-lab` shorthand and the window
    hand the lab's grid over the same way, so tests may use tiny frames (larger frames: the patches are found)."""
    from dualrgb.app.processing.chart_detect import MIN_PATCH_PX

    out = {}
    for role, grid in lab_grids(mode, frame_size, charts).items():
        geometry = target_spec(mode, Subject.target(role), None, chart=(charts or {}).get(role)).geometry
        if geometry is None:
            continue
        x0, y0, x1, y1 = geometry.patch_area
        side = min(np.linalg.norm(grid.corners[1] - grid.corners[0]) / (x1 - x0),
                   np.linalg.norm(grid.corners[3] - grid.corners[0]) / (y1 - y0))
        smallest = float(side * min(min(b.size) for b in geometry.blocks))
        if smallest < MIN_PATCH_PX:
            out[role] = (grid, smallest)
    return out


def virtual_target_spec(lab: VirtualLab, subject: Subject, *, grid: PatchGrid | None = None, label: str = "",
                        method: str | None = None, chart: Chart | None = None) -> TargetSpec:
    """A target captured in the in-process lab ``lab`` (the demo's study): the lab's scene gives the grid and its ND
    filter's transmittance; the rest is the production path (app.workflow.targets.target_spec)."""
    scene = lab.scene_for(subject.name, nd=subject.nd)
    return target_spec(lab.mode, subject, grid or scene_grid(scene), label=label, method=method, chart=chart,
                       nd=NdFilter(scene.nd_transmittance))


def chart_reader(mode: str) -> Callable[[str, str, str, str], Any]:
    """What the lab's sample changer's CHART request reads a chart with (app.workflow.charts, as calibrate)."""
    def read(role: str, layout: str, leave_out: str, file: str):
        from dualrgb.app.workflow.charts import ChartChoice, load_charts

        return load_charts({role: ChartChoice(file, layout, leave_out)}, mode)[role].render_target()
    return read
