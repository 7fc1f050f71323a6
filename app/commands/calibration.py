"""``dualrgb calibration show FILE|SESSION``: what a calibration profile is (a session folder: its newest), and
(with devices) whether it fits the stand.

    dualrgb calibration show FILE|SESSION [--virtual-lab | --port P --camera C] [--json J]
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

from dualrgb.app.commands.options import calibration_source
from dualrgb.app.commands.stand_options import (
    add_device_options,
    add_reuse_options,
    check_device_options,
    open_devices,
    reuse_limits,
)
from dualrgb.app.json_output import text_stream, write_json

log = logging.getLogger(__name__)

SHOW_FORMAT = "dualrgb-calibration/1"       # --json: the profile (app.workflow.calibration.profile.FORMAT), its age
                                            # and checks


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calibration", help="show a calibration profile and check it against the stand")
    verbs = p.add_subparsers(dest="verb", metavar="VERB")
    verbs.required = True
    show = verbs.add_parser("show", help="what the calibration is; with devices, its reuse checks")
    show.add_argument("file", type=calibration_source, metavar="FILE|SESSION",
                      help="a calibration profile (.json), or a session folder: its newest calibration")
    add_reuse_options(show)
    add_device_options(show)
    show.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    if args.virtual_lab or args.port or args.camera:
        check_device_options(args)            # before the heavy imports below
    from dualrgb.app.cli_refusals import newest_calibration
    from dualrgb.app.workflow.calibration.profile import (
        CameraIdentity,
        SphereIdentity,
        check_reuse,
        describe,
        load_profile,
    )

    path = Path(args.file)
    profile = load_profile(newest_calibration(path) if path.is_dir() else path)
    check = None
    if args.virtual_lab or args.port or args.camera:
        with open_devices(args, profile.mode) as dev:
            check = check_reuse(profile, CameraIdentity.of(dev.camera), SphereIdentity.of(dev.sphere),
                                profile.lights, reuse_limits(args))
    from dualrgb.app.processing.quality import grading_lines

    for line in describe(profile, check) + [f"grade {g}" for g in grading_lines(profile.statistics.get("quality"))]:
        print(line, file=text_stream(args.json_path))
    write_json(args.json_path, SHOW_FORMAT, {**profile.to_dict(), "age_h": round(profile.age_h(), 3),
                                             "check": None if check is None else {"refusals": check.refusals,
                                                                                  "warnings": check.warnings}},
               default=str)
    return 1 if check is not None and not check.ok and not args.force else 0
