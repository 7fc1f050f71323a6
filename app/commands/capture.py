"""``dualrgb capture``: one original, or a day's queue from a CSV, with a saved calibration, to the deliverables.

    dualrgb capture [--session DIR] [--calibration FILE|DIR] --id ACC-123 [--title ..] [--operator ..] [--notes ..]
                    [--mode reflective|transmissive] [--reshoot] [--force] [--render-illuminant A]
                    [--resolution full|half]
                    (--virtual-lab | --port P --camera C)
    dualrgb capture --session DIR [--calibration FILE|DIR] --queue originals.csv [--column identifier="Accession No."]
                    [--skip-invalid] [--operator ..] [--reshoot] [--check] [--collection NAME] ...

``--calibration`` defaults to the session's newest (of the original's mode with ``--id --mode``): a session made by
``dualrgb calibrate --session DIR`` takes the day's originals. Every original's metadata, mode (the mode rule:
app.workflow.stand.mode_rule) and deliverables folder are checked before a device opens (core.metadata,
app.workflow.delivery.delivery_folder); a queue's refused rows are listed one per line and nothing is shot while one is
refused, unless ``--skip-invalid``; ``--check`` prints the plan (rows to shoot, kept, refused) and opens no device.
An original of the queue already delivered in the session is kept and said so. ``--collection`` (or a queue's
``collection`` column) applies that collection's metadata preset (app.workflow.day.collection_presets).
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
    calibration_source,
    column_option,
    count,
    delivery_request,
    identifier,
    input_file,
    number,
)
from dualrgb.app.commands.stand_options import (
    add_device_options,
    add_reuse_options,
    add_session_option,
    ask_person,
    check_camera_request,
    check_device_options,
    open_devices,
    progress_printer,
    reuse_limits,
    said_redelivery,
    session_of_run,
    timed,
)
from dualrgb.app.json_output import text_stream, write_json
from dualrgb.app.workflow.stand.defaults import DAY_WORKFLOW, MODES, VIRTUAL_ORIGINALS

log = logging.getLogger(__name__)

CAPTURE_FORMAT = "dualrgb-capture/1"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("capture", help="capture one original with a saved calibration and deliver it",
                       description="Checks the calibration against the stand (camera serial, ISO, aperture, lights, "
                                   "sphere temperature, age), meters the original, captures it (an HDR bracket "
                                   "only when metering asks) and writes its deliverables.")
    add_session_option(p)
    p.add_argument("--calibration", type=calibration_source, metavar="FILE|SESSION",
                   help="calibration profile (.json), or a session folder: its newest; default with --session: the "
                        "session's newest (of --mode's)")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--id", dest="identifier", type=identifier,
                      help="identifier / accession number (names the files)")
    what.add_argument("--queue", type=input_file, metavar="CSV",
                      help="a day's originals from the collection database: a UTF-8 CSV with a header naming the "
                           "columns identifier, title, operator, notes, mode (others kept as extra metadata); "
                           "every row is checked before anything is shot")
    p.add_argument("--column", type=column_option, action="append", default=[], metavar="FIELD=NAME",
                   help="--queue: the CSV column holding FIELD, e.g. --column identifier='Accession No.'")
    p.add_argument("--skip-invalid", action="store_true",
                   help="--queue: list the refused rows and shoot the others (default: shoot nothing while one is "
                        "refused)")
    p.add_argument("--check", action="store_true",
                   help="validate and print the plan (rows to shoot, kept, refused with the reason) and stop: no "
                        "device is opened, nothing is shot")
    p.add_argument("--collection", default="", metavar="NAME",
                   help="the collection whose metadata preset (creator, rights, default extra fields) is applied to "
                        "the original (with --queue: to the rows whose 'collection' column is empty)")
    p.add_argument("--collections", type=Path, default=None, metavar="DIR",
                   help="the collection presets' folder (default: presets/collections in the per-user data folder)")
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


def _calibration(args: argparse.Namespace) -> Path:
    """--calibration (a file, or a session folder: its newest), else the session's newest calibration (of
    ``--mode``'s when given; app.cli_refusals.newest_calibration: no heavy import, a refusal comes at once)."""
    from dualrgb.app.cli_refusals import newest_calibration

    given = Path(args.calibration) if args.calibration else None
    if given is not None and not given.is_dir():
        return given
    found = newest_calibration(given or args.session, args.mode)
    print(f"dualrgb: calibration {found} (the session's newest)", file=sys.stderr)
    return found


def _single(args: argparse.Namespace, mode: str, out_dir: Path | None, profile) -> list:
    from dualrgb.app.workflow.day.collection_presets import apply_preset
    from dualrgb.app.workflow.delivery.delivery_folder import check_folder
    from dualrgb.app.workflow.stand.mode_rule import check_mode
    from dualrgb.core.metadata import Original

    original = apply_preset(Original(args.identifier, args.title, args.operator, args.notes, mode), _preset(args))
    check_mode(original, profile, force=args.force)
    if out_dir is not None:
        check_folder(out_dir, original)
    return [original]


def _preset(args: argparse.Namespace):
    """``--collection``'s metadata preset (app.workflow.day.collection_presets, as the window's form; None: no
    --collection); a named collection without a preset file is refused in one line."""
    from dualrgb.app.workflow.day.collection_presets import find_preset, preset_path

    if not args.collection:
        return None
    preset = find_preset(args.collection, args.collections)
    if preset is None:
        where = preset_path(args.collection, args.collections)
        raise ValueError(f"--collection {args.collection}: no preset file {where}")
    return preset


def _plan(args: argparse.Namespace, mode: str, out_dir: Path | None, profile):
    """The queue's plan (app.workflow.day.queue_plan): every row checked before a device opens."""
    from dualrgb.app.workflow.day.queue_csv import read_queue_csv
    from dualrgb.app.workflow.day.queue_plan import plan_queue

    if args.title or args.notes:
        raise ValueError("--title and --notes name one original (--id); a queue's come from its CSV")
    _preset(args)                               # a named collection without a preset: refused before the rows
    queue = read_queue_csv(Path(args.queue), columns=dict(args.column), default_mode=mode, out_dir=out_dir,
                           collection=args.collection, presets=args.collections)
    session = None
    if args.session and (Path(args.session) / "session.json").is_file():
        from dualrgb.app.workflow.stand.folders import open_session

        session = open_session(Path(args.session), readonly=True)
    plan = plan_queue(queue, profile, session=session, force=args.force, reshoot=args.reshoot)
    if args.operator:
        plan.rows = [replace(r, original=replace(r.original, operator=args.operator))
                     if r.original is not None and not r.original.operator else r for r in plan.rows]
    return plan


def _queue_originals(args: argparse.Namespace, plan) -> list:
    """The originals of the plan to shoot (kept ones too: capture_queue says so); its refused rows listed, and
    refused whole while one is unless --skip-invalid."""
    from dualrgb.app.workflow.day.queue_plan import REFUSED

    name = Path(args.queue).name
    for line in plan.column_lines:
        print(f"{name}: {line}", file=sys.stderr)
    refused = plan.of(REFUSED)
    for r in refused:
        print(f"{name}: {r.refusal()}", file=sys.stderr)
    shots = [r.original for r in plan.rows if r.state != REFUSED and r.original is not None]
    n = len(refused)
    if refused and not args.skip_invalid:
        k = len(shots)
        rest = ("no row is valid" if k == 0 else
                f"or --skip-invalid to shoot the other {k}" if k > 1 else "or --skip-invalid to shoot the other one")
        raise ValueError(f"{args.queue}: {n} refused row{'s' if n > 1 else ''} (listed above); nothing was shot: "
                         f"fix {'it' if n == 1 else 'them'}{'; ' if k == 0 else ', '}{rest}")
    if not shots:
        raise ValueError(f"{args.queue}: no original to shoot")
    if refused:
        print(f"skipped {n} refused row{'s' if n > 1 else ''}: {', '.join(str(r.row) for r in refused)}",
              file=sys.stderr)
    return shots


def main(args: argparse.Namespace) -> int:
    if not args.check:
        check_device_options(args)            # before the heavy imports below (--check opens no device)
    calibration = _calibration(args)          # a missing calibration or session: refused before the imports
    from dualrgb.app.processing.render import DEFAULT_RENDER_ILLUMINANT
    from dualrgb.app.warm_kernels import ensure_ready as ensure_kernels
    from dualrgb.app.workflow.calibration.profile import load_profile
    from dualrgb.app.workflow.stand.copystand import StandSettings

    profile = load_profile(calibration)
    delivery = delivery_request(args, profile)          # before any device opens: refused in one line
    mode = args.mode or profile.mode
    out_dir = Path(args.out) if args.out else args.session / "deliverables" if args.session else None
    plan = _plan(args, mode, out_dir, profile) if args.queue else None
    if args.check:
        return _check(args, plan, _single(args, mode, out_dir, profile) if plan is None else [], profile)
    originals = _queue_originals(args, plan) if plan is not None else _single(args, mode, out_dir, profile)
    check_camera_request(args, args.session, None if args.force else profile)   # before the camera is set
    settings = StandSettings(settle_s=args.settle, limits=reuse_limits(args), force=args.force, ppi=args.ppi,
                             original_frames=args.frames, resolution=args.resolution, delivery=delivery,
                             render_illuminant=args.render_illuminant or delivery.render_illuminant
                             or DEFAULT_RENDER_ILLUMINANT)
    ensure_kernels()                          # first run: compiled here, before any device opens
    return _run(args, profile, settings, originals, plan, mode, out_dir)


def _run(args: argparse.Namespace, profile, settings, originals: list, plan, mode: str, out_dir: Path | None) -> int:
    """The devices opened, every check before the light made (app.workflow.stand.run_gate), then only the session
    opened and the originals shot: a refused run leaves the session folder as it was."""
    from dualrgb.app.workflow.day.queue_run import QueueOutcome, capture_queue
    from dualrgb.app.workflow.phase_costs import PhaseClock
    from dualrgb.app.workflow.stand.copystand import CopyStand
    from dualrgb.app.workflow.stand.run_gate import check_capture_run

    definition = {"workflow": DAY_WORKFLOW}
    with open_devices(args, mode, args.virtual_original) as dev:
        check_capture_run(dev.camera, dev.sphere, profile, settings, args.session, definition, out_dir,
                          len(originals))
        with session_of_run(args.session, definition, dev.camera) as session:
            out_dir = out_dir or session.path / "deliverables"
            clock, computer = _clock(args, profile, originals, single=plan is None)   # time left from the costs
            stand = CopyStand(dev.camera, dev.sphere, session, stand=dev.stand, settings=settings,
                              progress=progress_printer(clock), prompt=ask_person,
                              reshoot=lambda _o, _n: args.reshoot)
            if isinstance(clock, PhaseClock):   # one original: shot, or its frames kept and delivered again
                said_redelivery(session, originals[0], args.reshoot)
                computer.on_stand(stand)                                # a person's placements left out
                with timed(clock):
                    result = stand.capture(originals[0], profile, reshoot=args.reshoot, out_dir=out_dir)
                _print_outcome(QueueOutcome(originals[0], report=result), text_stream(args.json_path))
                return _single_json(args, result, profile)
            with timed(clock):
                outcomes = capture_queue(stand, originals, profile, reshoot=args.reshoot, out_dir=out_dir,
                                         on_outcome=lambda o: _print_outcome(o, text_stream(args.json_path)),
                                         clock=clock)
    write_json(args.json_path, CAPTURE_FORMAT, {"queue": str(args.queue), "calibration": profile.id,
                                                "bad_rows": plan.refused_lines(), "plan": plan.to_dict(),
                                                "originals": [_outcome_json(o) for o in outcomes]}, default=str)
    return 1 if any(o.error for o in outcomes) else 0        # a failed delivery: said against its original


def _clock(args: argparse.Namespace, profile, originals: list, *, single: bool):
    """The run's clock (app.workflow.phase_costs): one original's phases, or the queue's (app.workflow.day.queue_clock),
    from the measured costs of an original; and the computer's time it runs on."""
    from dualrgb.app.workflow.day.queue_clock import ComputerTime, QueueClock
    from dualrgb.app.workflow.day.queue_run import original_plan
    from dualrgb.app.workflow.stand.run_phases import original_clock

    plans = [original_plan(profile, o.identifier, args.frames or 1) for o in originals]
    if single:
        computer = ComputerTime()
        return original_clock(plans[0], args.settle, now=computer), computer
    clock = QueueClock(plans, settle_s=args.settle)
    return clock, clock.time


def _check(args: argparse.Namespace, plan, single: list, profile) -> int:
    """``--check``: the plan printed (and with --json written), no device opened; exit 1 when the same command
    without --check would shoot nothing (a refused row without --skip-invalid, or no row to shoot)."""
    from dualrgb.app.workflow.day.queue_plan import PLAN_FORMAT, REFUSED

    out = text_stream(args.json_path)
    if plan is None:
        line = f"{single[0].identifier}: shoot with calibration {profile.id}"
        print(line, file=out)
        write_json(args.json_path, PLAN_FORMAT, {"original": single[0].to_dict(), "calibration": profile.id,
                                                 "summary": line})
        return 0
    for line in plan.lines():
        print(line, file=out)
    write_json(args.json_path, PLAN_FORMAT, plan.to_dict())
    shots = [r for r in plan.rows if r.state != REFUSED]
    return 1 if not shots or (plan.of(REFUSED) and not args.skip_invalid) else 0


def _print_outcome(outcome, out=None) -> None:
    out = out or sys.stdout
    result = outcome.report
    if result is None:
        print(outcome.summary(), file=out)
        return
    for w in result.check.warnings + result.warnings:
        print(f"warning: {w}", file=out)
    print(result.summary(), file=out)
    for key, path in result.delivery.files.items():
        print(f"  {key}: {path}", file=out)
    print(f"  sidecar: {result.delivery.sidecar}", file=out)


def _outcome_json(outcome) -> dict:
    r = outcome.report
    if outcome.error:           # issue 41: captured, its delivery failed (its frames are in the session)
        return {"original": outcome.original.to_dict(), "state": "failed", "error": outcome.error,
                **outcome.timings()}
    if r is None:
        return {"original": outcome.original.to_dict(), "state": "kept", "sidecar": str(outcome.kept)}
    return {"original": outcome.original.to_dict(), "state": "delivered", "new": r.new, "kept": r.kept,
            "qa": r.delivery.qa.to_dict(), "files": {k: str(v) for k, v in r.delivery.files.items()},
            "sidecar": str(r.delivery.sidecar), **outcome.timings()}


def _single_json(args: argparse.Namespace, result, profile) -> int:
    write_json(args.json_path, CAPTURE_FORMAT, {
        "original": result.original.to_dict(), "new": result.new, "kept": result.kept,
        "exposures": result.exposures, "qa": result.delivery.qa.to_dict(),
        "files": {k: str(v) for k, v in result.delivery.files.items()}, "sidecar": str(result.delivery.sidecar),
        "calibration": profile.id, "calibration_age_h": round(result.check.age_h, 3)}, default=str)
    return 0
