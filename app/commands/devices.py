"""``dualrgb devices``: what is plugged in — cameras (gphoto2 and USB), serial ports, and why a camera that is
on USB cannot be used (claimed by gvfs on Linux, ptpcamerad on macOS, or another program)."""
from __future__ import annotations

import argparse
import logging
from typing import TYPE_CHECKING

from dualrgb.app.cli import UserError
from dualrgb.app.commands.options import seconds
from dualrgb.app.json_output import add_json_option, write_json

if TYPE_CHECKING:
    from dualrgb.drivers.usb_discovery import DeviceReport

log = logging.getLogger(__name__)

NOTHING_FOUND = ("no camera and no USB serial port found: connect the camera by USB and switch it on, "
                 "and plug in the LED controller")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("devices", help="list cameras, serial ports and USB problems",
                       description="List attached cameras (libgphoto2 and USB) and serial ports, and say why a "
                                   "camera on USB cannot be used. Exits 1 when nothing is attached.")
    add_json_option(p)
    p.add_argument("--no-probe", action="store_true",
                   help="do not open each camera to check it can be claimed (faster)")
    p.add_argument("--all", action="store_true", help="also list built-in (non-USB) serial ports")
    p.add_argument("--timeout", type=seconds(0.1, 120), default=3.0,
                   help="seconds allowed per probe, 0.1..120 (default 3)")
    p.set_defaults(func=run)


FORMAT = "dualrgb-devices/1"


def format_report(report: DeviceReport, show_all: bool = False) -> str:
    lines = []
    cams = list(report.gphoto_cameras)
    listed = {c.bus_address for c in cams if c.bus_address}
    cams += [c for c in report.usb_cameras if c.bus_address not in listed]
    if cams:
        lines.append("cameras:")
        for c in cams:
            where = c.port or f"usb bus {c.bus} device {c.address}"
            usb_id = f"  [{c.usb_id}]" if c.usb_id else ""
            status = "" if not c.status else ("  ready" if c.status == "ok" else "  NOT USABLE")
            lines.append(f"  {c.model:<24} {where:<14} via {c.source}{usb_id}{status}")
    else:
        lines.append("cameras: none")
    ports = report.serial_ports if show_all else report.usb_serial_ports
    if ports:
        lines.append("serial ports:")
        for p in ports:
            ids = f"  [{p.vendor_id:04x}:{p.product_id:04x}]" if p.is_usb else "  (built-in)"
            desc = p.description or p.manufacturer or ""
            lines.append(f"  {p.device:<16} {desc}{ids}")
    else:
        hidden = len(report.serial_ports) - len(report.usb_serial_ports)
        lines.append("serial ports: no USB serial port" + (f" ({hidden} built-in, --all lists them)" if hidden
                                                             else ""))
    for hint in report.hints:
        lines.append(f"hint: {hint}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from dualrgb.drivers.usb_discovery import discover

    report = discover(probe=not args.no_probe, timeout_s=args.timeout)
    if args.json:
        write_json(args.json, FORMAT, report.to_dict())
        if args.json == "-":
            return 1 if report.nothing_found else 0
    if report.nothing_found:
        raise UserError("; ".join([NOTHING_FOUND, *report.hints]))
    print(format_report(report, show_all=args.all))
    return 0
