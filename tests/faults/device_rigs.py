"""The physical stand's faults for the device fault suite (issue 28): hand-made serial peers on real
pseudo-terminals and cameras that are not there, fail or hang, for the commands run as a technician runs them.

Sphere peers (``sphere_peer(kind)`` -> a context manager yielding a :class:`Peer`):

* ``silent``: a pty nobody answers on (the wrong port, a sphere without power);
* ``garbage``: a pty that speaks random bytes (wrong baud rate, another device);
* ``disconnecting``: the sphere emulator, unplugged (pty closed) once it is lit or after ``after`` requests
  (0: during the first);
* ``ignoring``: the sphere emulator lit by another program, acknowledging ``ALLOFF`` and ``LIGHT 0`` without
  carrying them out (a stuck relay, a firmware bug: emulator fault ``disobey``).

Cameras (``camera_fault(monkeypatch, kind)`` -> the ``--camera`` value): ``missing`` (libgphoto2 itself, a port
that does not exist), ``failing`` (libgphoto2's calls replayed by tests/drivers/gphoto_fake.py, the trigger
answering -7 I/O problem with the reason only in the log, as libgphoto2 does), ``hanging`` (the same stand-in,
the trigger never returning; the driver's host-side deadlines shortened to 2 s so the suite stays quick), and
``working`` (the stand-in taking pictures, for the sphere's faults).
"""
from __future__ import annotations

import contextlib
import functools
import os
import random
import sys
import threading
import time
import tty
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "drivers"))     # gphoto_fake, sphere_fakes

from gphoto_fake import FakeGPhoto2, GPhoto2Error

from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator

SPHERE_PEERS = ("silent", "garbage", "disconnecting", "ignoring")
CAMERA_FAULTS = ("missing", "failing", "hanging")
SCRIPTED_CAMERA = "Nikon DSC D610 @ usb:001,007"
MISSING_CAMERA = "Nikon DSC D610 @ usb:001,002"
HOST_DEADLINE_S = 2.0


@dataclass
class Peer:
    port: str
    emulator: SphereEmulator | None = None
    stop: threading.Event = field(default_factory=threading.Event)

    def light_off(self, within_s: float = 0.0) -> bool:
        """Whether the emulated sphere emits nothing (waiting up to ``within_s`` for its own limits)."""
        if self.emulator is None:
            return True                           # nothing there to light
        deadline = time.monotonic() + within_s
        while True:
            snap = self.emulator.snapshot()
            if not snap.light_on or not snap.levels.any():
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.05)


def _raw_pty() -> tuple[int, int]:
    master, slave = os.openpty()
    tty.setraw(slave)
    return master, slave


def _speak_garbage(master: int, stop: threading.Event) -> None:
    rng = random.Random(28)
    os.set_blocking(master, False)
    while not stop.is_set():
        with contextlib.suppress(OSError):
            os.write(master, bytes(rng.randrange(256) for _ in range(rng.randint(1, 40))))
            os.read(master, 4096)
        time.sleep(0.01)


def _unplug_after(emulator: SphereEmulator, after: int, stop: threading.Event) -> None:
    """Unplug the emulator once it is lit (the worst moment) or after ``after`` requests, whichever comes first;
    ``after=0``: while the first request is on the wire (it is not answered)."""
    if after == 0:
        emulator.inject("no_reply")          # executed, never answered: counted in emulator.requests
    while not stop.is_set() and len(emulator.requests) < max(after, 1):
        snap = emulator.snapshot()
        if snap.light_on and snap.levels.any():
            break
        time.sleep(0.002)
    if not stop.is_set():
        emulator.inject("disconnect")


@contextlib.contextmanager
def sphere_peer(kind: str, after: int = 4) -> Iterator[Peer]:
    """A sphere peer of ``kind`` (module docstring); stopped and closed on the way out."""
    if kind in ("silent", "garbage"):
        master, slave = _raw_pty()
        peer = Peer(os.ttyname(slave))
        if kind == "garbage":
            threading.Thread(target=_speak_garbage, args=(master, peer.stop), daemon=True).start()
        try:
            yield peer
        finally:
            peer.stop.set()
            os.close(master)
            os.close(slave)
        return
    emulator = SphereEmulator(watchdog_s=30)
    peer = Peer(emulator.start(), emulator)
    if kind == "disconnecting":           # ("working": the emulator as it is)
        threading.Thread(target=_unplug_after, args=(emulator, after, peer.stop), daemon=True).start()
    elif kind == "ignoring":
        for line in (b"LEVELS 65535 0 0 0 0 65535 0 0 0 0", b"LIGHT 1"):       # lit by another program
            assert emulator.handle(line).startswith(b"OK")
        emulator.inject("disobey", keywords=["ALLOFF", "LIGHT"])
    try:
        yield peer
    finally:
        peer.stop.set()
        emulator.stop()


class _Abilities(list):
    def load(self) -> None:
        pass

    def lookup_model(self, name: str) -> int:
        if name != "Nikon DSC D610":
            raise GPhoto2Error(-105)
        return 0

    def __getitem__(self, i):
        return SimpleNamespace(model="Nikon DSC D610")


class StandGPhoto2(FakeGPhoto2):
    """The scripted libgphoto2 with what opening a named camera on a port also needs."""

    def CameraAbilitiesList(self):
        return _Abilities()


def _failing_trigger(camera) -> None:
    camera.calls.append("trigger")
    camera.gp.log("ptp2/trigger_capture", "PTP I/O error: the camera went away during the exposure")
    raise GPhoto2Error(-7)


def camera_fault(monkeypatch, kind: str) -> tuple[str, threading.Event]:
    """Prepare camera fault ``kind``: the ``--camera`` value to pass, and an event that releases a hung call."""
    release = threading.Event()
    if kind == "missing":
        pytest = __import__("pytest")
        pytest.importorskip("gphoto2", reason="libgphoto2 (python-gphoto2) is not installed")
        return MISSING_CAMERA, release
    from dualrgb.drivers.camera import gphoto

    gp = StandGPhoto2()
    camera = gp.camera
    camera.quality = camera.t["raw"]
    if kind == "failing":
        camera.trigger_capture = lambda: _failing_trigger(camera)
    elif kind == "hanging":
        camera.trigger_capture = lambda: (camera.calls.append("trigger"), release.wait(60))
    monkeypatch.setattr(gphoto, "_import_gphoto", lambda: gp)
    monkeypatch.setattr(gphoto, "GPhotoCamera", functools.partial(
        gphoto.GPhotoCamera, call_timeout_s=HOST_DEADLINE_S, capture_timeout_s=HOST_DEADLINE_S, busy_delay_s=0.01))
    return SCRIPTED_CAMERA, release
