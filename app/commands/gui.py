"""``dualrgb gui``: the copy-stand window (PySide6). ``--virtual-lab`` opens it connected to the virtual lab;
``--screenshot DIR`` runs a small session on the virtual lab, saves one PNG per panel and exits."""
from __future__ import annotations

import argparse
from pathlib import Path

from dualrgb.app.commands.options import add_world_option


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("gui", help="the copy-stand window (devices, light, camera, capture, results, simulation)",
                       description="Open the dual-RGB copy-stand window.")
    p.add_argument("--virtual-lab", action="store_true",
                   help="start connected to the virtual lab (sphere emulator + virtual camera), no hardware needed")
    p.add_argument("--screenshot", type=Path, metavar="DIR",
                   help="run a small session on the virtual lab, save one PNG per panel in DIR, then exit")
    add_world_option(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.gui.app import run  # Qt is imported only when the window is really wanted

    return run(virtual_lab=args.virtual_lab or args.screenshot is not None, screenshot_dir=args.screenshot,
               world=args.world)
