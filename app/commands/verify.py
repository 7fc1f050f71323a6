"""``dualrgb verify DELIVERY_OR_SESSION``: check delivered files against the size and SHA-256 their sidecars
recorded when they were written (app.workflow.delivery.fixity).

    dualrgb verify SESSION/deliverables/ACC-1       one delivery (or its sidecar)
    dualrgb verify SESSION                          every delivery of a session, previous sets included

One line per problem (a missing file, another size, another digest, a file the sidecar does not list, a delivery
without recorded fixity), a ``note:`` line per file another program left beside a delivery (GDAL's
``.aux.xml``, ``.DS_Store``, ``Thumbs.db``: named as such, not a problem), then a summary; exit 1 on any problem,
0 when every file matches.
"""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from dualrgb.app.json_output import add_json_option, write_json

log = logging.getLogger(__name__)

FORMAT = "dualrgb-verify/1"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("verify", help="check delivered files against their sidecars' checksums",
                       description="Reads every file of each delivery under PATH again and compares its size and "
                                   "SHA-256 with its sidecar's: one line per problem, exit 1 on any.")
    p.add_argument("path", type=Path, help="a delivery's folder or sidecar, a deliverables folder, or a session")
    add_json_option(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.workflow.delivery.fixity import verify

    report = verify(args.path)
    quiet = args.json == "-"
    out = sys.stderr if quiet else sys.stdout
    for line in report.problems:
        print(line, file=out)
    for line in report.notes():
        print(f"note: {line}", file=out)
    print(report.summary(), file=out)
    if args.json:
        write_json(args.json, FORMAT, report.to_dict())
    return 0 if report.ok else 1
