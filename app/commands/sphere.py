"""``dualrgb sphere``: talk to the LED sphere over serial; ``dualrgb sphere-emulator``: serve a virtual one on a pty.

    dualrgb sphere --port /dev/ttyACM0 identify
    dualrgb sphere --port /dev/ttyACM0 status [--json PATH]
    dualrgb sphere --port /dev/ttyACM0 set 4 0.5
    dualrgb sphere --port /dev/ttyACM0 apply preset.json [--source 2]
    dualrgb sphere --port /dev/ttyACM0 on
    dualrgb sphere --port /dev/ttyACM0 off
    dualrgb sphere-emulator [--watchdog 30]      # prints the pty path to use as --port

Each call opens the port, does its exchange(s), prints the result and closes the port (levels and the light
switch stay as set: the sphere's watchdog switches everything off after its timeout without requests). When a
call fails after the port is open, it switches every LED and the light off before reporting one line and exit 1.
"""
from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Optional

from app.cli import UserError
from app.commands.options import positive, seconds
from app.json_output import add_json_option, write_json

if TYPE_CHECKING:       # the driver imports pyserial and numpy: only when a command talks to the sphere
    from drivers.led_sphere import LedSphere
    from simulation.lightsource import LightSource

log = logging.getLogger(__name__)

PORT_ENV = "DUALRGB_SPHERE_PORT"
STATUS_FORMAT = "dualrgb-sphere-status/1"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sphere", help="LED sphere: identify, status, set a level, apply a preset, on, off",
                       description="Talk to the 10-LED sphere over its serial port (docs/led-sphere-protocol.md).")
    p.add_argument("--port", default=os.environ.get(PORT_ENV),
                   help=f"serial port or pyserial URL, e.g. /dev/ttyACM0, a pty path (default ${PORT_ENV})")
    p.add_argument("--timeout", type=seconds(0.01, 60), default=None,
                   help="seconds to wait for each reply, 0.01..60 (default: the driver's, 1 s; one retry)")
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    actions.required = True
    actions.add_parser("identify", help="model, firmware, serial number")
    st = actions.add_parser("status", help="light, levels, temperature, on-time, watchdog, faults")
    add_json_option(st)
    s = actions.add_parser("set", help="one LED's level (0..1)")
    s.add_argument("led", type=int, help="LED number 1..10")
    s.add_argument("level", type=float, help="level 0..1")
    a = actions.add_parser("apply", help="a preset's light source (LEDs not in it to 0)")
    a.add_argument("preset", type=Path, help="preset JSON (dualrgb simulate --preset-out)")
    a.add_argument("--source", type=positive, default=1, help="which light source of the preset: 1 (default) or 2")
    actions.add_parser("on", help="light on (master switch)")
    actions.add_parser("off", help="every LED to 0 and the light off")
    p.set_defaults(func=main)

    e = sub.add_parser("sphere-emulator", help="serve a virtual LED sphere on a pseudo-terminal until Ctrl-C",
                       description="Start the LED sphere emulator on a pty and print its path (use it as --port).")
    e.add_argument("--watchdog", type=seconds(0.1, 3600), default=30.0, help="watchdog seconds, 0.1..3600 (default 30)")
    e.set_defaults(func=serve_emulator)


def load_light_source(path: Path, index: int) -> "LightSource":
    """Light source number ``index`` (1-based) of a preset file."""
    from simulation.presets import load_preset

    sources = load_preset(path).sources           # PresetError is a ValueError: one line naming the file
    if not 1 <= index <= len(sources):
        raise UserError(f"--source {index}: {path} has light sources 1..{len(sources)}")
    return sources[index - 1]


def main(args: argparse.Namespace) -> int:
    if not args.port:
        raise UserError(f"no sphere port: give --port (e.g. /dev/ttyACM0) or set {PORT_ENV}")
    from drivers.led_sphere import LedSphere, SphereError
    from drivers.led_sphere.driver import DEFAULT_TIMEOUT_S

    light = load_light_source(args.preset, args.source) if args.action == "apply" else None
    timeout = DEFAULT_TIMEOUT_S if args.timeout is None else args.timeout
    try:
        sphere = LedSphere(args.port, timeout=timeout).open()
    except SphereError as exc:
        raise UserError(str(exc)) from None
    try:
        _run(sphere, args, light)
    except SphereError as exc:
        try:
            sphere.shutdown()
        except SphereError as off_exc:
            log.info("switching the sphere off after the error failed: %s", off_exc)
            raise UserError(f"{exc}; switching the LEDs off failed too (the sphere's watchdog switches them off "
                            "after its timeout)") from None
        raise UserError(f"{exc} (all LEDs and the light were switched off)") from None
    finally:
        sphere.close(leave_on=True)         # levels and light stay as set; on failure shutdown() was just tried
    return 0


def _run(sphere: "LedSphere", args: argparse.Namespace, light: Optional["LightSource"]) -> None:
    if args.action == "identify":
        info = sphere.identify()
        print(f"model {info['model']}, firmware {info['firmware']}, serial {info['serial']}")
    elif args.action == "status":
        status = sphere.status()
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
    elif args.action == "set":
        taken = sphere.set_level(args.led, args.level)
        print(f"LED {args.led} level {taken:.4f}")
    elif args.action == "apply":
        taken = sphere.apply(light)
        levels = " ".join(f"{v:.4f}" for v in taken)
        print(f"applied {light.name or 'light source'} {light.label()}: levels {levels}")
    elif args.action == "on":
        sphere.on()
        print("light on")
    elif args.action == "off":
        sphere.shutdown()
        print("all LEDs off, light off")


def serve_emulator(args: argparse.Namespace) -> int:
    from drivers.virtual.sphere_emulator import SphereEmulator

    try:
        emulator = SphereEmulator(watchdog_s=args.watchdog)
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
        print("dualrgb: the sphere emulator's pty closed", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 0
    finally:
        emulator.stop()
        if in_main:
            signal.signal(signal.SIGTERM, previous)
