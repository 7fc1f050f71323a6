"""``dualrgb process``: deliver a session's originals again, e.g. with a newer calibration.

    dualrgb process SESSION [--calibration FILE] [--out DIR] [--render-illuminant A] [--json J]
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import TYPE_CHECKING

from dualrgb.app.commands.options import add_render_option, number
from dualrgb.app.commands.stand_options import progress_printer, write_json

if TYPE_CHECKING:
    from dualrgb.app.protocols import Session

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("process", help="re-process a session's originals (optionally with another calibration)",
                       description="Delivers every original in SESSION again from its raw frames (latest takes), "
                                   "with --calibration or the session's newest calibration.")
    p.add_argument("session", type=Path)
    p.add_argument("--calibration", type=Path, help="calibration profile (.json); default: the session's newest")
    p.add_argument("--out", type=Path, help="deliverables folder (default <session>/deliverables)")
    p.add_argument("--ppi", type=number(above=0.0), help="sampling of the deliverables (pixels per inch)")
    p.add_argument("--json", type=Path, dest="json_path", help="write a JSON summary here")
    add_render_option(p)
    p.set_defaults(func=main)


def newest_calibration(session: Session) -> Path:
    """The session's own newest calibration, else the one its latest original was captured with."""
    found = sorted((session.path / "calibration").glob("cal-*.json"))
    used = [Path(o["calibration"]) for o in session.settings.get("originals", {}).values() if o.get("calibration")]
    found += [p for p in used if p.exists()]
    if not found:
        raise ValueError(f"{session.path}: no calibration in it or named by its originals; pass --calibration FILE")
    return found[-1]


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.session.capture_session import CaptureSession
    from dualrgb.app.workflow.copystand import redeliver
    from dualrgb.app.workflow.profile import load_profile

    session = CaptureSession.open(args.session, readonly=True)      # frames checked before use (session_frames)
    profile = load_profile(args.calibration or newest_calibration(session))
    deliveries = redeliver(session, profile, args.out or args.session / "deliverables", ppi=args.ppi,
                           progress=progress_printer(), render_illuminant=args.render_illuminant)
    if not deliveries:
        raise ValueError(f"{args.session}: no originals to process")
    for d in deliveries:
        print(d.qa.text())
    write_json(args.json_path, {"calibration": profile.id, "originals": [
        {"identifier": d.original.identifier, "qa": d.qa.to_dict(), "files": {k: str(v) for k, v in d.files.items()},
         "sidecar": str(d.sidecar)} for d in deliveries]})
    return 0
