"""A world is part of what defines a virtual-lab session and of the calibration's stand identity: a session shot
in one world is never resumed in another, a calibration made in one world is refused in another (like another
camera serial); the shared --world option on demo, calibrate, capture and gui."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from dualrgb.app.cli import build_parser
from dualrgb.app.session.capture_session import CaptureSession
from dualrgb.app.session.manifest import DefinitionMismatch, camera_definition
from dualrgb.app.workflow.profile import CameraIdentity, check_reuse, load_profile
from dualrgb.app.workflow.profile_check import seal
from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.world import load_world
from tests.workflow_profiles import make_profile


def _camera(world: str) -> VirtualCamera:
    return VirtualCamera(lambda: StaticLight(np.zeros(10)), world=world)


def test_virtual_camera_reports_its_world_in_its_identity():
    nominal, other = CameraIdentity.of(_camera("nominal")), CameraIdentity.of(_camera("mismatched-d700"))
    assert nominal.world == load_world("nominal").identity and nominal.world.startswith("nominal (")
    assert other.world.startswith("mismatched-d700 (") and nominal.serial == other.serial
    assert camera_definition(_camera("aged-leds"))["world"] == load_world("aged-leds").identity


def test_calibration_from_another_world_is_refused(tmp_path):
    made_in = CameraIdentity.of(_camera("nominal"))
    prof = make_profile(tmp_path)
    prof.camera = replace(made_in, iso=50, aperture=8.0)
    prof.save(tmp_path)
    reloaded = load_profile(prof.path)
    assert reloaded.camera.world == made_in.world                    # saved and read back with the profile
    same = check_reuse(reloaded, replace(made_in, iso=50, aperture=8.0), reloaded.sphere, reloaded.lights)
    assert same.ok
    other = replace(CameraIdentity.of(_camera("mismatched-d700")), iso=50, aperture=8.0)
    check = check_reuse(reloaded, other, reloaded.sphere, reloaded.lights)
    assert not check.ok and len(check.refusals) == 1
    assert "virtual-lab world mismatched-d700 (" in check.refusals[0] and "calibration's nominal (" in check.refusals[0]
    real = replace(made_in, world="", iso=50, aperture=8.0)                # a real camera reports no world
    assert "none (a real camera)" in check_reuse(reloaded, real, reloaded.sphere, reloaded.lights).refusals[0]


def test_profile_without_a_world_still_loads(tmp_path):
    prof = make_profile(tmp_path)
    doc = json.loads(prof.path.read_text())
    doc["camera"].pop("world")
    prof.path.write_text(json.dumps(seal(doc)))          # as a dualrgb without worlds wrote it (with a digest)
    old = load_profile(prof.path, arrays=False)
    assert old.camera.world == ""
    assert check_reuse(old, replace(old.camera, world="nominal (x)"), old.sphere, old.lights).ok


def test_session_shot_in_one_world_is_not_resumed_in_another(tmp_path):
    """The camera's definition carries the world it reports (the virtual camera's, through its bridge too)."""
    folder = tmp_path / "session"
    definition = {"workflow": "calibrate", "mode": "reflective", "camera": camera_definition(_camera("nominal"))}
    CaptureSession.resume(folder, definition, {}).close()
    CaptureSession.resume(folder, definition, {}).close()                    # same world: resumed
    with pytest.raises(DefinitionMismatch, match=r"world: session 'nominal \(.*this run 'aged-leds \("):
        CaptureSession.resume(folder, {**definition, "camera": camera_definition(_camera("aged-leds"))}, {})


@pytest.mark.parametrize("command", [["demo", "--out", "o"], ["calibrate", "--session", "s", "--virtual-lab"],
                                     ["capture", "--session", "s", "--calibration", "__file__", "--id", "A",
                                      "--virtual-lab"],
                                     ["gui", "--virtual-lab"]])
def test_world_option_on_every_virtual_lab_command(command, tmp_path):
    parser = build_parser()
    argv = [str(tmp_path / "p.json") if a == "__file__" else a for a in command]
    (tmp_path / "p.json").write_text("{}")
    assert parser.parse_args(argv).world == "nominal"
    assert parser.parse_args([*argv, "--world", "mismatched-d700"]).world == "mismatched-d700"
    world_file = tmp_path / "mine.json"
    world_file.write_text('{"name": "mine"}')
    assert parser.parse_args([*argv, "--world", str(world_file)]).world == str(world_file)
    with pytest.raises(SystemExit):
        parser.parse_args([*argv, "--world", "no-such-world"])
