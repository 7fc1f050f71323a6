"""``dualrgb capture``: one original, or a day's queue from a CSV, with a saved calibration, to the deliverables.

    dualrgb capture [--session DIR] --calibration FILE --id ACC-123 [--title ..] [--operator ..] [--notes ..]
                    [--mode reflective|transmissive] [--reshoot] [--force] [--render-illuminant A]
                    [--resolution full|half]
                    (--virtual-lab | --port P --camera C)
    dualrgb capture --session DIR --calibration FILE --queue originals.csv [--column identifier="Accession No."]
                    [--skip-invalid] [--operator ..] [--reshoot] ...

Every original's metadata and deliverables folder are checked before a device opens (app.workflow.metadata,
app.workflow.delivery_folder); a queue's bad rows are listed one per line and nothing is shot while one is bad,
unless ``--skip-invalid``. An original of the queue already delivered in the session is kept and said so.
"""
from __future__ import annotations

import argparse
import logging
import sys
from dataclasses import replace
from pathlib import Path

from dualrgb.app.commands.options import (
    add_render_option,
    add_resolution_option,
    column_option,
    count,
    input_file,
    number,
)
from dualrgb.app.commands.stand_options import (
    add_device_options,
    add_reuse_options,
    add_session_option,
    ask_person,
    open_devices,
    open_session,
    progress_printer,
    reuse_limits,
    virtual_world,
    write_json,
)
from dualrgb.app.workflow.defaults import MODES, VIRTUAL_ORIGINALS

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("capture", help="capture one original with a saved calibration and deliver it",
                       description="Checks the calibration against the stand (camera serial, ISO, aperture, lights, "
                                   "sphere temperature, age), meters the original, captures it (an HDR bracket "
                                   "only when metering asks) and writes its deliverables.")
    add_session_option(p)
    p.add_argument("--calibration", type=input_file, required=True, help="calibration profile (.json)")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--id", dest="identifier", help="identifier / accession number (names the files)")
    what.add_argument("--queue", type=input_file, metavar="CSV",
                      help="a day's originals from the collection database: a UTF-8 CSV with a header naming the "
                           "columns identifier, title, operator, notes, mode (others kept as extra metadata); "
                           "every row is checked before anything is shot")
    p.add_argument("--column", type=column_option, action="append", default=[], metavar="FIELD=NAME",
                   help="--queue: the CSV column holding FIELD, e.g. --column identifier='Accession No.'")
    p.add_argument("--skip-invalid", action="store_true",
                   help="--queue: list the bad rows and shoot the others (default: shoot nothing while one is bad)")
    p.add_argument("--title", default="")
    p.add_argument("--operator", default="", help="with --queue: for the rows that name none")
    p.add_argument("--notes", default="")
    p.add_argument("--mode", choices=MODES, default=None,
                   help="default: the calibration's (with --queue: for the rows that name none)")
    p.add_argument("--reshoot", action="store_true",
                   help="shoot again an original already in the session (with --queue: every row)")
    p.add_argument("--out", type=Path, help="deliverables folder (default <session>/deliverables)")
    p.add_argument("--ppi", type=number(above=0.0), help="sampling of the deliverables (default: the calibration's)")
    p.add_argument("--frames", type=count(1, 100), default=1,
                   help="frames averaged per exposure (noise / sqrt(N), light dose x N; default 1)")
    p.add_argument("--virtual-original", default=None,
                   help="virtual lab: which virtual original stands in (default by mode: "
                        + ", ".join(f"{m}: {o}" for m, o in VIRTUAL_ORIGINALS.items()) + ")")
    add_render_option(p)
    add_resolution_option(p)
    add_reuse_options(p)
    add_device_options(p)
    p.set_defaults(func=main)


def _originals(args: argparse.Namespace, mode: str, out_dir: Path | None) -> tuple[list, list[str]]:
    """The originals to shoot, every one checked before a device opens, and the queue's bad-row lines
    (``out_dir`` None: the deliverables folder of a session not made yet, which holds nothing to check)."""
    from dualrgb.app.workflow.delivery_folder import check_folder
    from dualrgb.app.workflow.metadata import Original
    from dualrgb.app.workflow.queue_csv import read_queue_csv

    if not args.queue:
        original = Original(args.identifier, args.title, args.operator, args.notes, mode)
        if out_dir is not None:
            check_folder(out_dir, original)
        return [original], []
    if args.title or args.notes:
        raise ValueError("--title and --notes name one original (--id); a queue's come from its CSV")
    queue = read_queue_csv(Path(args.queue), columns=dict(args.column), default_mode=mode, out_dir=out_dir)
    bad = queue.bad_lines()
    for line in bad:
        print(f"{Path(args.queue).name}: {line}", file=sys.stderr)
    if bad and not args.skip_invalid:
        raise ValueError(f"{args.queue}: {len(bad)} bad row{'s' if len(bad) > 1 else ''} (listed above); nothing "
                         f"was shot: fix them, or --skip-invalid to shoot the other {len(queue.entries)}")
    if not queue.entries:
        raise ValueError(f"{args.queue}: no original to shoot")
    if bad:
        print(f"skipped {len(bad)} bad row{'s' if len(bad) > 1 else ''}: {', '.join(map(str, queue.bad_rows))}",
              file=sys.stderr)
    fill = {"operator": args.operator} if args.operator else {}
    return [replace(o, **fill) if fill and not o.operator else o for o in queue.originals], bad


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.workflow.copystand import CopyStand, QueueOutcome, StandSettings, capture_queue
    from dualrgb.app.workflow.profile import load_profile

    profile = load_profile(args.calibration)
    out_dir = Path(args.out) if args.out else args.session / "deliverables" if args.session else None
    originals, bad = _originals(args, args.mode or profile.mode, out_dir)      # refused here: nothing is open yet
    settings = StandSettings(settle_s=args.settle, limits=reuse_limits(args), force=args.force, ppi=args.ppi,
                             original_frames=args.frames, render_illuminant=args.render_illuminant,
                             resolution=args.resolution)
    with open_devices(args, args.mode or profile.mode, args.virtual_original) as dev, \
            open_session(args.session, {"workflow": "originals", **virtual_world(args)}, dev.camera) as session:
        out_dir = out_dir or session.path / "deliverables"
        stand = CopyStand(dev.camera, dev.sphere, session, stand=dev.stand, lab=dev.lab, settings=settings,
                          progress=progress_printer(), prompt=ask_person, reshoot=lambda _o, _n: args.reshoot)
        if not args.queue:                  # one original: shot, or its frames kept and delivered again
            result = stand.capture(originals[0], profile, reshoot=args.reshoot, out_dir=out_dir)
            _print_outcome(QueueOutcome(originals[0], report=result))
            return _single_json(args, result, profile)
        outcomes = capture_queue(stand, originals, profile, reshoot=args.reshoot, out_dir=out_dir,
                                 on_outcome=_print_outcome)
    write_json(args.json_path, {"queue": str(args.queue), "calibration": profile.id, "bad_rows": bad,
                                "originals": [_outcome_json(o) for o in outcomes]})
    return 0


def _print_outcome(outcome) -> None:
    result = outcome.report
    if result is None:
        print(outcome.summary())
        return
    for w in result.check.warnings + result.warnings:
        print(f"warning: {w}")
    print(result.summary())
    for key, path in result.delivery.files.items():
        print(f"  {key}: {path}")
    print(f"  sidecar: {result.delivery.sidecar}")


def _outcome_json(outcome) -> dict:
    r = outcome.report
    if r is None:
        return {"original": outcome.original.to_dict(), "state": "kept", "sidecar": str(outcome.kept)}
    return {"original": outcome.original.to_dict(), "state": "delivered", "new": r.new, "kept": r.kept,
            "qa": r.delivery.qa.to_dict(), "files": {k: str(v) for k, v in r.delivery.files.items()},
            "sidecar": str(r.delivery.sidecar)}


def _single_json(args: argparse.Namespace, result, profile) -> int:
    write_json(args.json_path, {"original": result.original.to_dict(), "new": result.new, "kept": result.kept,
                                "exposures": result.exposures, "qa": result.delivery.qa.to_dict(),
                                "files": {k: str(v) for k, v in result.delivery.files.items()},
                                "sidecar": str(result.delivery.sidecar), "calibration": profile.id,
                                "calibration_age_h": round(result.check.age_h, 3)})
    return 0
