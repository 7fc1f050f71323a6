"""Charts on the virtual stand as they are and as they lie (issue 36): the ColorChecker Classic, the Digital SG and
the IT8.7 drawn in their real geometry (ArgyllCMS's templates' patch sizes, gaps and borders), any chart turned,
moved and scaled by the world's ``chart_pose``, and the scene's own corners, patch boxes and ND patches following
the pose."""
from __future__ import annotations

import json

import numpy as np
import pytest

from dualrgb.drivers.virtual.chart_pose import ChartPose
from dualrgb.drivers.virtual.lab import VirtualLab
from dualrgb.drivers.virtual.scene import Scene
from dualrgb.drivers.virtual.world import WorldError, load_world, parse_world
from dualrgb.simulation.chart_geometry import classic24, digital_sg, geometry_for, it8
from dualrgb.simulation.datasets import Target, default_setup

POSE = ChartPose(rotation_deg=3, shift_x=0.04, shift_y=-0.03, scale=0.92)


def _target(n: int, layout: tuple[int, int], names: list[str] | None = None) -> Target:
    n_wl = len(default_setup().grid)
    spectra = np.linspace(0.05, 0.9, n)[:, None] * np.ones((1, n_wl))
    return Target("t", spectra, names or [f"p{i}" for i in range(n)], layout)


def test_known_charts_are_recognised_by_their_layout():
    assert geometry_for((4, 6), 24) == classic24()
    assert geometry_for((10, 14), 140) == digital_sg()
    assert geometry_for((14, 22), 288).name == "IT8.7"
    it8_names = [f"{chr(65 + r)}{c + 1:02d}" for r in range(12) for c in range(22)] + [f"GS{k:02d}" for k in range(24)]
    assert geometry_for((14, 21), 288, it8_names).name == "IT8.7"           # a CGATS file laid out 1.5:1
    assert geometry_for((12, 17), 190).name == "grid" and geometry_for((6, 4), 24).name == "grid"


def test_the_geometries_are_argylls_templates():
    """Against the numbers of /usr/share/color/argyll/ref/*.cht (restated in simulation.chart_geometry)."""
    b = classic24().boxes
    assert b[0].tolist() == [12.0, 11.5, 58.0, 57.5] and b[-1][2:].tolist() == [320.5, 215.0]   # its box line
    b = digital_sg().boxes
    assert b[0].tolist() == pytest.approx([27.5, 20.0, 40.175, 32.75]) and b[-1][2] == pytest.approx(237.45)
    g = it8()
    assert g.boxes[264].tolist() == [0.0, 358.75, 25.625, 410.0] and g.patch_area == (0.0, 26.625, 615.0, 410.0)


@pytest.mark.parametrize("n, layout", [(24, (4, 6)), (140, (10, 14)), (288, (14, 22)), (190, (12, 17))])
@pytest.mark.parametrize("pose", [None, POSE, ChartPose(rotation_deg=-90, scale=0.6)])
def test_every_patch_is_drawn_where_the_pose_puts_it(n, layout, pose):
    scene = Scene.with_target(_target(n, layout), 600, 400, pose=pose)
    geometry = scene.geometry
    if scene.placement is None:                        # the generic grid, square: drawn as before worlds
        assert geometry.name == "grid" and pose is None
        return
    centres = scene.placement.to_frame(geometry.centres())               # frame x, y of every patch centre
    labels = scene.labels(np.arange(400), np.arange(600))
    rows, cols = np.floor(centres[:, 1]).astype(int), np.floor(centres[:, 0]).astype(int)
    assert np.array_equal(labels[rows, cols], np.arange(n))
    for i, (r0, r1, c0, c1) in enumerate(scene.patch_boxes()):           # metering boxes lie on their patch
        assert r1 > r0 and c1 > c0 and np.all(labels[r0:r1, c0:c1] == i)
    x0, y0, x1, y1 = geometry.patch_area
    expected = scene.placement.to_frame(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
    assert np.allclose(np.asarray(scene.corners())[:, ::-1], expected)


def test_the_pose_turns_moves_and_scales_the_chart():
    flat = Scene.with_target(_target(24, (4, 6)), 600, 400)
    posed = Scene.with_target(_target(24, (4, 6)), 600, 400, pose=POSE)
    a, b = np.asarray(flat.corners())[:, ::-1], np.asarray(posed.corners())[:, ::-1]     # x, y
    top_a, top_b = a[1] - a[0], b[1] - b[0]
    turned = np.degrees(np.arctan2(-top_b[1], top_b[0]))                 # counter-clockwise as the frame is seen
    assert turned == pytest.approx(3.0) and np.linalg.norm(top_b) == pytest.approx(0.92 * np.linalg.norm(top_a))
    body = np.array([[165.0, 114.0]])                                   # the chart body's centre (330 x 228)
    moved = posed.placement.to_frame(body) - flat.placement.to_frame(body)
    assert moved[0] == pytest.approx([0.04 * 600, -0.03 * 400])


def test_the_nd_filter_covers_the_left_half_of_a_posed_chart():
    scene = Scene.with_target(_target(24, (4, 6)), 600, 400, pose=POSE, nd_filter=True)
    nd = scene.nd_patches()
    assert nd.reshape(4, 6)[:, :3].all() and not nd.reshape(4, 6)[:, 3:].any()
    centres = scene.placement.to_frame(scene.geometry.centres())
    labels = scene.labels(np.arange(400), np.arange(600))
    got = labels[np.floor(centres[:, 1]).astype(int), np.floor(centres[:, 0]).astype(int)]
    assert np.array_equal(got, np.arange(24) + 26 * nd)


@pytest.mark.fault("input")
@pytest.mark.parametrize("pose, message", [
    ({"rotation_deg": 200}, "'chart_pose.rotation_deg': expected a number from -180 to 180 degrees"),
    ({"scale": 0}, "'chart_pose.scale': expected a number from 0.2 to 2"),
    ({"shift_x": "0.1"}, "'chart_pose.shift_x'"),
    ({"tilt": 1}, "unknown key 'chart_pose.tilt'"),
    ([3, 0, 0, 1], "key 'chart_pose': expected an object")])
def test_a_bad_chart_pose_is_one_line_naming_the_key(pose, message):
    with pytest.raises(WorldError, match=message):
        parse_world({"name": "w", "chart_pose": pose}, "w.json")


def test_the_world_puts_its_pose_on_every_chart_it_places(tmp_path):
    path = tmp_path / "posed.json"
    path.write_text(json.dumps({"name": "posed", "chart_pose": POSE.to_dict()}))
    world = load_world(path)
    assert world.chart_pose == POSE and world.to_dict()["chart_pose"] == POSE.to_dict()
    assert "chart_pose" not in load_world("nominal").to_dict()             # other worlds keep their identity
    assert load_world("posed-charts").chart_pose == POSE and load_world("posed-charts").leds_nominal
    square = tmp_path / "square.json"
    square.write_text(json.dumps({"name": "posed"}))
    assert load_world(square).identity != world.identity                   # sessions in the two are never mixed
    with VirtualLab(frame_size=(240, 160), world=world) as lab:
        assert lab.place("test").pose == POSE and lab.scene_for("train").pose == POSE
        assert lab.place("open-gate").kind == "open_gate"
