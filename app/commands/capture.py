"""``dualrgb capture``: one original, with a saved calibration, to its deliverables.

    dualrgb capture --session DIR --calibration FILE --id ACC-123 [--title ..] [--operator ..] [--notes ..]
                    [--mode reflective|transmissive] [--reshoot] [--force] (--virtual-lab | --port P --camera C)
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

from app.commands.options import count, input_file, number
from app.commands.stand_options import (
    add_device_options,
    add_reuse_options,
    ask_person,
    open_devices,
    open_session,
    progress_printer,
    reuse_limits,
    virtual_world,
    write_json,
)

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("capture", help="capture one original with a saved calibration and deliver it",
                       description="Checks the calibration against the stand (camera serial, ISO, aperture, lights, "
                                   "sphere temperature, age), meters the original, captures it (an HDR bracket "
                                   "only when metering asks) and writes its deliverables.")
    p.add_argument("--session", type=Path, required=True, help="session folder (created, or resumed)")
    p.add_argument("--calibration", type=input_file, required=True, help="calibration profile (.json)")
    p.add_argument("--id", dest="identifier", required=True, help="identifier / accession number (names the files)")
    p.add_argument("--title", default="")
    p.add_argument("--operator", default="")
    p.add_argument("--notes", default="")
    p.add_argument("--mode", choices=("reflective", "transmissive"), default=None,
                   help="default: the calibration's")
    p.add_argument("--reshoot", action="store_true", help="shoot an original already in the session again")
    p.add_argument("--out", type=Path, help="deliverables folder (default <session>/deliverables)")
    p.add_argument("--ppi", type=number(above=0.0), help="sampling of the deliverables (default: the calibration's)")
    p.add_argument("--frames", type=count(1, 100), default=1,
                   help="frames averaged per exposure (noise / sqrt(N), light dose x N; default 1)")
    p.add_argument("--virtual-original", default=None,
                   help="virtual lab: which virtual original stands in (default painting / film by mode)")
    add_reuse_options(p)
    add_device_options(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from app.workflow.copystand import CopyStand, StandSettings
    from app.workflow.delivery import Original
    from app.workflow.profile import load_profile

    profile = load_profile(args.calibration)
    original = Original(args.identifier, args.title, args.operator, args.notes, args.mode or profile.mode)
    settings = StandSettings(settle_s=args.settle, limits=reuse_limits(args), force=args.force, ppi=args.ppi,
                             original_frames=args.frames)
    with open_devices(args, original.mode, args.virtual_original) as dev, \
            open_session(args.session, {"workflow": "originals", **virtual_world(args)}, dev.camera) as session:
        stand = CopyStand(dev.camera, dev.sphere, session, stand=dev.stand, lab=dev.lab, settings=settings,
                          progress=progress_printer(), prompt=ask_person, reshoot=lambda _o, _n: args.reshoot)
        result = stand.capture(original, profile, reshoot=args.reshoot, out_dir=args.out)
    for w in result.check.warnings + result.warnings:
        print(f"warning: {w}")
    print(result.summary())
    for key, path in result.delivery.files.items():
        print(f"  {key}: {path}")
    print(f"  sidecar: {result.delivery.sidecar}")
    write_json(args.json_path, {"original": original.to_dict(), "new": result.new, "kept": result.kept,
                                "exposures": result.exposures, "qa": result.delivery.qa.to_dict(),
                                "files": {k: str(v) for k, v in result.delivery.files.items()},
                                "sidecar": str(result.delivery.sidecar), "calibration": profile.id,
                                "calibration_age_h": round(result.check.age_h, 3)})
    return 0
