"""``dualrgb bag SOURCE --out BAG``: the current deliveries under SOURCE (a deliverables folder or a session) as a
BagIt 1.0 bag for the transfer to the archive (app.workflow.delivery.bagging: the Library of Congress' bagit, SHA-256
manifests checked against the sidecars; every delivery verified first; copies, reflinks where offered).

    dualrgb bag SESSION/deliverables --out /transfer/2026-03-14 [--organization "..."] [--info Key=Value] [--link]
"""
from __future__ import annotations

import argparse
import logging
import sys
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
    p.add_argument("--link", action="store_true",
                   help="hard-link the files instead of copying them (default: a copy, a reflink where the file "
                        "system offers one; a hard link shares edits with the session)")
    p.add_argument("--copy", action="store_true", help=argparse.SUPPRESS)     # the default since BagIt 1.0 bags
    p.add_argument("--delivery-settings", type=Path, metavar="FILE",
                   help="the delivery settings whose [bag-info] fields go into bag-info.txt (default <per-user data "
                        "folder>/delivery.toml when it exists)")
    add_json_option(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.workflow.delivery.bagging import make_day_bag
    from dualrgb.app.workflow.delivery.delivery_settings import load

    info = {**load(args.delivery_settings).bag_info, **dict(args.info)}
    if args.organization:
        info["Source-Organization"] = args.organization
    bag = make_day_bag(args.source, args.out, info=info, link=args.link)
    for line in bag.left_out:
        print(line, file=sys.stderr)
    if args.json != "-":
        print(bag.summary())
    if args.json:
        write_json(args.json, FORMAT, {"bag": str(bag.path), "originals": bag.originals, "files": bag.files,
                                       "bytes": bag.bytes, "placed": bag.placed, "left_out": bag.left_out})
    return 0
