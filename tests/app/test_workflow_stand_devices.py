"""Device and session set-up written once for the CLI and the GUI (app.workflow.stand_devices): both front ends
call these functions (checked here by what they import), the virtual stand-in, the camera choice, the sphere
opened dark or closed with its light state said."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from dualrgb.app.workflow import stand_devices
from dualrgb.drivers.camera.base import CameraError
from dualrgb.drivers.led_sphere import SphereError

ROOT = Path(__file__).resolve().parents[2]


def imported_names(path: Path, module: str) -> set[str]:
    tree = ast.parse(path.read_text())
    return {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module == module for a in n.names}


def test_both_front_ends_set_up_through_the_workflow():
    cli = imported_names(ROOT / "app/commands/stand_options.py", "dualrgb.app.workflow.stand_devices")
    gui = imported_names(ROOT / "app/gui/device_hub.py", "dualrgb.app.workflow.stand_devices")
    shared = {"virtual_lab", "virtual_stand", "open_sphere"}
    assert shared <= cli and shared <= gui, (cli, gui)
    sessions = imported_names(ROOT / "app/workflow/folders.py", "dualrgb.app.workflow.stand_devices")
    assert "open_camera" in gui and "camera_definition_of" in sessions      # sessions: app.workflow.folders


class Lab:
    mode = "reflective"

    def __init__(self):
        self.placed = []

    def place(self, what, nd=False):
        self.placed.append((what, nd))
        return what


@pytest.mark.parametrize("stand_in, expected", [
    ("", ("original:painting", False)),
    ("shadow", ("original:shadow", False)),
    ("test", ("test", False)),
    ("test+nd", ("test", True)),
])
def test_an_original_is_placed_as_its_virtual_stand_in(stand_in, expected):
    lab = Lab()
    place = stand_devices.virtual_stand(lab, stand_in)      # type: ignore[arg-type]
    place("original:ACC-1", False)
    place("train", True)
    assert lab.placed == [expected, ("train", True)]


def test_a_camera_choice_names_model_and_port():
    assert stand_devices.camera_choice("Nikon DSC D610 @ usb:001,004") == ("Nikon DSC D610", "usb:001,004")
    with pytest.raises(CameraError, match="expected 'MODEL @ PORT' or 'auto'.*ptpcamerad"):
        stand_devices.camera_choice("Nikon DSC D610")


def test_auto_without_a_camera_gives_the_advice(monkeypatch):
    import dualrgb.drivers.usb_discovery as usb

    monkeypatch.setattr(usb, "gphoto_cameras", list)
    with pytest.raises(CameraError, match="no camera found.*gvfs"):
        stand_devices.camera_choice("auto")


class FailingSphere:
    """A sphere whose identify fails; its read-back says the light is off."""

    def __init__(self, port):
        self.closed = None

    def open(self):
        return self

    def identify(self):
        raise SphereError("LED sphere X: garbled answer to 'ID'")

    def ensure_off(self):
        from dualrgb.drivers.led_sphere.errors import LightReport
        return LightReport(True, "the light was switched off (confirmed)")

    def close(self, leave_on=False):
        self.closed = leave_on


def test_a_sphere_that_fails_to_open_is_closed_and_says_the_light_state(monkeypatch):
    import dualrgb.drivers.led_sphere as led

    made = []
    monkeypatch.setattr(led, "LedSphere", lambda port: made.append(FailingSphere(port)) or made[-1])
    with pytest.raises(SphereError) as info:
        stand_devices.open_sphere("/dev/ttyX")
    assert made[0].closed is True and "switched off" in " ".join(info.value.__notes__)


def test_a_virtual_session_records_the_world_as_the_cli_does():
    """The GUI's session definition names the virtual lab's world under the key the CLI's uses (virtual_world),
    so neither front end resumes a session of one world in another."""
    from types import SimpleNamespace

    from dualrgb.drivers.virtual.world import load_world

    world = load_world(None)
    lab = SimpleNamespace(mode="transmissive", width=96, height=64, world=world)
    out = stand_devices.stand_definition("reflective", None, lab)          # type: ignore[arg-type]
    assert out == {"mode": "transmissive", "frame_size": [96, 64], "world": world.identity}
    assert stand_devices.stand_definition("reflective") == {"mode": "reflective"}
