"""``dualrgb import``: calibrate and deliver raw files another program shot (Capture One, digiCamControl, a script).

    dualrgb import FOLDER --roles-template ROLES.csv              # a roles file to start from, for checking
    dualrgb import FOLDER --roles ROLES.csv --session DIR [--preset P] [--mode M]
                   [--train-corners X1,Y1,...,X4,Y4|FILE] [--test-corners X1,Y1,...,X4,Y4|FILE]
                   [--train-target FILE [--train-layout RxC]] [--test-target FILE [--test-layout RxC]]
                   [--ppi N | --target-width-mm W] [--out DIR] [--resolution full|half] [--json J]

Everything is checked before anything is written (app.workflow.raw_import.import_checks): each problem is one line on
stderr
naming the file or the roles file's row, and the command exits 1 having written nothing. Then the files are
copied into the session, the calibration is made from its darks, flats and targets and every original is
delivered, as ``calibrate`` and ``capture`` do on a stand (app.workflow.raw_import.raw_import); ``dualrgb process DIR``
delivers them again. Without ``--preset`` the lights are unknown (said in the profile and the sidecars).
"""
from __future__ import annotations

import argparse
import contextlib
import logging
import sys
from pathlib import Path

from dualrgb.app.cli import UserError
from dualrgb.app.commands.options import (
    add_chart_options,
    add_render_option,
    add_resolution_option,
    corners,
    count,
    input_file,
    number,
)
from dualrgb.app.commands.stand_options import add_session_option, progress_printer
from dualrgb.app.json_output import HELP as JSON_HELP
from dualrgb.app.json_output import text_stream, write_json
from dualrgb.app.workflow.stand import defaults as day

log = logging.getLogger(__name__)

IMPORT_FORMAT = "dualrgb-import/1"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("import", help="calibrate and deliver raw files shot by another program",
                       description="Checks a folder of raw files (NEF, CR2, CR3, ARW, DNG, IIQ ...) and their roles, "
                                   "then copies them into a session, calibrates from their darks, flats and targets "
                                   "and delivers every original, as a captured day.")
    p.add_argument("folder", type=Path, help="the folder holding the raw files")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--roles", type=input_file, metavar="ROLES.csv",
                      help="one row per file: file,role,light,identifier (role dark, flat, target or original; light "
                           "the light's number in the preset; identifier the original's, train / test for targets), "
                           "then the originals' title, operator, ... as in a queue CSV")
    what.add_argument("--roles-template", type=Path, metavar="ROLES.csv",
                      help="write a roles file to start from: the files in capture order, roles and lights guessed")
    add_session_option(p)
    p.add_argument("--preset", default=None, help="the preset the files were shot under (file or packaged name); "
                                                  "without it the lights are unknown")
    p.add_argument("--mode", choices=day.MODES, default=None, help=f"default: the preset's ({day.DEFAULT_MODE})")
    p.add_argument("--lights", type=count(1, 8), default=2, help="--roles-template: lights per subject (2)")
    for role, what in (("train", "training"), ("test", "test")):
        p.add_argument(f"--{role}-corners", metavar="X1,Y1,...,X4,Y4|FILE",
                       help=f"the {what} chart placed by hand, as calibrate's option: its four corners (outer corners "
                            "of its corner patches: top-left, top-right, bottom-right, bottom-left) in the raw file's "
                            "pixels, or a JSON file {\"corners\": [[x, y], ...]}; without it the chart is found in "
                            "its frames")
    p.add_argument("--target-corners", type=corners, action="append", default=[], metavar="NAME=X,Y,...",
                   help="the older spelling of --train-corners / --test-corners: NAME=train or test")
    p.add_argument("--train-grid", type=input_file, help="patch grid JSON of the training target (stack pixels)")
    p.add_argument("--test-grid", type=input_file, help="patch grid JSON of the test target (stack pixels)")
    add_chart_options(p)
    p.add_argument("--ppi", type=number(above=0.0), help="the sensor's sampling of the original (pixels per inch)")
    p.add_argument("--target-width-mm", type=number(above=0.0), help="test target width (its corner patches' outer "
                                                                    "corners) -> ppi")
    p.add_argument("--no-de-fit", action="store_true", help="least squares only")
    p.add_argument("--out", type=Path, help="deliverables folder (default <session>/deliverables)")
    add_resolution_option(p)
    add_render_option(p)
    p.add_argument("--json", metavar="PATH", dest="json_path", help=JSON_HELP)
    p.set_defaults(func=main)


def _settings(args: argparse.Namespace):
    """The import's settings from the options, checked before any file is read."""
    from dualrgb.app.commands.calibrate import find_preset
    from dualrgb.app.commands.options import chart_choices
    from dualrgb.app.workflow.calibration import charts as day_charts
    from dualrgb.app.workflow.calibration.targets import load_grid
    from dualrgb.app.workflow.raw_import.import_checks import ImportSettings, corner_grid
    from dualrgb.app.workflow.stand.preflight import check_lights
    from dualrgb.core.vocabulary import lights_of

    preset = None
    if args.preset:
        preset = find_preset(args.preset, args.mode)
        preset.mode = args.mode or preset.mode
        check_lights(lights_of(preset), f"preset {args.preset}")
    mode = preset.mode if preset is not None else (args.mode or day.DEFAULT_MODE)
    charts = day_charts.load_charts(chart_choices(args), mode)
    grids = {k: load_grid(v, charts[k].layout if k in charts else None)
             for k, v in (("train", args.train_grid), ("test", args.test_grid)) if v}
    for name, values in _corner_options(args):
        grids[name] = corner_grid(mode, name, values, charts)
    return ImportSettings(mode, preset, charts, grids, args.session.absolute() if args.session else None,
                          args.out.absolute() if args.out else None)


def _corner_options(args: argparse.Namespace) -> list[tuple[str, tuple[float, ...]]]:
    """``--train-corners`` / ``--test-corners`` (numbers or a JSON file, as calibrate takes them) and the older
    ``--target-corners NAME=...``; a chart placed twice is refused in one line."""
    from dualrgb.app.workflow.calibration.targets import parse_corners

    out = list(args.target_corners)
    for role in ("train", "test"):
        text = getattr(args, f"{role}_corners", None)
        if text is None:
            continue
        if any(name == role for name, _ in out):
            raise ValueError(f"--{role}-corners and --target-corners {role}=... both place the {role} target: "
                             "give one")
        out.append((role, tuple(float(v) for v in parse_corners(text, f"--{role}-corners").ravel())))
    return out


def template(args: argparse.Namespace) -> int:
    from dualrgb.app.workflow.raw_import.import_template import write_template

    if not args.folder.is_dir():
        raise ValueError(f"{args.folder}: not a folder of raw files")
    rows = write_template(args.folder, args.roles_template, args.lights)
    usable = [g for g in rows if g.role]
    print(f"{args.roles_template}: {len(rows)} files ({len(usable)} with a guessed role); check every row before "
          "importing", file=sys.stderr)
    for g in rows:
        if not g.role:
            print(f"{args.folder / g.file}: {g.why}", file=sys.stderr)
    return 0


def main(args: argparse.Namespace) -> int:
    if args.roles_template:
        return template(args)
    from dualrgb.app.workflow.raw_import.import_roles import read_roles
    from dualrgb.app.workflow.raw_import.raw_import import ImportOptions, ImportRefused, plan_import, run_import

    settings = _settings(args)
    roles = read_roles(Path(args.roles), default_mode=settings.mode,
                       out_dir=settings.out_dir or (settings.session / "deliverables" if settings.session else None))
    try:
        plan = plan_import(args.folder.absolute(), roles, settings)
    except ImportRefused as exc:
        for line in exc.lines:
            print(f"dualrgb: refused: {line}", file=sys.stderr)
        raise UserError(f"import refused: {exc}") from None
    for note in plan.notes:
        print(f"note: {note}", file=sys.stderr)
    options = ImportOptions(False if args.no_de_fit else None, args.ppi, args.target_width_mm, args.resolution,
                            args.render_illuminant)
    from dualrgb.core.session.log import SessionLog

    with SessionLog(settings.session) if settings.session else contextlib.nullcontext():
        result = run_import(plan, options, progress=progress_printer())        # the run's log in its session.log
    text = text_stream(args.json_path)
    for d in result.deliveries:
        print(d.qa.text(), file=text)
    print(f"session: {result.session} ({result.copied} files copied, {result.kept} kept); calibration: "
          f"{result.profile.path}", file=text)
    write_json(args.json_path, IMPORT_FORMAT, {
        "session": str(result.session), "copied": result.copied, "kept": result.kept,
        "calibration": str(result.profile.path), "profile": result.profile.to_dict(),
        "originals": [{"identifier": d.original.identifier, "qa": d.qa.to_dict(), "sidecar": str(d.sidecar),
                       "files": {k: str(v) for k, v in d.files.items()}} for d in result.deliveries]}, default=str)
    return 0
