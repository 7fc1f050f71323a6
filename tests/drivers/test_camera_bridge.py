"""The camera bridge protocol (docs/camera-bridge-protocol.md; drivers.camera.bridge_protocol, bridge, network):
the framing byte for byte, the examples of the protocol page, a virtual camera served by the bridge and driven
through NetworkCamera exactly as directly (the same DNG bytes), and a failing or vanished bridge as one-line
CameraErrors."""
from __future__ import annotations

import io
import json
import socket
import time

import numpy as np
import pytest

from dualrgb.drivers.camera.base import CameraError, CameraSettings
from dualrgb.drivers.camera.bridge import CameraBridge
from dualrgb.drivers.camera.bridge_protocol import ProtocolError, parse_address, receive, send
from dualrgb.drivers.camera.network import NetworkCamera
from dualrgb.drivers.raw import load_raw
from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.scene import Scene
from dualrgb.simulation.datasets import default_setup


class _Pipe:
    """A socket stand-in for ``send``: collects what is sent."""

    def __init__(self):
        self.sent = b""

    def sendall(self, data: bytes) -> None:
        self.sent += data


def test_a_message_is_one_json_line_then_its_payload():
    pipe = _Pipe()
    send(pipe, {"op": "fetch", "handle": 3})                                       # type: ignore[arg-type]
    send(pipe, {"ok": True, "filename": "VIRT_0001.DNG"}, b"II*\x00")             # type: ignore[arg-type]
    assert pipe.sent == (b'{"op":"fetch","handle":3}\n'
                         b'{"ok":true,"filename":"VIRT_0001.DNG","bytes":4}\nII*\x00')
    stream = io.BytesIO(pipe.sent)
    assert receive(stream) == ({"op": "fetch", "handle": 3}, b"")
    assert receive(stream) == ({"ok": True, "filename": "VIRT_0001.DNG", "bytes": 4}, b"II*\x00")
    assert receive(stream) is None                                                 # a clean end


@pytest.mark.parametrize("raw, problem", [
    (b"not json\n", "not a JSON message line"),
    (b"[1, 2]\n", "must be a JSON object"),
    (b'{"bytes": -1}\n', "payload size -1"),
    (b'{"bytes": 10}\nabc', "closed after 3 of 10 payload bytes"),
    (b'{"op": "hel', "closed in the middle of a message"),
])
@pytest.mark.fault("input")
def test_what_is_not_a_message_is_refused_in_one_line(raw, problem):
    with pytest.raises(ProtocolError, match=problem):
        receive(io.BytesIO(raw))


def test_addresses():
    assert parse_address("tcp://127.0.0.1:5050") == ("127.0.0.1", 5050)
    assert parse_address("TCP://[::1]:80") == ("::1", 80)
    for bad in ("127.0.0.1:5050", "tcp://host", "tcp://host:0", "usb:001,004"):
        with pytest.raises(ValueError, match="expected tcp://HOST:PORT"):
            parse_address(bad)


def _camera(seed: int = 3) -> VirtualCamera:
    light = StaticLight(np.array([1.0, 0, 0, 0, 0, 1.0, 0, 1.0, 0, 0]))
    return VirtualCamera(lambda: light, Scene.with_target(default_setup("reflective").test, 96, 64), seed=seed)


@pytest.fixture
def bridged():
    bridge = CameraBridge(_camera())
    address = bridge.start()
    camera = NetworkCamera(address)
    camera.open()
    yield bridge, camera
    camera.close()
    bridge.close()


def test_a_bridged_camera_is_the_camera(bridged, tmp_path):
    """Settings, speeds, identity and the raw file itself: the bytes a direct capture of the same seeded camera
    writes (rawpy reads them like any raw file)."""
    bridge, camera = bridged
    direct = _camera()
    direct.open()
    assert camera.name == "Virtual D610" and camera.shutter_speeds() == direct.shutter_speeds()
    taken = camera.apply(CameraSettings(iso=100, aperture=5.6, shutter_s=1 / 50))
    assert taken == direct.apply(CameraSettings(iso=100, aperture=5.6, shutter_s=1 / 50))
    assert camera.settings() == taken and camera.frame_shape() == (64, 96) and camera.image_area() == "96x64 px"
    summary = camera.config_summary()
    assert summary["serial"] == "VD610-000001" and summary["world"].startswith("nominal (")
    assert summary["bridge"] == bridge.address and camera.frame_bytes() == direct.frame_bytes()
    assert camera.latency_for(0.5) == direct.latency_for(0.5) == camera.latency_s
    via, here = camera.capture(1 / 60), direct.capture(1 / 60)
    assert via.data == here.data and via.filename == here.filename == "VIRT_0001.DNG"
    assert (via.exposure_s, via.iso, via.aperture, via.camera) == (here.exposure_s, 100, 5.6, here.camera)
    assert via.extra == json.loads(json.dumps(here.extra))
    (tmp_path / via.filename).write_bytes(via.data)
    assert load_raw(tmp_path / via.filename).mosaic.shape == (64, 96)
    assert np.array_equal(camera.preview(), direct.preview())
    assert (camera.sensor.black_level, camera.sensor.white_level) == (600, 15520)      # the raw levels it says


def test_an_exposure_is_fetched_once(bridged):
    _, camera = bridged
    exposure = camera.expose(1 / 60)
    assert exposure.ended >= exposure.started and exposure.exposure_s == pytest.approx(1 / 60)
    camera.fetch(exposure)
    with pytest.raises(CameraError, match=r"exposure \d+: not taken on this bridge, or fetched already"):
        camera.fetch(exposure)


@pytest.mark.fault("camera")
def test_the_camera_s_own_error_comes_through_as_its_one_line(bridged):
    bridge, camera = bridged
    bridge.camera.inject("error", message="capture: the shutter is jammed", code=-110)   # type: ignore[attr-defined]
    with pytest.raises(CameraError, match="^capture: the shutter is jammed$") as info:
        camera.expose(1 / 60)
    assert info.value.code == -110
    bridge.camera.inject(None)                                                     # type: ignore[attr-defined]
    assert camera.capture(1 / 60).data                                             # the bridge served on


@pytest.mark.fault("camera")
def test_a_request_the_bridge_does_not_know_is_refused(bridged):
    bridge, _ = bridged
    host, port = parse_address(bridge.address)
    with socket.create_connection((host, port), timeout=5) as s, s.makefile("rb") as stream:
        s.sendall(b'{"op": "format_card"}\n')
        header, _ = receive(stream)
        assert header == {"ok": False, "kind": "protocol", "code": None,
                          "error": header["error"]} and "unknown operation 'format_card'" in header["error"]
        s.sendall(b"garbage\n")
        header, _ = receive(stream)
        assert header["kind"] == "protocol" and "not a JSON message line" in header["error"]


@pytest.mark.fault("camera")
def test_a_bridge_that_hangs_or_vanishes_is_a_one_line_error_and_the_next_call_reconnects():
    """A request held behind a hung exposure (another client's) times out in one line and closes its connection
    (a late reply never answers the next request); the next call connects again; a bridge gone is named."""
    import threading

    bridge = CameraBridge(_camera())
    address = bridge.start()
    camera, other = NetworkCamera(address, timeout_s=0.5), NetworkCamera(address)
    camera.open()
    other.open()
    bridge.camera.inject("hang")                                                   # type: ignore[attr-defined]
    hung = threading.Thread(target=other.expose, args=(1 / 60,), daemon=True)
    hung.start()
    for _ in range(1000):                                   # until the hung exposure holds the camera (hang guard)
        if bridge.lock.locked():
            break
        time.sleep(0.01)
    with pytest.raises(CameraError, match=r"settings: no answer within 0.5 s; check the bridge") as info:
        camera.settings()
    assert info.value.code == -10 and camera._sock is None
    bridge.camera.inject(None)                                                     # type: ignore[attr-defined]
    hung.join(10)
    assert camera.settings().iso == 50                                             # a new connection
    other.close()
    bridge.close()
    with pytest.raises(CameraError, match="camera bridge tcp://127.0.0.1:.*(cannot connect|closed)"):
        camera.settings()
    camera.close()
