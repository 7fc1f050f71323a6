"""``dualrgb calibrate``: darks, flats, training and test targets, matrix -> a calibration profile (made once a day).

    dualrgb calibrate [--session DIR] [--preset P] [--hdr auto|off] (--virtual-lab | --port P --camera C) [--json J]
                      [--train-target FILE [--train-layout ROWSxCOLS] [--train-leave-out NAMES]]
                      [--test-target FILE [--test-layout ROWSxCOLS] [--test-leave-out NAMES]]
                      [--train-corners X1,Y1,...,X4,Y4|FILE] [--test-corners X1,Y1,...,X4,Y4|FILE]

Each chart's patches are found in its frames (app.processing.chart_detect) unless its grid is given: by its four
corners (``--train-corners`` / ``--test-corners``, the raw frame's pixels) or a grid JSON (``--train-grid``).

The charts' reference files are read (app.workflow.calibration.charts) before any device opens; without them the mode's
packaged targets are used. The session is the day's (app.workflow.stand.defaults.DAY_WORKFLOW): `capture --session`
the same folder takes the day's originals with this calibration.

Every default (lights per mode, HDR plan, darks and flats, matrix, the session folder) is the GUI's too:
app.workflow.stand.defaults.
"""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any

from dualrgb.app.commands.calibrate_summary import say_calibrated
from dualrgb.app.commands.options import add_chart_options, chart_choices, count, input_file, number, stand_dir
from dualrgb.app.commands.stand_options import (
    add_device_options,
    add_session_option,
    ask_person,
    check_camera_request,
    check_device_options,
    open_devices,
    progress_printer,
    session_of_run,
    timed,
)
from dualrgb.app.json_output import text_stream, write_json
from dualrgb.app.workflow.stand import defaults as day

log = logging.getLogger(__name__)

CALIBRATE_FORMAT = "dualrgb-calibration/1"        # --json: the profile (app.workflow.calibration.profile.FORMAT) and
                                                  # its path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calibrate", help="calibrate the copy stand: darks, flats, targets, matrix, profile",
                       description="Auto-exposure, darks and flats at every planned exposure, the training and test "
                                   "targets, the characterisation matrix; writes the calibration profile "
                                   "(<session>/calibration/<id>.json + .npz).")
    add_session_option(p)
    p.add_argument("--preset", default=None,
                   help="preset file or packaged name (default: the mode's, "
                        + ", ".join(f"{m}: {n}" for m, n in day.PRESETS.items()) + ")")
    p.add_argument("--mode", choices=day.MODES, default=None,
                   help=f"default: the preset's mode ({day.DEFAULT_MODE})")
    p.add_argument("--hdr", choices=("auto", "off"), default=None,
                   help="auto: also calibrate the longer exposures HDR originals may need (as many as "
                        f"resources/parsimony.json says); default {'auto' if day.HDR_AUTO else 'off'}")
    p.add_argument("--dark-frames", type=count(1, 200), default=None,
                   help=f"dark frames per exposure (default {day.DARK_FRAMES})")
    p.add_argument("--flat-frames", type=count(1, 200), default=None,
                   help=f"open-gate frames per light and exposure (default {day.FLAT_FRAMES})")
    p.add_argument("--ppi", type=number(above=0.0),
                   help="sampling of the original at the sensor's full resolution (pixels per inch; half-resolution "
                        "deliverables carry half); default: from the test target's size")
    p.add_argument("--target-width-mm", type=number(above=0.0),
                   help="test target width (outer corners of its corner patches)")
    _add_placement_options(p)
    add_chart_options(p)
    p.add_argument("--no-de-fit", action="store_true",
                   help="leave the ΔE00-optimised matrix out (default: every model the processing delivers - least "
                        "squares, ΔE00-optimised, root-polynomial 2 and 3 - 5-fold cross-validation on the training "
                        "chart choosing with the one-standard-error rule)")
    p.add_argument("--stand-dir", type=stand_dir, metavar="DIR",
                   help="a stand folder (`dualrgb measure leds`): warn when the preset sets an LED below the "
                        "measured minimum stable level, where its output is not proportional to the level; its LED "
                        "spectra and level -> output curves are the stand model's starting curves (the prediction "
                        "uses what each LED emitted at its level)")
    p.add_argument("--camera-csv", type=input_file,
                   help="the camera's measured sensitivities (`dualrgb measure csrf`): the stand model fitted to the "
                        "captures starts from them instead of the nominal curves")
    add_device_options(p)
    p.set_defaults(func=main)


def _add_placement_options(p: argparse.ArgumentParser) -> None:
    """``--train-grid / --test-grid`` and ``--train-corners / --test-corners``: a chart placed by hand."""
    p.add_argument("--train-grid", type=input_file,
                   help="patch grid JSON of the training target (real stands): its four corners (and rows / cols, "
                        "else the chart's layout)")
    p.add_argument("--test-grid", type=input_file, help="patch grid JSON of the test target (real stands; else "
                                                        "the chart is found in its frames)")
    for role in ("train", "test"):
        what = "training" if role == "train" else "test"
        p.add_argument(f"--{role}-corners", metavar="X1,Y1,...,X4,Y4|FILE",
                       help=f"the {what} chart placed by hand, when it is not found in its frames: "
                            "its four corners in the raw frame's pixels (column x, row y), the outer corners of its "
                            "outermost patches, the chart's top-left first, then top-right, bottom-right, "
                            "bottom-left; or a JSON file {\"corners\": [[x, y], ...]}; the patches are placed from "
                            "the chart's layout")


def find_preset(name: str | None, mode: str | None):
    """A preset by file path or packaged file name (with or without .json); default: the mode's
    (app.workflow.stand.defaults.default_preset_name)."""
    from dualrgb.simulation.presets import load_preset, packaged_presets

    wanted = name or day.default_preset_name(mode)
    path = Path(wanted)
    if path.suffix == ".json" and path.exists():
        return load_preset(path)
    for p in packaged_presets():
        if p.stem == wanted or p.name == wanted:
            return load_preset(p)
    names = ", ".join(p.stem for p in packaged_presets())
    raise ValueError(f"preset {wanted!r}: no such file and not a packaged preset ({names})")


def resolve(args: argparse.Namespace) -> tuple[Any, str, int, int]:
    """What the options (or their defaults, app.workflow.stand.defaults) ask for: (the preset, its mode set to the
    run's, the HDR plan 'auto' / 'off', dark frames, flat frames)."""
    from dualrgb.app.workflow.stand.preflight import check_lights
    from dualrgb.core.vocabulary import lights_of

    preset = find_preset(args.preset, args.mode)
    preset.mode = args.mode or preset.mode
    check_lights(lights_of(preset), f"preset {args.preset or preset.name}")     # before any device opens
    d = day.workflow_defaults(preset.mode)
    return preset, args.hdr or d.hdr, args.dark_frames or d.dark_frames, args.flat_frames or d.flat_frames


def conditioning(preset: Any, stand: Any) -> None:
    """The preset's lights with the camera model (app.workflow.stand.preflight.check_conditioning): refused above the
    limit (ConditioningError, one line) before any device opens; the band's warning is said once, by the
    workflow's own check (CopyStand.calibrate) before the light."""
    from dualrgb.app.workflow.stand.preflight import check_conditioning
    from dualrgb.core.vocabulary import lights_of

    check_conditioning(lights_of(preset), preset.mode, f"preset {preset.name}", stand, say=False)


def _stand_start(args: argparse.Namespace) -> Any:
    """The measured curves the stand fit starts from (app.workflow.calibration.stand_reoptimise.measured_start)."""
    from dualrgb.app.workflow.calibration.stand_reoptimise import measured_start

    return measured_start(args.camera_csv, args.stand_dir)


def _corner_grids(args: argparse.Namespace, mode: str, charts: dict) -> dict:
    """The grids ``--train-corners`` / ``--test-corners`` place (app.workflow.calibration.targets.corners_grid)."""
    from dualrgb.app.workflow.calibration.targets import corners_grid, parse_corners

    out = {}
    for role in ("train", "test"):
        text = getattr(args, f"{role}_corners", None)
        if text is None:
            continue
        if getattr(args, f"{role}_grid", None):
            raise ValueError(f"--{role}-grid and --{role}-corners both place the {role} target: give one")
        out[role] = corners_grid(parse_corners(text, f"--{role}-corners"), mode, role, charts.get(role))
    return out


def _lab_shorthand(args: argparse.Namespace, mode: str, charts: dict, grids: dict) -> tuple[dict, float]:
    """``--virtual-lab``: the lab's test target's width (as a person types it) unless given, and for a chart laid
    too small to be found in frames this size, its placement (as a person places it by hand), said in one line."""
    from dualrgb.app.lab.targets import LAB_TARGET_WIDTH_MM, too_small_to_find

    placed = dict(grids)
    for role, (grid, px) in too_small_to_find(mode, args.frame_size, charts).items():
        if role not in placed:
            placed[role] = grid
            print(f"note: the {'training' if role == 'train' else 'test'} chart's patches are {px:.1f} px across in "
                  f"{args.frame_size[0]}x{args.frame_size[1]} frames, too small to find: placed as the lab lays it",
                  file=sys.stderr)
    return placed, args.target_width_mm or LAB_TARGET_WIDTH_MM


def main(args: argparse.Namespace) -> int:
    check_device_options(args)                # before the heavy imports below
    preset, hdr, darks, flats = resolve(args)       # an unknown preset: refused before them too
    from dualrgb.app.warm_kernels import ensure_ready as ensure_kernels
    from dualrgb.app.workflow.calibration import charts as day_charts
    from dualrgb.app.workflow.calibration.targets import load_grid
    from dualrgb.app.workflow.stand.copystand import CopyStand, StandSettings
    from dualrgb.app.workflow.stand.defaults import DAY_WORKFLOW
    from dualrgb.app.workflow.stand.run_gate import check_session_run
    from dualrgb.app.workflow.stand.run_phases import calibration_clock

    mode = preset.mode
    stand_start = _stand_start(args)
    conditioning(preset, stand_start)                                     # before any device opens
    if args.stand_dir:
        from dualrgb.app.workflow.calibration.led_stand import load_stand, unstable_levels

        for line in unstable_levels(preset.sources, load_stand(args.stand_dir)):
            print(f"warning: {line}", file=sys.stderr)
    charts = day_charts.load_charts(chart_choices(args), mode)          # before any device opens
    grids = {k: load_grid(v, charts[k].layout if k in charts else None)
             for k, v in (("train", args.train_grid), ("test", args.test_grid)) if v}
    grids.update(_corner_grids(args, mode, charts))
    width_mm = args.target_width_mm
    if args.virtual_lab:                      # the shorthand: what a person at the lab's stand would give
        grids, width_mm = _lab_shorthand(args, mode, charts, grids)
    settings = StandSettings(settle_s=args.settle, dark_frames=darks, flat_frames=flats,
                             optimise_matrix=False if args.no_de_fit else None, ppi=args.ppi,
                             target_width_mm=width_mm, stand_start=stand_start, charts=charts)
    definition = {"workflow": DAY_WORKFLOW, "mode": mode, "preset": preset.name, "hdr": hdr,
                  "dark_frames": darks, "flat_frames": flats, "settle_s": args.settle,
                  **day_charts.definition(charts)}
    check_session_run(args.session, definition, None)       # another day's session: refused before the lab starts
    check_camera_request(args, args.session)                # --iso / --aperture: before the camera is set
    ensure_kernels()                          # first run: compiled here, before any device opens
    with open_devices(args, mode, charts=chart_choices(args)) as dev:
        check_session_run(args.session, definition, dev.camera)         # another day's session: nothing written
        with session_of_run(args.session, definition, dev.camera, {"mode": mode}) as session:
            clock = calibration_clock([], args.settle)           # time left from the measured phase costs
            stand = CopyStand(dev.camera, dev.sphere, session, stand=dev.stand, settings=settings,
                              progress=progress_printer(clock), prompt=ask_person, on_event=clock.saw)
            with timed(clock):
                profile = stand.calibrate(preset, hdr_auto=hdr == "auto", grids=grids)
    say_calibrated(args, profile, text_stream(args.json_path))
    write_json(args.json_path, CALIBRATE_FORMAT, {"calibration": str(profile.path), **profile.to_dict()})
    return 0
