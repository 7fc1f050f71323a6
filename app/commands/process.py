"""``dualrgb process``: deliver a session's originals again, e.g. with a newer calibration.

    dualrgb process SESSION [--calibration FILE] [--force] [--out DIR] [--render-illuminant A]
                    [--resolution full|half] [--json J]

The mode rule (app.workflow.mode_rule) as for ``capture``: without ``--calibration`` each original is delivered
with the session's newest calibration of its own mode; with one, originals of the other mode are refused (listed,
exit 1) unless ``--force``. Every original that can be is delivered; those that cannot (a missing or damaged
frame, a folder holding another original's files, a refused QA) are listed one per line, and the command ends
with exit 1 (issue 28).
"""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from dualrgb.app.cli import UserError
from dualrgb.app.commands.options import add_render_option, add_resolution_option, number
from dualrgb.app.commands.stand_options import progress_printer
from dualrgb.app.json_output import add_json_option, text_stream, write_json

log = logging.getLogger(__name__)

PROCESS_FORMAT = "dualrgb-process/1"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("process", help="re-process a session's originals (optionally with another calibration)",
                       description="Delivers every original in SESSION again from its raw frames (latest takes), "
                                   "with --calibration or the session's newest calibration.")
    p.add_argument("session", type=Path)
    p.add_argument("--calibration", type=Path, help="calibration profile (.json); default: the session's newest")
    p.add_argument("--out", type=Path, help="deliverables folder (default <session>/deliverables)")
    p.add_argument("--ppi", type=number(above=0.0), help="sampling of the deliverables (pixels per inch)")
    p.add_argument("--force", action="store_true",
                   help="with --calibration: deliver originals of the other mode with it too (said in the sidecar "
                        "and QA line)")
    add_json_option(p)
    add_render_option(p)
    add_resolution_option(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.workflow.folders import open_session
    from dualrgb.app.workflow.profile import load_profile
    from dualrgb.app.workflow.redelivery import newest_by_mode, redeliver

    session = open_session(args.session, readonly=True)      # frames checked before use, per original
    profiles = load_profile(args.calibration) if args.calibration else newest_by_mode(session)
    refused: list[str] = []
    deliveries, failed = redeliver(session, profiles, args.out or args.session / "deliverables", ppi=args.ppi,
                                   progress=progress_printer(), render_illuminant=args.render_illuminant,
                                   force=args.force, refused=refused, resolution=args.resolution)
    for line in refused:
        print(f"refused: {line}", file=sys.stderr)
    if not deliveries and not refused and not failed:
        raise ValueError(f"{args.session}: no originals to process")
    for d in deliveries:
        print(d.qa.text(), file=text_stream(args.json))
    for f in failed:
        print(f"{f.identifier}: not delivered: {f.reason}", file=sys.stderr)
    used = [profiles] if not isinstance(profiles, dict) else list(profiles.values())
    write_json(args.json, PROCESS_FORMAT, {"calibration": used[0].id if len(used) == 1 else None,
                                           "calibrations": {p.mode: p.id for p in used}, "refused": refused,
                                           "not_delivered": [{"identifier": f.identifier, "reason": f.reason}
                                                             for f in failed],
                                           "originals": [
        {"identifier": d.original.identifier, "qa": d.qa.to_dict(), "files": {k: str(v) for k, v in d.files.items()},
         "sidecar": str(d.sidecar)} for d in deliveries]}, default=str)
    if failed:
        raise UserError(f"{len(failed)} of {len(failed) + len(deliveries)} originals not delivered (listed above: "
                        f"{', '.join(f.identifier for f in failed[:5])}{' ...' if len(failed) > 5 else ''}); the "
                        "others were delivered")
    return 1 if refused else 0
