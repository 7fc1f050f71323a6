"""``dualrgb calibrate``: darks, flats, training and test targets, matrix -> a calibration profile (made once a day).

    dualrgb calibrate --session DIR [--preset P] [--hdr auto] (--virtual-lab | --port P --camera C) [--json J]
"""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from app.commands.options import count, input_file, number, stand_dir
from app.commands.stand_options import (
    add_device_options,
    ask_person,
    open_devices,
    open_session,
    progress_printer,
    virtual_world,
    write_json,
)

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calibrate", help="calibrate the copy stand: darks, flats, targets, matrix, profile",
                       description="Auto-exposure, darks and flats at every planned exposure, the training and test "
                                   "targets, the characterisation matrix; writes the calibration profile "
                                   "(<session>/calibration/<id>.json + .npz).")
    p.add_argument("--session", type=Path, required=True, help="session folder (created, or resumed)")
    p.add_argument("--preset", default=None, help="preset file or packaged name (default: the PSO preset of --mode)")
    p.add_argument("--mode", choices=("reflective", "transmissive"), default=None,
                   help="default: the preset's mode (reflective)")
    p.add_argument("--hdr", choices=("auto", "off"), default="off",
                   help="auto: also calibrate the longer exposures HDR originals may need (resources/parsimony.json)")
    p.add_argument("--dark-frames", type=count(1, 200), default=10)
    p.add_argument("--flat-frames", type=count(1, 200), default=3)
    p.add_argument("--ppi", type=number(above=0.0), help="sampling of the deliverables (pixels per inch)")
    p.add_argument("--target-width-mm", type=number(above=0.0),
                   help="test target width (outer corners of its corner patches)")
    p.add_argument("--train-grid", type=input_file, help="patch grid JSON of the training target (real stands)")
    p.add_argument("--test-grid", type=input_file, help="patch grid JSON of the test target (real stands)")
    p.add_argument("--no-de-fit", action="store_true", help="least squares only")
    p.add_argument("--stand-dir", type=stand_dir, metavar="DIR",
                   help="a stand folder (`dualrgb measure leds`): warn when the preset sets an LED below the "
                        "measured minimum stable level, where its output is not proportional to the level")
    add_device_options(p)
    p.set_defaults(func=main)


def find_preset(name: str | None, mode: str | None):
    """A preset by file path or packaged file name (with or without .json); default: '<mode>_pso'."""
    from simulation.presets import load_preset, packaged_presets

    wanted = name or f"{mode or 'reflective'}_pso"
    path = Path(wanted)
    if path.suffix == ".json" and path.exists():
        return load_preset(path)
    for p in packaged_presets():
        if p.stem == wanted or p.name == wanted:
            return load_preset(p)
    names = ", ".join(p.stem for p in packaged_presets())
    raise ValueError(f"preset {wanted!r}: no such file and not a packaged preset ({names})")


def main(args: argparse.Namespace) -> int:
    from app.workflow.copystand import CopyStand, StandSettings
    from app.workflow.targets import load_grid

    preset = find_preset(args.preset, args.mode)
    if args.stand_dir:
        from app.workflow.led_stand import load_stand, unstable_levels

        for line in unstable_levels(preset.sources, load_stand(args.stand_dir)):
            print(f"warning: {line}", file=sys.stderr)
    mode = args.mode or preset.mode
    preset.mode = mode
    grids = {k: load_grid(v) for k, v in (("train", args.train_grid), ("test", args.test_grid)) if v}
    settings = StandSettings(settle_s=args.settle, dark_frames=args.dark_frames, flat_frames=args.flat_frames,
                             optimise_matrix=False if args.no_de_fit else None, ppi=args.ppi,
                             target_width_mm=args.target_width_mm)
    definition = {"workflow": "calibrate", "mode": mode, "preset": preset.name, "hdr": args.hdr,
                  "dark_frames": args.dark_frames, "flat_frames": args.flat_frames, "settle_s": args.settle,
                  **virtual_world(args)}
    with open_devices(args, mode) as dev, open_session(args.session, definition, dev.camera, {"mode": mode}) as session:
        stand = CopyStand(dev.camera, dev.sphere, session, stand=dev.stand, lab=dev.lab, settings=settings,
                          progress=progress_printer(), prompt=ask_person)
        profile = stand.calibrate(preset, hdr_auto=args.hdr == "auto", grids=grids)
    from app.workflow.profile import describe

    for line in describe(profile):
        print(line)
    print(f"calibration: {profile.path}")
    write_json(args.json_path, {"calibration": str(profile.path), **profile.to_dict()})
    print(f"dualrgb: calibration {profile.id} written", file=sys.stderr)
    return 0
