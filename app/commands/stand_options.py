"""What ``dualrgb calibrate``, ``capture``, ``process`` and ``calibration show`` share: device options (the
virtual lab or --port / --camera), progress on stderr, the ``--json`` option (written by app.json_output, the
one writer), the reuse limits. Not a command itself.
"""
from __future__ import annotations

import argparse
import contextlib
import logging
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dualrgb.app.commands.options import add_world_option, count, frame_size, number, seed
from dualrgb.app.json_output import HELP as JSON_HELP
from dualrgb.app.workflow.defaults import DEFAULT_MODE, SETTLE_S, VIRTUAL_FRAME_SIZE

if TYPE_CHECKING:                       # types only: a command imports its devices when it runs (fast --help)
    from dualrgb.app.protocols import Sphere
    from dualrgb.app.session.capture_session import CaptureSession
    from dualrgb.app.workflow.device_actions import Place as Stand
    from dualrgb.drivers.camera.base import Camera
    from dualrgb.drivers.virtual.lab import VirtualLab

log = logging.getLogger(__name__)


def add_device_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("devices")
    g.add_argument("--virtual-lab", action="store_true", help="the built-in virtual lab (sphere emulator + camera)")
    g.add_argument("--port", help="the LED sphere's serial port (e.g. /dev/ttyACM0)")
    g.add_argument("--camera", help="the camera as 'MODEL @ PORT' (from `dualrgb devices`), or 'auto' (the first)")
    g.add_argument("--frame-size", type=frame_size, default=VIRTUAL_FRAME_SIZE,
                   help="virtual lab frames WxH ({}x{})".format(*VIRTUAL_FRAME_SIZE))
    g.add_argument("--seed", type=seed, default=0, help="virtual lab noise seed")
    add_world_option(g)
    g.add_argument("--iso", type=count(25, 409600), help="set the camera's ISO first")
    g.add_argument("--aperture", type=number(0.5, 128), help="set the camera's f-number first")
    g.add_argument("--settle", type=number(0.0, 5.0, unit=" s"), default=SETTLE_S,
                   help=f"seconds between light on and shutter ({SETTLE_S:g})")
    p.add_argument("--json", metavar="PATH", dest="json_path", help=JSON_HELP)


def check_device_options(args: argparse.Namespace) -> None:
    """What the device options must say, answered before anything heavy is imported: the virtual lab, or the
    sphere's port AND the camera (``ValueError``, one line)."""
    if getattr(args, "virtual_lab", False):
        return
    port, camera = getattr(args, "port", None), getattr(args, "camera", None)
    if port and not camera:
        raise ValueError(f"--port {port} without --camera: name the camera too (--camera 'MODEL @ PORT' from "
                         "`dualrgb devices`, or auto), or use --virtual-lab")
    if camera and not port:
        raise ValueError(f"--camera {camera!r} without --port: name the sphere's serial port too (e.g. --port "
                         "/dev/ttyACM0), or use --virtual-lab")
    if not port:
        raise ValueError("name the devices: --port SERIAL_PORT --camera 'MODEL @ PORT' (or --virtual-lab)")


def add_reuse_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--force", action="store_true", help="use a calibration that does not match, with a warning")
    p.add_argument("--max-age-h", type=number(0.0, 8760), default=8.0, help="warn when the calibration is older (8 h)")
    p.add_argument("--max-temperature-drift", type=number(0.0, 100), default=5.0,
                   help="refuse when the sphere is this many C from the calibration's temperature (5)")


def progress_printer() -> Callable[[float, str], None]:
    last: list[str | None] = [None]

    def progress(f: float, msg: str) -> None:
        line = f"[{int(100 * f):3d}%] {msg}"
        if line != last[0]:
            last[0] = line
            print(line, file=sys.stderr, flush=True)
    return progress


def ask_person(message: str) -> None:
    """A prompt from a sequence: say it and wait for Enter (a terminal is needed)."""
    if not sys.stdin or not sys.stdin.isatty():
        raise ValueError(f"{message}: needs a person at the stand (run in a terminal, or use --virtual-lab)")
    print(f">>> {message} (Enter)", file=sys.stderr, flush=True)
    sys.stdin.readline()


@dataclass
class Devices:
    camera: Camera
    sphere: Sphere
    stand: Stand | None
    lab: VirtualLab | None = None


@contextlib.contextmanager
def open_devices(args: argparse.Namespace, mode: str = DEFAULT_MODE, original: str | None = None
                 ) -> Iterator[Devices]:
    """The virtual lab or the real sphere + camera (app.workflow.stand_devices, shared with the GUI); LEDs off and
    ports closed on the way out, whatever happens.

    In the virtual lab an original is placed as its virtual stand-in ``original`` (``--virtual-original``: a
    virtual original's name, or a chart: 'test', 'test+nd' with the ND 2.0 filter over half)."""
    from dualrgb.app.workflow.stand_devices import apply_settings, virtual_lab, virtual_stand

    if args.virtual_lab:
        with virtual_lab(mode, args.frame_size, args.seed, args.world) as lab:
            camera, sphere = lab.devices()
            apply_settings(camera, args.iso, args.aperture)
            yield Devices(camera, sphere, virtual_stand(lab, original or ""), lab)
        return
    check_device_options(args)
    yield from _real_devices(args)


@contextlib.contextmanager
def real_camera(args: argparse.Namespace) -> Iterator[Camera]:
    """The tethered camera ``args.camera`` ('MODEL @ PORT' or 'auto': the first found), ISO / aperture applied
    (app.workflow.stand_devices.open_camera, as the GUI opens it)."""
    from dualrgb.app.workflow.stand_devices import close_camera, open_camera

    camera = open_camera(args.camera, args.iso, args.aperture)
    try:
        yield camera
    finally:
        close_camera(camera)


def _real_devices(args: argparse.Namespace) -> Iterator[Devices]:
    """The sphere on ``--port`` (identified and switched off first: app.workflow.stand_devices.open_sphere) and
    the camera; whatever fails, the light is switched off on the way out (close_sphere) and the error carries a
    note saying what state it is in (read back, never assumed)."""
    from dualrgb.app.workflow.stand_devices import close_sphere, open_sphere
    from dualrgb.drivers.led_sphere import SphereError

    sphere = open_sphere(args.port)
    try:
        with real_camera(args) as camera:
            yield Devices(camera, sphere, None, None)
    except BaseException as exc:
        report = close_sphere(sphere)
        if not (isinstance(exc, SphereError) and exc.light is not None) and (
                not report.off or not _says_light_off(str(exc))):
            exc.add_note(report.message)
        raise
    report = close_sphere(sphere)           # every LED 0, light off, read back
    if not report.off:
        raise SphereError(f"closing the devices: {report.message}", kind="unconfirmed", light="unknown")


def _says_light_off(message: str) -> bool:
    """Whether an error already says the light was switched off (app.workflow.light_safety.restate)."""
    return "switched off" in message


def add_session_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--session", type=Path, default=None,
                   help="session folder (created, or resumed); default: a new dated one such as 2026-11-24_1 in "
                        "the captures folder (<per-user data folder>/captures)")


def open_session(folder: Path | None, definition: dict, camera: Camera, meta: dict | None = None) -> CaptureSession:
    """The session in ``folder``: new, or resumed when it was made with the same ``definition`` and camera
    (app.workflow.folders.open_session; anything else is refused in one line naming the difference). No
    ``folder``: a new dated session in the captures folder, named on stderr."""
    from dualrgb.app.workflow.folders import open_session as open_or_make

    session = open_or_make(folder, definition, camera, meta,
                           hint="use the same options and camera, or another --session")
    if folder is None:
        print(f"dualrgb: new session {session.path}", file=sys.stderr, flush=True)
    return session


def virtual_world(args: argparse.Namespace) -> dict[str, str]:
    """``{"world": identity}`` for a virtual-lab run (a session shot in one world is never resumed in another;
    drivers.virtual.world.World.identity), ``{}`` on a real stand."""
    if not args.virtual_lab:
        return {}
    from dualrgb.drivers.virtual.world import load_world

    return {"world": load_world(args.world).identity}


def reuse_limits(args: argparse.Namespace) -> Any:
    from dualrgb.app.workflow.profile import ReuseLimits

    return ReuseLimits(temperature_drift_c=args.max_temperature_drift, max_age_h=args.max_age_h)
