"""The camera's two phases (expose, then fetch: the light can be off during the download) and host-side deadlines
(a hung libgphoto2 call is a one-line CameraError, and the camera is not entered again until it returns)."""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from test_gphoto_logic import open_fake

from dualrgb.drivers.camera.base import CameraError, CameraTimeout, call_with_deadline
from dualrgb.drivers.raw import load_raw
from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.scene import Scene


def test_call_with_deadline_returns_raises_or_times_out():
    assert call_with_deadline(lambda: 42, 1.0, "answer") == 42
    with pytest.raises(KeyError):
        call_with_deadline(lambda: {}["x"], 1.0, "lookup")
    gate = threading.Event()
    started = time.monotonic()
    with pytest.raises(CameraTimeout, match=r"^capture: the camera did not answer within 0\.2 s; ") as info:
        call_with_deadline(lambda: gate.wait(30), 0.2, "capture")
    # it waited its deadline and no longer: the hung call is still inside (the gate opens only below)
    assert time.monotonic() - started >= 0.2 and info.value.code == -10 and info.value.worker.is_alive()
    gate.set()
    info.value.worker.join(1)


def test_gphoto_expose_does_not_download_and_fetch_does():
    cam, d610, _ = open_fake()
    downloads = []
    real_get = d610.file_get
    d610.file_get = lambda *a: downloads.append(a[1]) or real_get(*a)
    exposure = cam.expose(0.5)
    assert downloads == [] and d610.events                   # announced, not read with the light on
    raw = cam.fetch(exposure)
    assert downloads == ["capt0000.nef"] and raw.data == b"NEF-capt0000.nef" and raw.exposure_s == 0.5


def test_gphoto_bulb_expose_returns_when_the_shutter_closed_and_fetch_waits_for_the_file():
    cam, d610, clock = open_fake()
    exposure = cam.expose(45.0)
    assert exposure.bulb and exposure.handle.files == [] and d610.writes[-1] == ("bulb", 0)
    assert cam.fetch(exposure).filename == "capt0000.nef"


def test_a_hung_gphoto_call_is_a_camera_error_and_the_camera_is_not_entered_twice():
    cam, d610, _ = open_fake(capture_timeout_s=0.2)
    gate = threading.Event()
    real_trigger = d610.trigger_capture
    d610.trigger_capture = lambda: gate.wait(30) and real_trigger()
    with pytest.raises(CameraError, match=r"^capture: the camera did not answer within 0\.7 s") as info:
        cam.expose(0.5)
    assert "\n" not in str(info.value)              # and it did not wait for the hung call: it is still inside
    with pytest.raises(CameraError, match="has not finished 'capture'"):
        cam.settings()                               # libgphoto2 is still inside capture: refused, not entered
    gate.set()
    time.sleep(0.1)
    assert cam.capture(0.5).filename.endswith(".nef")   # once it returned, the camera works again


def test_virtual_camera_renders_the_light_it_saw_at_expose_time(tmp_path):
    light = StaticLight(levels=np.zeros(10))
    light.levels[[0, 5, 7]] = 1.0
    cam = VirtualCamera(lambda: light, Scene.open_gate(width=64, height=48))
    cam.open()
    lit = cam.expose(1 / 60)
    light.levels = np.zeros(10)                      # the light goes off before the download
    dark = cam.expose(1 / 60)
    frames = []
    for i, e in enumerate((lit, dark)):
        raw = cam.fetch(e)
        (tmp_path / f"{i}.dng").write_bytes(raw.data)
        frames.append(load_raw(tmp_path / f"{i}.dng"))
    lit_frame, dark_frame = frames
    assert lit_frame.mosaic.mean() > 5000 > 700 > dark_frame.mosaic.mean()
    assert [e.lit for e in cam.exposure_log] == [True, False]


def test_virtual_camera_faults():
    cam = VirtualCamera(lambda: StaticLight(levels=np.ones(10)), Scene.open_gate(width=64, height=48))
    cam.open()
    cam.inject("latency", delay_s=0.2)
    exposure = cam.expose(1 / 60)
    assert cam.exposure_log[-1].t_open - exposure.started >= 0.2
    cam.inject("hang")
    worker = threading.Thread(target=cam.expose, args=(1 / 60,), daemon=True)
    worker.start()
    worker.join(0.3)
    assert worker.is_alive()
    cam.inject(None)                                 # clears every fault and ends the hang
    worker.join(2)
    assert not worker.is_alive()
    cam.inject("error", message="capture: injected", code=-113)
    with pytest.raises(CameraError, match="injected"):
        cam.expose(1 / 60)
    with pytest.raises(ValueError):
        cam.inject("smoke")
