"""A tethering bridge: any :class:`drivers.camera.base.Camera` served over TCP with the camera bridge protocol
(drivers.camera.bridge_protocol, docs/camera-bridge-protocol.md), so that the program driving the stand opens it
as ``tcp://HOST:PORT`` (drivers.camera.network.NetworkCamera) like any other camera.

    bridge = CameraBridge(GPhotoCamera(port="usb:001,004"))     # or the virtual lab's camera (`dualrgb lab serve`)
    print("camera", bridge.start())                               # tcp://127.0.0.1:40211
    ...; bridge.close()                                            # the camera is closed with it

Each connection is served on its own thread; the camera is called by one of them at a time (a lock), in the order
the requests arrive. An exposure's frame is kept until it is fetched (at most :data:`KEPT_EXPOSURES`, the oldest
dropped first). A camera error is the reply's one line; nothing raised by a request stops the bridge.
"""
from __future__ import annotations

import contextlib
import itertools
import logging
import math
import socket
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import numpy as np

from dualrgb.drivers.camera.base import Camera, CameraError, CameraSettings, Exposure
from dualrgb.drivers.camera.bridge_protocol import (
    PROTOCOL,
    SETTING_FIELDS,
    ProtocolError,
    error_reply,
    receive,
    send,
)

log = logging.getLogger(__name__)

KEPT_EXPOSURES = 8          # exposures taken and not fetched yet that the bridge keeps (a client that died)
Reply = tuple[dict[str, Any], bytes]


class CameraBridge:
    """Serve ``camera`` (opened by :meth:`start`, closed by :meth:`close`) on ``host``:``port`` (0: a free port)."""

    def __init__(self, camera: Camera, host: str = "127.0.0.1", port: int = 0):
        self.camera = camera
        self._host, self._port = host, port
        self._listener: socket.socket | None = None
        self._threads: list[threading.Thread] = []
        self._conns: set[socket.socket] = set()
        self.lock = threading.Lock()                  # one camera call at a time (and nothing else that moves
                                                      # what it sees: the lab's sample changer takes it too)
        self._exposures: OrderedDict[int, Exposure] = OrderedDict()
        self._ids = itertools.count(1)
        self._stop = threading.Event()
        self.address = ""
        self._ops: dict[str, Callable[[dict[str, Any]], Reply]] = {
            "hello": self._hello, "settings": self._settings, "apply": self._apply,
            "shutter_speeds": lambda _r: ({"speeds": list(self.camera.shutter_speeds())}, b""),
            "expose": self._expose, "fetch": self._fetch, "preview": self._preview,
            "frame_shape": lambda _r: ({"shape": self.camera.frame_shape()}, b""),
            "image_area": lambda _r: ({"image_area": self.camera.image_area()}, b""),
            "frame_bytes": lambda _r: ({"frame_bytes": int(self.camera.frame_bytes())}, b""),
            "latency": lambda r: ({"latency_s": float(self.camera.latency_for(float(r.get("exposure_s") or 0)))}, b""),
            "config": lambda _r: ({"config": _plain(self.camera.config_summary())}, b"")}

    def start(self) -> str:
        """Open the camera and listen; returns the address a client opens (``tcp://HOST:PORT``)."""
        self.camera.open()
        listener = socket.create_server((self._host, self._port))
        self._listener = listener
        self.address = f"tcp://{self._host}:{listener.getsockname()[1]}"
        thread = threading.Thread(target=self._accept_loop, name=f"camera bridge {self.address}", daemon=True)
        thread.start()
        self._threads.append(thread)
        log.info("camera bridge: %s on %s", getattr(self.camera, "name", "camera"), self.address)
        return self.address

    def close(self) -> None:
        """Stop listening, drop the clients, close the camera."""
        self._stop.set()
        for s in [self._listener, *list(self._conns)]:
            if s is not None:
                with contextlib.suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)
                with contextlib.suppress(OSError):
                    s.close()
        self._listener = None
        for t in self._threads:
            if t is not threading.current_thread():
                t.join(timeout=5)
        with self.lock:
            self.camera.close()

    def __enter__(self) -> CameraBridge:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- serving ----
    def _accept_loop(self) -> None:
        listener = self._listener
        while listener is not None and not self._stop.is_set():
            try:
                conn, peer = listener.accept()
            except OSError:
                return
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._conns.add(conn)
            thread = threading.Thread(target=self._serve, args=(conn,), name=f"camera bridge client {peer}",
                                      daemon=True)
            self._threads = [t for t in self._threads if t.is_alive()] + [thread]
            thread.start()

    def _serve(self, conn: socket.socket) -> None:
        with conn, conn.makefile("rb") as stream:
            while not self._stop.is_set():
                try:
                    message = receive(stream)
                except (ProtocolError, OSError) as exc:
                    with contextlib.suppress(OSError):
                        send(conn, error_reply(str(exc), "protocol"))
                    break
                if message is None:
                    break
                header, payload = self.answer(message[0])
                try:
                    send(conn, header, payload)
                except OSError as exc:                  # the client went away: its reply is lost, nothing else
                    log.info("camera bridge: reply not sent (%s)", exc)
                    break
        self._conns.discard(conn)

    def answer(self, request: dict[str, Any]) -> Reply:
        """The reply to one request (never raises)."""
        op = request.get("op")
        handler = self._ops.get(op) if isinstance(op, str) else None
        if handler is None:
            return error_reply(f"unknown operation {op!r}: expected one of {', '.join(self._ops)}", "protocol"), b""
        try:
            with self.lock:
                header, payload = handler(request)
        except CameraError as exc:
            return error_reply(str(exc), "camera", exc.code), b""
        except (ValueError, TypeError, KeyError) as exc:
            return error_reply(f"{op}: {exc}", "protocol"), b""
        except Exception as exc:  # one request's failure must not stop the bridge; it is logged
            log.exception("camera bridge: %s failed", op)
            return error_reply(f"{op}: {type(exc).__name__}: {exc}", "internal"), b""
        return {"ok": True, **header}, payload

    # ---- operations ----
    def _hello(self, request: dict[str, Any]) -> Reply:
        if request.get("protocol") != PROTOCOL:
            raise ValueError(f"protocol {request.get('protocol')!r}: this bridge speaks {PROTOCOL}")
        sensor = getattr(self.camera, "sensor", None)          # raw levels, where the camera knows them
        levels = ({"black_level": int(sensor.black_level), "white_level": int(sensor.white_level)}
                  if sensor is not None else None)
        return {"protocol": PROTOCOL, "name": str(getattr(self.camera, "name", "camera")),
                "latency_s": float(self.camera.latency_s), "config": _plain(self.camera.config_summary()),
                "raw_levels": levels}, b""

    def _settings(self, _request: dict[str, Any]) -> Reply:
        return {"settings": settings_dict(self.camera.settings())}, b""

    def _apply(self, request: dict[str, Any]) -> Reply:
        wanted = request.get("settings") or {}
        if not isinstance(wanted, dict) or set(wanted) - set(SETTING_FIELDS):
            raise ValueError(f"settings {wanted!r}: expected an object with some of {', '.join(SETTING_FIELDS)}")
        return {"settings": settings_dict(self.camera.apply(CameraSettings(**wanted)))}, b""

    def _expose(self, request: dict[str, Any]) -> Reply:
        t = request.get("exposure_s")
        exposure = self.camera.expose(None if t is None else float(t))
        handle = next(self._ids)
        self._exposures[handle] = exposure
        while len(self._exposures) > KEPT_EXPOSURES:
            dropped, _ = self._exposures.popitem(last=False)
            log.warning("camera bridge: exposure %d was never fetched; dropped", dropped)
        return {"handle": handle, "exposure_s": exposure.exposure_s, "bulb": exposure.bulb,
                "duration_s": float(exposure.ended - exposure.started)}, b""

    def _fetch(self, request: dict[str, Any]) -> Reply:
        handle = request.get("handle")
        exposure = self._exposures.pop(handle, None) if isinstance(handle, int) else None
        if exposure is None:
            raise CameraError(f"exposure {handle!r}: not taken on this bridge, or fetched already")
        raw = self.camera.fetch(exposure)
        return {"filename": raw.filename, "exposure_s": raw.exposure_s, "iso": raw.iso, "aperture": raw.aperture,
                "camera": raw.camera, "extra": _plain(raw.extra)}, bytes(raw.data)

    def _preview(self, _request: dict[str, Any]) -> Reply:
        img = np.ascontiguousarray(self.camera.preview(), dtype=np.uint8)
        return {"shape": list(img.shape)}, img.tobytes()


def settings_dict(s: CameraSettings) -> dict[str, Any]:
    return {k: getattr(s, k) for k in SETTING_FIELDS}


def _plain(value: Any) -> Any:
    """``value`` with numpy scalars and arrays, tuples and other objects made JSON's (strings at worst)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return _plain(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None                                  # JSON has no NaN / infinity
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)
