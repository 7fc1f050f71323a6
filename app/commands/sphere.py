"""``dualrgb sphere``: talk to the LED sphere over serial; ``dualrgb sphere-emulator``: serve a virtual one.

    dualrgb sphere --port /dev/ttyACM0 identify
    dualrgb sphere --port /dev/ttyACM0 status [--json PATH]
    dualrgb sphere --port /dev/ttyACM0 set 4 0.5
    dualrgb sphere --port /dev/ttyACM0 apply preset.json [--source 2]
    dualrgb sphere --port /dev/ttyACM0 on [--max-on 10]
    dualrgb sphere --port /dev/ttyACM0 off
    dualrgb sphere-emulator [--watchdog 30] [--transport pty|socket]   # prints the port to use as --port

Each call opens the port, does its exchange(s), prints the result and closes the port (levels and the light
switch stay as set; a light switched on goes off by itself after ``--max-on`` seconds, default 10). Every option
is checked while the command line is parsed (app.commands.options); when one is wrong, or a call fails, the port
(if one is given) is opened and every LED and the light are switched off, and the error line says what went wrong
and, truthfully, what state the light is in (exit 2 for a wrong option, 1 otherwise).
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from dualrgb.app.cli import UserError
from dualrgb.app.commands.options import count, number, positive, seconds
from dualrgb.app.json_output import add_json_option, write_json
from dualrgb.drivers.led_sphere.limits import DEFAULT_MAX_ON_S, DEFAULT_TIMEOUT_S, MAX_ON_RANGE_S
from dualrgb.simulation.choices import N_SPHERE_LEDS

if TYPE_CHECKING:       # the driver imports pyserial and numpy: only when a command talks to the sphere
    from dualrgb.drivers.led_sphere import LedSphere
    from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)

PORT_ENV = "DUALRGB_SPHERE_PORT"
STATUS_FORMAT = "dualrgb-sphere-status/1"
LIT_FORMAT = "dualrgb-sphere-lit/1"         # <data>/sphere/<port>.json: the limit `sphere on` sent


class _SphereParser(argparse.ArgumentParser):
    """The ``sphere`` command's parsers: a wrong option still ends with the light off when a port is given.

    argparse refuses a wrong option (a bad LED number, level, --timeout ...) before the command runs; the sphere
    may be lit from an earlier call, so the refusal first opens the port (default timeout), switches every LED
    and the light off and adds what happened to argparse's one error line (exit 2)."""

    root: _SphereParser | None = None     # the 'sphere' parser, which saw --port
    port: str | None = None

    def parse_known_args(self, args=None, namespace=None):
        if self.root is None and args is not None:
            self.port = _port_in(list(args)) or os.environ.get(PORT_ENV)
        return super().parse_known_args(args, namespace)

    def error(self, message: str):
        port = (self.root or self).port
        if port:
            message = f"{message}; {switch_off_after_refusal(port)}"
        super().error(message)


def _port_in(args: list[str]) -> str | None:
    for i, arg in enumerate(args):
        if arg == "--port" and i + 1 < len(args):
            return args[i + 1]
        if arg.startswith("--port="):
            return arg.split("=", 1)[1]
    return None


def switch_off_after_refusal(port: str) -> str:
    """Open ``port``, switch every LED and the light off, close it; what happened, in words."""
    from dualrgb.drivers.led_sphere import LedSphere, SphereError

    try:
        sphere = LedSphere(port, timeout=DEFAULT_TIMEOUT_S).open()
    except SphereError as exc:
        return f"the light could not be switched off: {exc}"
    try:
        return sphere.ensure_off().message
    finally:
        sphere.close(leave_on=True)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sphere", help="LED sphere: identify, status, set a level, apply a preset, on, off",
                       description="Talk to the 10-LED sphere over its serial port (docs/led-sphere-protocol.md).")
    p.__class__ = _SphereParser          # its errors switch the light off (the sub-commands' parsers inherit it)
    p.add_argument("--port", default=os.environ.get(PORT_ENV),
                   help=f"serial port or pyserial URL, e.g. /dev/ttyACM0, a pty path (default ${PORT_ENV})")
    p.add_argument("--timeout", type=seconds(0.01, 60), default=DEFAULT_TIMEOUT_S,
                   help=f"seconds to wait for each reply, 0.01..60 (default {DEFAULT_TIMEOUT_S:g}; one retry)")
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    actions.required = True
    actions.add_parser("identify", help="model, firmware, serial number")
    st = actions.add_parser("status", help="light, levels, temperature, on-time, watchdog, faults")
    add_json_option(st)
    s = actions.add_parser("set", help="one LED's level (0..1)")
    s.add_argument("led", type=count(1, N_SPHERE_LEDS), help=f"LED number 1..{N_SPHERE_LEDS}")
    s.add_argument("level", type=number(0.0, 1.0), help="level 0..1")
    a = actions.add_parser("apply", help="a preset's light source (LEDs not in it to 0)")
    a.add_argument("preset", type=Path, help="preset JSON (dualrgb simulate --preset-out)")
    a.add_argument("--source", type=positive, default=1, help="which light source of the preset: 1 (default) or 2")
    o = actions.add_parser("on", help="light on (master switch) for at most --max-on seconds")
    o.add_argument("--max-on", type=seconds(*MAX_ON_RANGE_S), default=DEFAULT_MAX_ON_S,
                   help=f"seconds until the sphere switches the light off by itself (default {DEFAULT_MAX_ON_S:g}, "
                        f"{MAX_ON_RANGE_S[0]:g}..{MAX_ON_RANGE_S[1]:g})")
    actions.add_parser("off", help="every LED to 0 and the light off")
    for child in actions.choices.values():
        child.root = p
    p.set_defaults(func=main)

    e = sub.add_parser("sphere-emulator", help="serve a virtual LED sphere until Ctrl-C",
                       description="Start the LED sphere emulator and print its port (use it as --port): a "
                                   "pseudo-terminal path on Linux and macOS, socket://127.0.0.1:PORT on Windows.")
    e.add_argument("--watchdog", type=seconds(0.1, 3600), default=30.0, help="watchdog seconds, 0.1..3600 (default 30)")
    e.add_argument("--transport", choices=("pty", "socket"), default=None,
                   help="pty (where the OS has them) or socket (pyserial's socket://, every OS); default: pty where "
                        "there is one, else socket, or $DUALRGB_VIRTUAL_TRANSPORT")
    e.set_defaults(func=serve_emulator)


def load_light_source(path: Path, index: int) -> LightSource:
    """Light source number ``index`` (1-based) of a preset file."""
    from dualrgb.simulation.presets import load_preset

    sources = load_preset(path).sources           # PresetError is a ValueError: one line naming the file
    if not 1 <= index <= len(sources):
        raise UserError(f"--source {index}: {path} has light sources 1..{len(sources)}")
    return sources[index - 1]


def main(args: argparse.Namespace) -> int:
    if not args.port:
        raise UserError(f"no sphere port: give --port (e.g. /dev/ttyACM0) or set {PORT_ENV}")
    from dualrgb.drivers.led_sphere import LedSphere, SphereError

    light, problem = None, None
    if args.action == "apply":
        try:
            light = load_light_source(args.preset, args.source)
        except (UserError, ValueError, OSError) as exc:
            problem = str(exc)
    try:
        sphere = LedSphere(args.port, timeout=args.timeout).open()
    except SphereError as exc:
        raise UserError(f"{problem}; {exc}" if problem else str(exc)) from None
    try:
        if problem is not None:                 # a wrong preset: nothing is set, the light is switched off
            raise UserError(f"{problem}; {sphere.ensure_off().message}")
        _run(sphere, args, light)
    except SphereError as exc:
        if exc.light is not None:               # the driver switched off and its message says how that went
            raise UserError(str(exc)) from None
        raise UserError(f"{exc}; {sphere.ensure_off().message}") from None
    finally:
        sphere.close(leave_on=True)         # levels and light stay as set; on failure ensure_off() was just tried
    return 0


def _run(sphere: LedSphere, args: argparse.Namespace, light: LightSource | None) -> None:
    if args.action == "identify":
        info = sphere.identify()
        print(f"model {info['model']}, firmware {info['firmware']}, serial {info['serial']}")
    elif args.action == "status":
        _status(sphere, args)
    elif args.action == "set":
        taken = sphere.set_level(args.led, args.level)
        print(f"LED {args.led} level {taken:.4f}")
    elif args.action == "apply" and light is not None:        # main() refused a light it could not load
        taken = sphere.apply(light)
        levels = " ".join(f"{v:.4f}" for v in taken)
        print(f"applied {light.name or 'light source'} {light.label()}: levels {levels}")
    elif args.action == "on":
        period = sphere.on(max_on_s=args.max_on)
        _remember_lit(sphere.port, args.max_on if period.device_limit else None)
        if period.device_limit:
            print(f"light on for at most {args.max_on:g} s (the sphere switches it off by itself)")
        else:
            print(f"light on; this firmware has no on-time limit: its watchdog, set to {args.max_on:g} s, switches "
                  "it off that long after the last request")
    elif args.action == "off":
        sphere.shutdown()                   # read back: a sphere that does not confirm it is off is an error
        _remember_lit(sphere.port, None)
        print("all LEDs off, light off (read back)")


def _status(sphere: LedSphere, args: argparse.Namespace) -> None:
    """``status``: the sphere's state, and when a lit period ends at the latest: the limit `sphere on` sent with ON
    when this lit period is the one it started (the sphere's on-time agrees), else the sphere's watchdog."""
    status = sphere.status(adopt=False)         # this command exits: no limit of its own would be held
    limit = _our_limit(sphere.port, status["device_on_time_s"]) if status["light_on"] else None
    if limit is not None:
        status["off_in_s"] = max(0.0, min(limit - status["device_on_time_s"], status["watchdog_s"]))
        status["off_by"], status["max_on_s"] = "limit", limit
    if args.json:
        write_json(args.json, STATUS_FORMAT, status)
        if args.json == "-":
            return
    for key, value in status.items():
        if value is None:
            value = "-"
        elif isinstance(value, float):
            value = f"{value:.3f}"
        elif key == "levels":
            value = " ".join(f"{v:.4f}" for v in value)
        print(f"{key}: {value}")
    if limit is not None:
        print(f"the light goes off by itself in {status['off_in_s']:.1f} s (the {limit:g} s limit `dualrgb sphere "
              "on` sent with ON)")
    elif status["light_on"]:
        print(f"the light goes off at the latest in {status['off_in_s']:.1f} s (the sphere's watchdog, counted from "
              "this request; sooner if whoever switched it on set a shorter limit)")


def _lit_file(port: str) -> Path:
    from dualrgb import resources

    return resources.user_path("sphere", "".join(c if c.isalnum() else "_" for c in port) + ".json")


def _remember_lit(port: str, max_on_s: float | None) -> None:
    """What `sphere on` switched on (the limit the sphere holds), for a later `sphere status`; None: forget it."""
    from dualrgb.common.atomic_files import atomic_write, remove_quietly

    path = _lit_file(port)
    if max_on_s is None:
        remove_quietly(path)
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    from dualrgb.simulation.versions import stamped

    atomic_write(path, json.dumps(stamped(LIT_FORMAT, {"port": port, "max_on_s": max_on_s,
                                                       "switched_on_at": time.time()})))


def _our_limit(port: str, device_on_time_s: float) -> float | None:
    """The limit `sphere on` sent, when the sphere's on-time says this is still that lit period (within 0.5 s)."""
    try:
        doc = json.loads(_lit_file(port).read_text(encoding="utf-8"))
        elapsed, limit = time.time() - float(doc["switched_on_at"]), float(doc["max_on_s"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return limit if doc.get("format") == LIT_FORMAT and abs(elapsed - device_on_time_s) <= 0.5 else None


def serve_emulator(args: argparse.Namespace) -> int:
    from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator
    from dualrgb.drivers.virtual.transport import chosen_transport

    try:
        transport = chosen_transport(args.transport)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    try:
        emulator = SphereEmulator(watchdog_s=args.watchdog, transport=transport)
    except ValueError as exc:
        raise UserError(f"--watchdog {args.watchdog}: {exc}") from None

    def _terminate(signum, frame):  # SIGTERM behaves like Ctrl-C: stop cleanly
        raise KeyboardInterrupt

    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if in_main else None
    try:
        print(emulator.start(), flush=True)
        while emulator.running:
            time.sleep(0.2)
        print("dualrgb: the sphere emulator's port closed", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 0
    finally:
        emulator.stop()
        if in_main:
            signal.signal(signal.SIGTERM, previous)
