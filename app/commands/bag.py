"""``dualrgb bag SOURCE --out BAG``: the current deliveries under SOURCE (a deliverables folder or a session) as a
BagIt bag for the transfer to the archive (app.workflow.bagging: the Library of Congress' bagit, SHA-256
manifest checked against the sidecars; every delivery verified first).

    dualrgb bag SESSION/deliverables --out /transfer/2026-03-14 [--organization "..."] [--info Key=Value] [--copy]
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

from dualrgb.app.commands.options import key_value
from dualrgb.app.json_output import add_json_option, write_json

log = logging.getLogger(__name__)

FORMAT = "dualrgb-bag/1"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bag", help="package a day's deliverables as a BagIt bag for the archive",
                       description="Verifies every current delivery under SOURCE against its sidecar, then makes a "
                                   "BagIt bag of them (data/<original>/..., SHA-256 manifest) in the new folder OUT.")
    p.add_argument("source", type=Path, help="a deliverables folder or a session")
    p.add_argument("--out", type=Path, required=True, help="the bag's folder (new, or empty)")
    p.add_argument("--organization", help="bag-info Source-Organization")
    p.add_argument("--info", type=key_value, action="append", default=[], metavar="KEY=VALUE",
                   help="another bag-info field, e.g. --info Contact-Name='J. Doe' (repeatable)")
    p.add_argument("--copy", action="store_true", help="copy the files (default: hard links where possible)")
    add_json_option(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.workflow.bagging import make_day_bag

    info = dict(args.info)
    if args.organization:
        info["Source-Organization"] = args.organization
    bag = make_day_bag(args.source, args.out, info=info, copy=args.copy)
    if args.json != "-":
        print(bag.summary())
    if args.json:
        write_json(args.json, FORMAT, {"bag": str(bag.path), "originals": bag.originals, "files": bag.files,
                                       "bytes": bag.bytes})
    return 0
