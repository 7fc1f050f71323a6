"""``dualrgb cube DELIVERY``: a delivery's spectral cube (ENVI) made from its camera-RGB TIFFs through the map its
sidecar states, and with ``--render LIGHT`` its rendering under that light (app.workflow.delivery.spectral_on_demand).

    dualrgb cube SESSION/deliverables/ACC-1 [--out DIR] [--render A]

A full-resolution delivery states its cube instead of writing it (1.86 GB at 24 MP); this makes it, band by band.
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

from dualrgb.app.commands.options import render_illuminant
from dualrgb.app.json_output import add_json_option, write_json

log = logging.getLogger(__name__)

FORMAT = "dualrgb-cube/1"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("cube", help="make a delivery's spectral cube (and rendering) from its channel TIFFs",
                       description="Writes <id>_spectral.img/.hdr (ENVI, BIL, 16-bit x 10000) computed from the "
                                   "delivery's camera-RGB TIFFs through the spectral map in its sidecar.")
    p.add_argument("delivery", type=Path, help="a delivery's folder or its sidecar (<id>.json)")
    p.add_argument("--out", type=Path, help="where to write (default: the delivery's folder)")
    p.add_argument("--render", type=render_illuminant, metavar="LIGHT",
                   help="also the rendering under LIGHT (<id>_under_<LIGHT>_prophoto_16bit.tif)")
    add_json_option(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.terminal_progress import TerminalProgress
    from dualrgb.app.warm_kernels import ensure_ready
    from dualrgb.app.workflow.delivery.spectral_on_demand import make_cube

    ensure_ready()                                      # first run: compiled once here, said in one line
    with TerminalProgress("cube") as progress:
        made = make_cube(args.delivery, args.out, args.render, progress=progress)
    files = {"cube": str(made.cube), "header": str(made.header), **({"render": str(made.render)} if made.render
                                                                         else {})}
    if args.json != "-":
        for key, path in files.items():
            print(f"{key}: {path}")
    if args.json:
        write_json(args.json, FORMAT, {"files": files, "lines": made.shape[0], "samples": made.shape[1]})
    return 0
