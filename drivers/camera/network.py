"""A camera reached through a tethering bridge over TCP (``tcp://HOST:PORT``): the camera bridge protocol
(drivers.camera.bridge_protocol, docs/camera-bridge-protocol.md) behind the :class:`drivers.camera.base.Camera`
interface, so the workflow drives it as it drives a camera on USB.

    camera = NetworkCamera("tcp://127.0.0.1:40211").open()       # `dualrgb lab serve` prints such an address
    raw = camera.capture(1 / 60)                                   # the raw file's bytes (a DNG, a NEF)

One request at a time (a lock); a request that times out or loses the connection closes it (a late reply is never
read as the answer to the next request) and is a one-line CameraError; the next call connects again. The
exposure's start and end are the host's clock, measured around the request (what the light's allowance needs).
"""
from __future__ import annotations

import contextlib
import logging
import socket
import threading
import time
from types import SimpleNamespace
from typing import Any

import numpy as np

from dualrgb.drivers.camera.base import (
    DEFAULT_LATENCY_S,
    GP_ERROR_TIMEOUT,
    Camera,
    CameraError,
    CameraSettings,
    Exposure,
    RawCapture,
)
from dualrgb.drivers.camera.bridge_protocol import PROTOCOL, SETTING_FIELDS, ProtocolError, parse_address, receive, send

log = logging.getLogger(__name__)

GP_ERROR_IO = -7                 # libgphoto2's I/O error code: the connection to the camera failed
REQUEST_TIMEOUT_S = 10.0         # settings, identity: a bridge answers these at once
FETCH_TIMEOUT_S = 120.0          # a raw file's download (~30 MB)
EXPOSE_MARGIN_S = 30.0           # beyond the exposure and the camera's latency


class NetworkCamera(Camera):
    """The camera behind the bridge at ``address`` (module docstring)."""

    name = "network camera"

    def __init__(self, address: str, timeout_s: float = REQUEST_TIMEOUT_S, fetch_timeout_s: float = FETCH_TIMEOUT_S):
        self.host, self.port = parse_address(address)
        self.address = f"tcp://{self.host}:{self.port}"
        self.timeout_s, self.fetch_timeout_s = float(timeout_s), float(fetch_timeout_s)
        self._sock: socket.socket | None = None
        self._stream: Any = None
        self._lock = threading.Lock()
        self._latency = DEFAULT_LATENCY_S
        self._latencies: dict[float, float] = {}
        self._speeds: list[float] | None = None
        self._open = False
        self.sensor: Any = None            # black and white level of the raw data, where the bridge says them

    # ---- connection ----
    def open(self) -> None:
        self._open = True
        with self._lock:
            self._connect()

    def close(self) -> None:
        self._open = False
        with self._lock:
            self._disconnect()

    def _connect(self) -> None:
        if self._sock is not None:
            return
        try:
            sock = socket.create_connection((self.host, self.port), timeout=self.timeout_s)
        except OSError as exc:
            raise CameraError(f"camera bridge {self.address}: cannot connect ({exc}); is the bridge running (e.g. "
                              "`dualrgb lab serve`) and the address right?", GP_ERROR_IO) from None
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock, self._stream = sock, sock.makefile("rb")
        reply, _ = self._exchange_locked({"op": "hello", "protocol": PROTOCOL}, self.timeout_s)
        self.name = str(reply.get("name") or self.name)
        self._latency = float(reply.get("latency_s", DEFAULT_LATENCY_S))
        levels = reply.get("raw_levels")
        self.sensor = SimpleNamespace(**levels) if isinstance(levels, dict) else None
        log.info("camera bridge %s: %s", self.address, self.name)

    def _disconnect(self) -> None:
        sock, stream, self._sock, self._stream = self._sock, self._stream, None, None
        for closable in (stream, sock):
            if closable is not None:
                with contextlib.suppress(OSError):
                    closable.close()

    def _exchange_locked(self, request: dict[str, Any], timeout_s: float) -> tuple[dict[str, Any], bytes]:
        sock = self._sock
        assert sock is not None
        try:
            sock.settimeout(timeout_s)
            send(sock, request)
            message = receive(self._stream)
            if message is None:
                raise ProtocolError("the bridge closed the connection")
        except (OSError, ProtocolError) as exc:
            self._disconnect()                     # a late reply must never answer the next request
            timeout = isinstance(exc, TimeoutError)
            what = f"no answer within {timeout_s:.3g} s" if timeout else str(exc) or type(exc).__name__
            raise CameraError(f"camera bridge {self.address}: {request['op']}: {what}; check the bridge and the "
                              "camera, then connect again", GP_ERROR_TIMEOUT if timeout else GP_ERROR_IO) from None
        header, payload = message
        if not header.get("ok"):
            raise CameraError(str(header.get("error") or "the bridge reported an error"), header.get("code"))
        return header, payload

    def _request(self, op: str, timeout_s: float | None = None, **fields: Any) -> tuple[dict[str, Any], bytes]:
        if not self._open:
            raise CameraError(f"camera bridge {self.address}: not open: call open() (or use it in a with-block) first")
        with self._lock:
            self._connect()
            return self._exchange_locked({"op": op, **fields}, self.timeout_s if timeout_s is None else timeout_s)

    # ---- Camera ----
    @property
    def latency_s(self) -> float:
        return self._latency

    def latency_for(self, exposure_s: float) -> float:
        key = float(exposure_s)
        if key not in self._latencies:
            self._latencies[key] = float(self._request("latency", exposure_s=key)[0]["latency_s"])
        return self._latencies[key]

    def settings(self) -> CameraSettings:
        return _settings(self._request("settings")[0]["settings"])

    def apply(self, settings: CameraSettings) -> CameraSettings:
        wanted = {k: getattr(settings, k) for k in SETTING_FIELDS if getattr(settings, k) is not None}
        self._latencies.clear()
        return _settings(self._request("apply", settings=wanted)[0]["settings"])

    def shutter_speeds(self) -> list[float]:
        if self._speeds is None:
            self._speeds = [float(v) for v in self._request("shutter_speeds")[0]["speeds"]]
        return list(self._speeds)

    def expose(self, exposure_s: float | None = None) -> Exposure:
        budget = (float(exposure_s or 0.0) + self.latency_s + EXPOSE_MARGIN_S)
        started = time.monotonic()
        reply, _ = self._request("expose", budget, exposure_s=exposure_s)
        ended = time.monotonic()
        return Exposure(exposure_s=float(reply["exposure_s"]), started=started, ended=ended,
                        bulb=bool(reply.get("bulb")), handle=int(reply["handle"]))

    def fetch(self, exposure: Exposure) -> RawCapture:
        reply, data = self._request("fetch", self.fetch_timeout_s, handle=exposure.handle)
        return RawCapture(data=data, filename=str(reply["filename"]), exposure_s=float(reply["exposure_s"]),
                          iso=reply.get("iso"), aperture=reply.get("aperture"), camera=str(reply.get("camera", "")),
                          extra=dict(reply.get("extra") or {}))

    def preview(self) -> np.ndarray:
        reply, data = self._request("preview")
        shape = tuple(int(v) for v in reply["shape"])
        return np.frombuffer(data, dtype=np.uint8).reshape(shape).copy()

    def frame_shape(self) -> tuple[int, int] | None:
        shape = self._request("frame_shape")[0].get("shape")
        return (int(shape[0]), int(shape[1])) if shape else None

    def image_area(self) -> str:
        return str(self._request("image_area")[0].get("image_area") or "")

    def frame_bytes(self) -> int:
        return int(self._request("frame_bytes")[0]["frame_bytes"])

    def config_summary(self) -> dict[str, object]:
        return {**dict(self._request("config")[0].get("config") or {}), "bridge": self.address}


def _settings(d: dict[str, Any]) -> CameraSettings:
    return CameraSettings(**{k: d.get(k) for k in SETTING_FIELDS})
