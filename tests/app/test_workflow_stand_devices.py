"""Device and session set-up written once for the CLI and the GUI (app.workflow.stand_devices): both front ends
call these functions (checked here by what they import), the camera choice (a camera bridge's address too), the
sphere opened dark or closed with its light state said."""
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
    assert "open_sphere" in cli and "open_sphere" in gui, (cli, gui)
    assert "open_camera" in cli, cli
    sessions = imported_names(ROOT / "app/workflow/folders.py", "dualrgb.app.workflow.stand_devices")
    assert "open_camera" in gui and "camera_definition_of" in sessions      # sessions: app.workflow.folders


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


def test_a_session_records_the_world_the_camera_reports():
    """The session's definition from the stand names the world a simulated camera reports (the virtual lab's
    camera, through its bridge as any other), so no front end resumes a session of one world in another."""
    from types import SimpleNamespace

    from dualrgb.drivers.camera.base import CameraSettings

    camera = SimpleNamespace(settings=lambda: CameraSettings(iso=50, aperture=8.0),
                             config_summary=lambda: {"camera": "sim", "serial": "S1", "world": "aged (abc)"},
                             image_area=lambda: "96x64 px")
    out = stand_devices.stand_definition("transmissive", camera)          # type: ignore[arg-type]
    assert out["mode"] == "transmissive" and out["camera"]["world"] == "aged (abc)"
    assert out["image_area"] == "96x64 px"
    assert stand_devices.stand_definition("reflective") == {"mode": "reflective"}


def test_a_camera_bridge_address_opens_a_network_camera(monkeypatch):
    """'tcp://HOST:PORT' is a camera bridge (drivers.camera.network), anything else a gphoto2 choice."""
    import dualrgb.drivers.camera.network as network

    opened = []

    class Fake:
        def __init__(self, address):
            self.address = address

        def open(self):
            opened.append(self.address)

    monkeypatch.setattr(network, "NetworkCamera", Fake)
    camera = stand_devices.open_camera("tcp://127.0.0.1:5050")
    assert isinstance(camera, Fake) and opened == ["tcp://127.0.0.1:5050"]
