"""What ``dualrgb calibrate``, ``capture``, ``process`` and ``calibration show`` share: device options (--port /
--camera / --stand, or --virtual-lab: the shorthand that starts `dualrgb lab serve` as a child process and uses its
instruments' addresses, app.lab.process), progress on stderr, the ``--json`` option (written by app.json_output, the
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
from dualrgb.app.workflow.stand.defaults import DEFAULT_MODE, SETTLE_S, VIRTUAL_FRAME_SIZE
from dualrgb.common.formatting import format_duration
from dualrgb.common.progress import Cancelled

if TYPE_CHECKING:                       # types only: a command imports its devices when it runs (fast --help)
    from dualrgb.core.device_actions import Place as Stand
    from dualrgb.core.engine import RunClock
    from dualrgb.core.protocols import Sphere
    from dualrgb.core.session.capture_session import CaptureSession
    from dualrgb.drivers.camera.base import Camera
    from dualrgb.drivers.sample_changer import SampleChanger

log = logging.getLogger(__name__)


#: the options only the virtual lab takes, with their defaults as shown (check_device_options refuses any other
#: value with --port / --camera: a physical stand would silently ignore it)
LAB_ONLY_DEFAULTS: dict[str, object] = {"frame_size": "{}x{}".format(*VIRTUAL_FRAME_SIZE), "seed": 0,
                                        "world": "nominal"}


def add_device_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("devices")
    g.add_argument("--virtual-lab", action="store_true",
                   help="start the built-in virtual lab (`dualrgb lab serve`, a child process) and use its sphere, "
                        "camera and sample changer")
    g.add_argument("--port", help="the LED sphere's serial port or URL (e.g. /dev/ttyACM0, socket://HOST:PORT)")
    g.add_argument("--camera", help="the camera as 'MODEL @ PORT' (from `dualrgb devices`), 'auto' (the first), or "
                                    "a camera bridge's tcp://HOST:PORT")
    g.add_argument("--stand", help="an automated sample changer's serial port or URL: it places the targets and "
                                   "originals (without one, the prompts ask you)")
    g.add_argument("--frame-size", type=frame_size, default=VIRTUAL_FRAME_SIZE,
                   help="--virtual-lab: its frames WxH ({})".format(LAB_ONLY_DEFAULTS["frame_size"]))
    g.add_argument("--seed", type=seed, default=LAB_ONLY_DEFAULTS["seed"], help="--virtual-lab: its noise seed")
    add_world_option(g)                 # its default: LAB_ONLY_DEFAULTS["world"]
    g.add_argument("--iso", type=count(25, 409600), help="set the camera's ISO first")
    g.add_argument("--aperture", type=number(0.5, 128), help="set the camera's f-number first")
    g.add_argument("--settle", type=number(0.0, 5.0, unit=" s"), default=SETTLE_S,
                   help=f"seconds between light on and shutter ({SETTLE_S:g})")
    p.add_argument("--json", metavar="PATH", dest="json_path", help=JSON_HELP)


def check_device_options(args: argparse.Namespace) -> None:
    """What the device options must say, answered before anything heavy is imported: the virtual lab, or the
    sphere's port AND the camera (``ValueError``, one line)."""
    if getattr(args, "virtual_lab", False):
        given = [f"--{o} {getattr(args, o)}" for o in ("port", "camera", "stand") if getattr(args, o, None)]
        if given:
            raise ValueError(f"{' and '.join(given)} with --virtual-lab: the virtual lab brings its own sphere, "
                             "camera and sample changer; drop one or the other")
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
    lab_only = []
    for name, default in LAB_ONLY_DEFAULTS.items():
        value = getattr(args, name, None)
        shown = "{}x{}".format(*value) if name == "frame_size" and value is not None else value
        if value is not None and shown != default:
            lab_only.append(f"--{name.replace('_', '-')} {shown}")
    if lab_only:
        it = "them" if len(lab_only) > 1 else "it"
        raise ValueError(f"{' and '.join(lab_only)} without --virtual-lab: only the virtual lab takes {it} (a "
                         f"lab of your own: `dualrgb lab serve` with {it}); drop {it} or use --virtual-lab")


def check_camera_request(args: argparse.Namespace, folder: Path | None, profile: Any = None) -> None:
    """``--iso`` / ``--aperture`` against what the session in ``folder`` was shot with and what ``profile`` (a
    capture's calibration, unless ``--force``) was made at, answered before a device opens: the camera is set only
    for a run that will be accepted, so a refused run leaves it as it was and the corrected run is not refused for
    a setting the refused one made (ValueError, one line)."""
    asked = {"iso": getattr(args, "iso", None), "aperture": getattr(args, "aperture", None)}
    if all(v is None for v in asked.values()):
        return
    from dualrgb.app.workflow.stand.folders import stored_definition

    known = []
    if folder is not None:
        known.append((f"session {folder} was shot", dict(stored_definition(Path(folder)).get("camera") or {}), ""))
    if profile is not None:
        known.append((f"calibration {profile.id} was made", vars(profile.camera), ", or --force"))
    for key, flag, unit in (("iso", "--iso", "ISO "), ("aperture", "--aperture", "f/")):
        for what, camera, force in known:
            value, have = asked[key], camera.get(key)
            if value is not None and have not in (None, "") and abs(float(have) - float(value)) > 1e-6:
                raise ValueError(f"{flag} {value:g}: {what} at {unit}{float(have):g}; nothing was set on the camera: "
                                 f"leave {flag} out, give {flag} {float(have):g}{force}, or use another --session")


def add_reuse_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--force", action="store_true", help="use a calibration that does not match, with a warning")
    p.add_argument("--max-age-h", type=number(0.0, 8760), default=8.0, help="warn when the calibration is older (8 h)")
    p.add_argument("--max-temperature-drift", type=number(0.0, 100), default=5.0,
                   help="refuse when the sphere is this many C from the calibration's temperature (5)")


def progress_printer(clock: RunClock | None = None) -> Callable[[float, str], None]:
    """Progress lines on stderr ('[ 88%] report: figure 3 of 11, ...'); with a ``clock``
    (app.workflow.phase_costs) each line ends with the time left from the measured phase costs."""
    last: list[str | None] = [None]

    def progress(f: float, msg: str) -> None:
        line = f"[{int(100 * f):3d}%] {msg}"
        if line == last[0]:
            return
        last[0] = line
        left = clock.time_left(f) if clock is not None else None
        print(line + (f" (time left {format_duration(left)})" if left is not None and f < 1.0 else ""),
              file=sys.stderr, flush=True)
    return progress


@contextlib.contextmanager
def timed(clock: RunClock) -> Iterator[RunClock]:
    """A CLI run timed by ``clock``: begun here, its phases recorded when it ends (all of them when it is done)."""
    clock.begin()
    outcome = "failed"
    try:
        yield clock
        outcome = "done"
    except (KeyboardInterrupt, Cancelled):
        outcome = "cancelled"
        raise
    finally:
        clock.finish(outcome)


def ask_person(message: str) -> None:
    """A prompt from a sequence: say it and wait for Enter (a terminal is needed)."""
    if not sys.stdin or not sys.stdin.isatty():
        raise ValueError(f"{message}: needs a person at the stand (run in a terminal), or a sample changer (--stand, "
                         "or --virtual-lab)")
    print(f">>> {message} (Enter)", file=sys.stderr, flush=True)
    sys.stdin.readline()


@dataclass
class Devices:
    camera: Camera
    sphere: Sphere
    stand: Stand | None                   # what places things: the sample changer's (None: a person, prompted)
    changer: SampleChanger | None = None


@contextlib.contextmanager
def open_devices(args: argparse.Namespace, mode: str = DEFAULT_MODE, original: str | None = None,
                 charts: dict | None = None) -> Iterator[Devices]:
    """The sphere, the camera and the sample changer by their addresses (app.workflow.stand.stand_devices, shared with
    the GUI); with ``--virtual-lab`` first the lab's (app.lab.process: started here, stopped at the end). LEDs off
    and ports closed on the way out, whatever happens.

    The virtual lab shows an original as ``original`` (``--virtual-original``: a virtual original's name, or a
    chart: 'test', 'test+nd' with the ND 2.0 filter over half) and holds ``charts`` (the stand's own, as
    app.workflow.calibration.charts.ChartChoice per role) on its stand."""
    if args.virtual_lab:
        with lab_addresses(args, mode, original, charts) as addresses:
            yield from _real_devices(argparse.Namespace(**{**vars(args), **addresses}))
        return
    check_device_options(args)
    yield from _real_devices(args)


@contextlib.contextmanager
def lab_addresses(args: argparse.Namespace, mode: str, original: str | None = None,
                  charts: dict | None = None) -> Iterator[dict[str, str]]:
    """``{"port", "camera", "stand"}``: the addresses of a virtual lab started for this command (`dualrgb lab
    serve` as a child process), stopped on the way out."""
    from dualrgb.app.lab.process import LabOptions, LabProcess

    given = {role: (c.file, c.layout, c.leave_out) for role, c in (charts or {}).items() if c.given}
    options = LabOptions(mode=mode, frame_size=args.frame_size, seed=args.seed, world=args.world,
                         stand_in=original or "", charts=given,
                         verbose=int(getattr(args, "verbose", 0) or 0))
    with LabProcess(options) as lab:
        found = lab.addresses
        yield {"port": found["sphere"], "camera": found["camera"], "stand": found["stand"]}


@contextlib.contextmanager
def real_camera(args: argparse.Namespace) -> Iterator[Camera]:
    """The tethered camera ``args.camera`` ('MODEL @ PORT' or 'auto': the first found), ISO / aperture applied
    (app.workflow.stand.stand_devices.open_camera, as the GUI opens it)."""
    from dualrgb.app.workflow.stand.stand_devices import close_camera, open_camera

    camera = open_camera(args.camera, args.iso, args.aperture)
    try:
        yield camera
    finally:
        close_camera(camera)


def _real_devices(args: argparse.Namespace) -> Iterator[Devices]:
    """The sphere on ``--port`` (identified and switched off first: app.workflow.stand.stand_devices.open_sphere) and
    the camera; whatever fails, the light is switched off on the way out (close_sphere) and the error carries a
    note saying what state it is in (read back, never assumed)."""
    from dualrgb.app.workflow.stand.stand_devices import close_sphere, open_sphere
    from dualrgb.drivers.led_sphere import SphereError

    sphere = open_sphere(args.port)
    try:
        with real_camera(args) as camera, _changer(getattr(args, "stand", None)) as changer:
            yield Devices(camera, sphere, changer.place if changer is not None else None, changer)
    except BaseException as exc:
        report = close_sphere(sphere)
        if not (isinstance(exc, SphereError) and exc.light is not None) and (
                not report.off or not _says_light_off(exc)):
            exc.add_note(report.message)
        raise
    report = close_sphere(sphere)           # every LED 0, light off, read back
    if not report.off:
        raise SphereError(f"closing the devices: {report.message}", kind="unconfirmed", light="unknown")


@contextlib.contextmanager
def _changer(port: str | None) -> Iterator[SampleChanger | None]:
    from dualrgb.app.workflow.stand.stand_devices import open_changer

    if not port:
        yield None
        return
    changer = open_changer(port)
    with contextlib.closing(changer):
        yield changer


def _says_light_off(exc: BaseException) -> bool:
    """Whether an error already says the light was switched off (core.light_safety.restate: in its message, or in
    a note it added to an error of another type)."""
    return any("switched off" in text for text in (str(exc), *getattr(exc, "__notes__", ())))


def add_session_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--session", type=Path, default=None,
                   help="session folder (created, or resumed); default: a new dated one such as 2026-11-24_1 in "
                        "the captures folder (<per-user data folder>/captures)")


def open_session(folder: Path | None, definition: dict, camera: Camera, meta: dict | None = None) -> CaptureSession:
    """The session in ``folder``: new, or resumed when it was made with the same ``definition`` and camera
    (app.workflow.stand.folders.open_session; anything else is refused in one line naming the difference). No
    ``folder``: a new dated session in the captures folder, named on stderr."""
    from dualrgb.app.workflow.stand.folders import open_session as open_or_make

    session = open_or_make(folder, definition, camera, meta,
                           hint="use the same options and camera, or another --session")
    if folder is None:
        print(f"dualrgb: new session {session.path}", file=sys.stderr, flush=True)
    return session


@contextlib.contextmanager
def session_of_run(folder: Path | None, definition: dict, camera: Camera,
                   meta: dict | None = None) -> Iterator[CaptureSession]:
    """:func:`open_session` for a run whose checks before the light have passed, with its ``session.log`` (every
    dualrgb record of the run, core.session.log) and, should the run still be refused before its first frame, the
    folder put back as it was (app.workflow.stand.run_gate.undone_if_refused)."""
    from dualrgb.app.workflow.stand.run_gate import undone_if_refused
    from dualrgb.core.session.log import SessionLog

    with undone_if_refused(folder), open_session(folder, definition, camera, meta) as session, \
            SessionLog(session.path):
        yield session


def said_redelivery(session: CaptureSession, original: Any, reshoot: bool) -> None:
    """One line when ``original`` is already in the session: delivered again from its frames, or (``--reshoot``)
    shot again; never silently."""
    from dualrgb.app.workflow.stand.copystand import original_takes

    takes = original_takes(session, original)
    if not takes:
        return
    if reshoot:
        print(f"{original.identifier}: already in the session (take {max(takes)}): shooting it again (--reshoot); "
              "its previous deliverables move to previous/", file=sys.stderr, flush=True)
    else:
        print(f"{original.identifier}: already in the session (take {max(takes)}): delivering it again from its "
              "frames, the previous deliverables moved to previous/; --reshoot shoots it again",
              file=sys.stderr, flush=True)


def reuse_limits(args: argparse.Namespace) -> Any:
    from dualrgb.app.workflow.calibration.profile import ReuseLimits

    return ReuseLimits(temperature_drift_c=args.max_temperature_drift, max_age_h=args.max_age_h)
