"""``dualrgb report SESSION``: the session's QA report, one HTML page (app.workflow.delivery.session_report): per
original a
thumbnail, identifier, QA line and grades; per calibration its figures and FADGI / ISO 19264 / Metamorfoze grading.

    dualrgb report SESSION [--out FILE] [--json J]

Every delivery is verified against its sidecar first; one that does not match shows its problems instead of a
thumbnail, and the command ends with exit 1 after writing the page.
"""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from dualrgb.app.json_output import add_json_option, write_json

log = logging.getLogger(__name__)

FORMAT = "dualrgb-report/1"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("report", help="write a session's QA report (one HTML page)",
                       description="Writes SESSION/report.html: a thumbnail, identifier, QA line and grades per "
                                   "original, and the calibrations' figures and grading.")
    p.add_argument("session", type=Path, help="a session folder (or a deliverables folder)")
    p.add_argument("--out", type=Path, help="the page's file (default SESSION/report.html)")
    add_json_option(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.workflow.delivery.session_report import write_report

    path, rows = write_report(args.session, args.out)
    bad = [r for r in rows if r.problems]
    if args.json != "-":
        print(f"{path}: {len(rows)} original(s), {len(bad)} with problems")
    for r in bad:
        print(f"{r.identifier}: {r.problems[0]}", file=sys.stderr)
    if args.json:
        write_json(args.json, FORMAT, {"report": str(path), "originals": [
            {"identifier": r.identifier, "qa": r.qa, "grades": r.grades, "problems": r.problems} for r in rows]})
    return 1 if bad else 0
