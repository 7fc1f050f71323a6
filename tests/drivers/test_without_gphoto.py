"""Without python-gphoto2 (Windows, or not installed) everything but tethering works, and the camera side says
in one line what tethering needs. gphoto2 is hidden by a None entry in sys.modules (import raises ImportError)."""
from __future__ import annotations

import sys

import pytest

from dualrgb.drivers.camera.base import CameraError
from dualrgb.drivers.camera.gphoto import TETHERING_UNAVAILABLE, GPhotoCamera, gphoto_available


@pytest.fixture
def no_gphoto(monkeypatch):
    monkeypatch.setitem(sys.modules, "gphoto2", None)


def test_tethering_says_what_it_needs_in_one_line(no_gphoto):
    assert not gphoto_available()
    with pytest.raises(CameraError) as err:
        GPhotoCamera().open()
    assert str(err.value).startswith(TETHERING_UNAVAILABLE) and "\n" not in str(err.value)
    assert "libgphoto2" in TETHERING_UNAVAILABLE and "Linux/macOS" in TETHERING_UNAVAILABLE


def test_devices_report_carries_the_hint(no_gphoto, capsys, monkeypatch):
    import dualrgb.drivers.usb_discovery as ud
    from dualrgb.app.cli import main

    monkeypatch.setattr(ud, "usb_cameras", list)
    monkeypatch.setattr(ud, "serial_ports", list)
    assert TETHERING_UNAVAILABLE in ud.discover().hints
    assert main(["devices", "--no-probe"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "tethering needs libgphoto2" in err


def test_virtual_lab_captures_without_gphoto(no_gphoto, tmp_path):
    from dualrgb.drivers.raw import load_raw
    from dualrgb.drivers.virtual.lab import VirtualLab

    with VirtualLab(frame_size=(96, 64)) as lab:
        lab.place("open-gate")
        lab.sphere.set_level(1, 1.0)
        lab.sphere.on()
        cap = lab.camera.capture(1 / 60)
        lab.sphere.shutdown()
    path = tmp_path / cap.filename
    path.write_bytes(cap.data)
    assert load_raw(path).mosaic.shape == (64, 96)
