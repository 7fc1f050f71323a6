"""A real camera's timing in the virtual camera (issue 41): a world's ``camera_timing`` (a preset's name or the two
seconds) makes the virtual camera wait its shutter lag inside ``expose()`` and its download inside ``fetch()``; the
waits are observed through the module's sleep (no wall-clock figure asserted); a bad value is one line naming the
file and the key; a world without the key keeps its identity."""
from __future__ import annotations

import json

import numpy as np
import pytest

from dualrgb.drivers.virtual import camera_timing
from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.camera_timing import PRESETS, CameraTiming
from dualrgb.drivers.virtual.world import World, WorldError, read_world


def _world(tmp_path, timing) -> World:
    path = tmp_path / "w.json"
    path.write_text(json.dumps({"name": "timed", "camera_timing": timing}))
    return read_world(path)


def test_the_d610_preset_and_explicit_seconds_are_read_from_a_world_file(tmp_path):
    d610 = _world(tmp_path, "d610").camera_timing
    assert d610 == PRESETS["d610"] and 0.05 <= d610.shutter_lag_s <= 0.1 and d610.download_s == pytest.approx(1.0)
    own = _world(tmp_path, {"shutter_lag_s": 0.2, "download_s": 2.5}).camera_timing
    assert (own.shutter_lag_s, own.download_s) == (0.2, 2.5)
    assert _world(tmp_path, "d610").to_dict()["camera_timing"] == "d610"
    assert "camera_timing" not in World().to_dict()                     # no key: the nominal identity is kept
    assert _world(tmp_path, "d610").identity != World(name="timed").identity


@pytest.mark.parametrize("value,says", [("d700", "key 'camera_timing': expected one of d610"),
                                        ({"lag_s": 0.1}, "unknown key 'camera_timing.lag_s'"),
                                        ({"download_s": -1}, "key 'camera_timing.download_s': expected a number"),
                                        ({"download_s": "1 s"}, "key 'camera_timing.download_s'"),
                                        (3, "key 'camera_timing': expected a preset's name")])
def test_a_bad_camera_timing_is_one_line_naming_the_file_and_key(tmp_path, value, says):
    with pytest.raises(WorldError) as err:
        _world(tmp_path, value)
    assert str(err.value).startswith(str(tmp_path / "w.json")) and says in str(err.value)
    assert "\n" not in str(err.value)


def test_the_virtual_camera_waits_its_shutter_lag_and_download(monkeypatch):
    slept: list[float] = []
    monkeypatch.setattr(camera_timing.time, "sleep", slept.append)
    world = World(camera_timing=CameraTiming(shutter_lag_s=0.07, download_s=1.0))
    cam = VirtualCamera(lambda: StaticLight(np.zeros(10)), world=world, seed=1)
    cam.open()
    exposure = cam.expose(1 / 60)
    assert slept == [0.07]                                  # the lag, between the trigger and the shutter opening
    cam.fetch(exposure)
    assert len(slept) == 2 and 0.0 < slept[1] <= 1.0        # the rest of the 1 s download after the render
    nominal = VirtualCamera(lambda: StaticLight(np.zeros(10)), seed=1)
    nominal.open()
    slept.clear()
    nominal.fetch(nominal.expose(1 / 60))
    assert slept == []                                      # the nominal world: no timing
