"""``dualrgb raw-info FILE``: what a raw file holds — format, camera, CFA, black/white levels, mosaic size and
per-channel mean/max — or one line saying why it is not a usable Bayer raw (exit 1)."""
from __future__ import annotations

import argparse
import logging
from typing import TYPE_CHECKING

from dualrgb.app.json_output import add_json_option, write_json

if TYPE_CHECKING:
    from dualrgb.drivers.raw import RawFrame

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("raw-info", help="show what a raw file (NEF/DNG) holds",
                       description="Format, camera, CFA pattern, black/white levels, mosaic size and per-channel "
                                   "statistics of a Bayer raw file.")
    p.add_argument("file", help="raw file (NEF, DNG, ...)")     # drivers.raw checks it is a regular file
    add_json_option(p)
    p.set_defaults(func=run)


FORMAT = "dualrgb-raw-info/1"


def raw_info(frame: RawFrame) -> dict:
    import numpy as np

    channels = {}
    for name, _, idx in frame.channels():
        plane = frame.plane(name)
        channels[name] = {
            "black": int(frame.black_levels[idx]),
            "mean": float(plane.mean(dtype=np.float64)),
            "max": int(plane.max()),
            "clipped_fraction": float(np.count_nonzero(plane >= frame.white_level) / plane.size),
        }
    return {
        "file": str(frame.path), "format": frame.format, "camera": frame.camera, "make": frame.make,
        "model": frame.model, "cfa_pattern": frame.cfa_pattern, "width": frame.width, "height": frame.height,
        "white_level": frame.white_level, "exposure_s": frame.exposure_s, "iso": frame.iso,
        "channels": channels,
    }


def format_info(info: dict) -> str:
    from dualrgb.drivers.camera.gphoto_labels import format_shutter

    shot = []
    if info["exposure_s"]:
        shot.append(format_shutter(info["exposure_s"]))
    if info["iso"]:
        shot.append(f"ISO {info['iso']:g}")
    lines = [
        f"file       {info['file']}",
        f"format     {info['format']}",
        f"camera     {info['camera'] or 'unknown'}",
    ]
    if shot:
        lines.append(f"exposure   {', '.join(shot)}")
    lines += [
        f"CFA        {info['cfa_pattern']}",
        f"mosaic     {info['width']} x {info['height']} px (W x H)",
        f"white      {info['white_level']}",
        f"{'channel':<8} {'black':>6} {'mean':>10} {'max':>7} {'clipped':>9}",
    ]
    for name, c in info["channels"].items():
        lines.append(f"{name:<8} {c['black']:>6} {c['mean']:>10.1f} {c['max']:>7} "
                     f"{100 * c['clipped_fraction']:>8.3f}%")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from dualrgb.drivers.raw import load_raw

    info = raw_info(load_raw(args.file))   # RawFileError is a ValueError: one line, exit 1 (app.cli)
    if args.json:
        write_json(args.json, FORMAT, info)
    if args.json != "-":
        print(format_info(info))
    return 0
