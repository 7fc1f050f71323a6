"""What the device commands share (app.commands.stand_options): an error that already says the light was switched
off is not told so twice; the virtual lab's own options are refused with a physical stand's devices, not ignored;
``--iso`` / ``--aperture`` that a session or its calibration would refuse are refused before the camera is set."""
from __future__ import annotations

import argparse
import json

import pytest

from dualrgb.app.commands import stand_options
from dualrgb.app.workflow.stand.defaults import VIRTUAL_FRAME_SIZE
from dualrgb.drivers.led_sphere.switch_off import LightReport

OFF = "all LEDs and the light were switched off"


def _args(**given) -> argparse.Namespace:
    base = {"virtual_lab": False, "port": "socket://127.0.0.1:1", "camera": "tcp://127.0.0.1:2", "stand": None,
            "frame_size": VIRTUAL_FRAME_SIZE, "seed": 0, "world": "nominal", "iso": None, "aperture": None}
    return argparse.Namespace(**{**base, **given})


def test_an_error_that_says_the_light_is_off_is_not_told_twice(monkeypatch):
    import contextlib

    import dualrgb.app.workflow.stand.stand_devices as stand_devices

    monkeypatch.setattr(stand_devices, "open_sphere", lambda port: object())
    monkeypatch.setattr(stand_devices, "close_sphere", lambda sphere: LightReport(True, OFF))
    monkeypatch.setattr(stand_options, "real_camera", lambda args: contextlib.nullcontext(object()))
    exc = ValueError("training target: the grid is off the patches")
    exc.add_note(OFF)                                   # as core.light_safety.restate says it for a ValueError
    with pytest.raises(ValueError) as info, stand_options.open_devices(_args()):
        raise exc
    assert info.value.__notes__ == [OFF]


@pytest.mark.parametrize("given, said", [
    ({"frame_size": (320, 240)}, "--frame-size 320x240 without --virtual-lab"),
    ({"seed": 3, "world": "aged-leds"}, "--seed 3 and --world aged-leds without --virtual-lab"),
])
def test_the_virtual_labs_options_are_refused_with_a_physical_stand(given, said):
    with pytest.raises(ValueError, match="only the virtual lab takes") as info:
        stand_options.check_device_options(_args(**given))
    assert str(info.value).startswith(said)
    stand_options.check_device_options(_args(virtual_lab=True, port=None, camera=None, **given))    # the lab's


def test_iso_and_aperture_are_checked_against_the_session_and_calibration_before_the_camera(tmp_path):
    (tmp_path / "session.json").write_text(json.dumps(
        {"format": "dualrgb-session", "version": 1, "definition": {"camera": {"iso": 50, "aperture": 8.0}}}))
    with pytest.raises(ValueError, match="--iso 800: session .* was shot at ISO 50; nothing was set on the camera"):
        stand_options.check_camera_request(_args(iso=800), tmp_path)
    with pytest.raises(ValueError, match="--aperture 11: session .* was shot at f/8;"):
        stand_options.check_camera_request(_args(aperture=11.0), tmp_path)
    stand_options.check_camera_request(_args(iso=50, aperture=8.0), tmp_path)              # the same: accepted
    profile = argparse.Namespace(id="cal-1", camera=argparse.Namespace(iso=100, aperture=None))
    with pytest.raises(ValueError, match="calibration cal-1 was made at ISO 100;.*--iso 100, or --force"):
        stand_options.check_camera_request(_args(iso=200), None, profile)
