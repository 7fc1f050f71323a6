"""``dualrgb simulate``: the light-source search of thesis chapters 5, 6 and 9 from the command line."""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from dualrgb.app.commands.options import calibration_source, count, input_file, number, seed, stand_dir
from dualrgb.app.json_output import add_json_option, write_json
from dualrgb.app.terminal_progress import TerminalProgress
from dualrgb.simulation.choices import DEFAULT_SPECTRAL_WEIGHT, METHODS, MODES, OBJECTIVES

log = logging.getLogger(__name__)


def _bins(text: str) -> tuple[int, ...]:
    try:
        bins = tuple(int(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"bins {text!r}: expected comma-separated integers like 3,3,4") from None
    if sum(bins) != 10 or any(b < 1 for b in bins):
        raise argparse.ArgumentTypeError(f"bins {text!r}: expected positive sizes adding up to the 10 LEDs")
    return bins


FORMAT = "dualrgb-simulation/1"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="search light-source pairs (halving PSO, exhaustive, PSO, GA, 3-channel)",
                       description="Simulate dual-RGB capture and search the sphere's light-source pairs. Default: "
                                   "successive halving over the thesis PSO with an L-BFGS-B polish, minimising "
                                   "the expected captured error (camera noise, reference uncertainty, LED drift, "
                                   "the sphere's level grid). --method pso --objective noise-free is the thesis' "
                                   "Algorithm 1 exactly.")
    p.add_argument("--mode", choices=MODES, default="reflective")
    p.add_argument("--method", choices=METHODS, default="halving",
                   help="halving (default: successive halving over PSO + L-BFGS-B polish), exhaustive (full "
                        "intensity), pso (thesis Algorithm 1), ga (Algorithm 2), three-channel (camera under D65)")
    p.add_argument("--objective", choices=OBJECTIVES, default="expected-captured",
                   help="expected-captured (default: expected captured mean dE00 of the training target), "
                        "noise-free (the thesis' cost), robust (mean over plausible worlds: LEDs, camera and "
                        "reference off by a few nm / %%), expected-per-pixel (the expected captured mean dE00 of "
                        "one pixel of each training patch, the matrix fitted on the patch means: as a master is "
                        "judged), spectral (for spectra: the expected captured RMSE of the "
                        "training target's spectra estimated by the Wiener method, reflectance or transmittance "
                        "factor pooled over patches and the mode's grid, 0.01 = 1 %%) or mixed (mean dE00 + "
                        "--spectral-weight x 100 x that RMSE)")
    p.add_argument("--per-pixel", action="store_true",
                   help="--objective expected-captured or robust: score one pixel of each patch instead of the "
                        "patch mean (every reported light set carries both figures either way)")
    p.add_argument("--spectral-weight", type=number(0.0, 100.0), default=DEFAULT_SPECTRAL_WEIGHT,
                   help=f"--objective mixed: the weight of the spectral RMSE in %% against mean dE00 (default "
                        f"{DEFAULT_SPECTRAL_WEIGHT:g}: 1 %% RMSE costs as much as {DEFAULT_SPECTRAL_WEIGHT:g} dE00)")
    p.add_argument("--reference-sd", type=number(0.0, 0.5), default=0.0,
                   help="relative uncertainty (gain) of the target's reference XYZ (default 0: the packaged "
                        "targets are exact; ~0.01 for a chart measured with a spectrophotometer)")
    p.add_argument("--drift-nm", type=number(0.0, 20.0, unit=" nm"), default=0.0,
                   help="sd of each LED's peak between captures in nm (default 0: no shift in the first 10 s on, "
                        "thesis 4.3.2; > 0 uses the float64 objective, ~20x slower)")
    p.add_argument("--min-level", type=number(0.0, 0.5), default=None,
                   help="the sphere's minimum stable level (a level is 0 or at least this; default: "
                        "dualrgb.simulation.sphere.SphereProperties, 0.01)")
    p.add_argument("--pixels", type=count(1), default=None,
                   help="pixels (superpixels) averaged per training patch (default: the virtual lab's 600x400 "
                        "frames)")
    p.add_argument("--seed", type=seed, default=0)
    p.add_argument("--top", type=count(1, 630), default=5, help="how many light sets to print and write (default 5)")
    add_json_option(p)
    p.add_argument("--preset-out", type=Path, help="save the best light pair as a preset JSON here")
    p.add_argument("--bins", type=_bins, default=(3, 3, 4), help="LED bins, shortest wavelengths first (3,3,4)")
    p.add_argument("--step", type=number(1.0, 50.0, unit=" nm"), default=None,
                   help="spectral step in nm (default: the parsimony study's choice for the mode, "
                        "resources/parsimony.json)")
    _add_data_options(p)
    p.set_defaults(func=main)


def _add_data_options(p: argparse.ArgumentParser) -> None:
    """The measured data that replace the packaged ones, and the stand to re-optimise for."""
    p.add_argument("--camera-csv", type=input_file, help="measured camera sensitivities (wavelength_nm,R,G,B)")
    p.add_argument("--leds-csv", type=input_file, help="measured LED spectra (wavelength_nm,LED1..LED10)")
    p.add_argument("--stand-dir", type=stand_dir, metavar="DIR",
                   help="a stand folder from `dualrgb measure leds` / `measure import-leds`: its measured LED "
                        "spectra (leds.csv), level -> output curves and minimum stable level replace the nominal ones "
                        "(an explicit --leds-csv / --min-level wins)")
    p.add_argument("--stand", type=calibration_source, metavar="CAL.json|SESSION",
                   help="re-optimise for the stand a calibration profile (or a session folder: its newest) fitted "
                        "(its stand model: the nominal "
                        "curves, the measurements given by --camera-csv / --leds-csv / --stand-dir / --min-level, and "
                        "the parameters fitted to its captures; refitted when the measurements differ from its own)")
    p.add_argument("--train-csv", type=input_file,
                   help="measured training target spectra (spectral CSV or CGATS / X-Rite file)")
    p.add_argument("--test-csv", type=input_file,
                   help="measured test target spectra (spectral CSV or CGATS / X-Rite file)")
    p.add_argument("--reference-xyz", choices=("eq-4.2", "astm-e308"), default="eq-4.2",
                   help="targets' reference XYZ: the thesis' eq 4.2 sum over the mode's grid (default) or ASTM E308 "
                        "(colour-science) over the measured spectra")


def main(args: argparse.Namespace) -> int:
    # imported here so that other subcommands start without loading colour-science and numba
    from dataclasses import replace

    from dualrgb.app.warm_kernels import OPTIMISERS, ensure_ready
    from dualrgb.simulation.datasets import default_setup
    from dualrgb.simulation.defaults import default_grid
    from dualrgb.simulation.runner import run

    if args.top < 1:
        raise ValueError(f"--top {args.top}: expected at least 1")
    if args.stand is not None:
        return _main_stand(args)
    _apply_stand(args)
    grid = default_grid(args.mode)                     # the parsimony study's grid for this mode
    if args.step is not None:
        grid = replace(grid, step=args.step)
    setup = default_setup(args.mode, grid, camera_csv=args.camera_csv,
                          leds_csv=args.leds_csv, train_csv=args.train_csv, test_csv=args.test_csv,
                          reference_xyz=args.reference_xyz)
    ensure_ready([OPTIMISERS])                         # first run: compiled once here, said in one line
    with TerminalProgress(f"simulate {args.method}") as progress:
        result = run(setup, args.method, seed=args.seed, top=args.top, bins=args.bins, objective=args.objective,
                     capture=_capture(args), progress=progress, spectral_weight=args.spectral_weight,
                     per_pixel=args.per_pixel)
    return _write(args, result, result.preset() if args.preset_out else None)


def _write(args: argparse.Namespace, result, preset) -> int:
    """The table on stdout, the JSON and the preset where asked."""
    from dualrgb.simulation.presets import save_preset
    from dualrgb.simulation.runner import format_table

    if args.json != "-":
        print(format_table(result))
    if args.json:
        if write_json(args.json, FORMAT, result.to_json()):
            print(f"wrote {args.json}", file=sys.stderr)
    if args.preset_out:
        save_preset(preset, args.preset_out)
        print(f"wrote preset {args.preset_out}", file=sys.stderr)
    return 0


def _main_stand(args: argparse.Namespace) -> int:
    """``--stand CAL.json``: the same search on the stand model (app.workflow.calibration.stand_reoptimise)."""
    from dataclasses import replace

    from dualrgb.app.cli_refusals import newest_calibration
    from dualrgb.app.workflow.calibration.profile import load_profile
    from dualrgb.app.workflow.calibration.stand_reoptimise import (
        Measurements,
        assemble,
        calibration_lights,
        reoptimise,
        stand_preset,
    )
    from dualrgb.simulation.defaults import default_grid

    profile = load_profile(newest_calibration(Path(args.stand)) if Path(args.stand).is_dir() else args.stand)
    model, notes = assemble(profile, Measurements.of(args.camera_csv, args.leds_csv, args.stand_dir, args.min_level))
    for line in notes:
        print(f"stand: {line}", file=sys.stderr)
    grid = default_grid(args.mode)                     # the parsimony study's grid for this mode
    if args.step is not None:
        grid = replace(grid, step=args.step)
    with TerminalProgress(f"simulate {args.method} (stand {profile.id})") as progress:
        result = reoptimise(model, args.mode, method=args.method, objective=args.objective, seed=args.seed,
                            top=args.top, capture=_capture(args), grid=grid,
                            targets={"train_csv": args.train_csv, "test_csv": args.test_csv,
                                     "reference_xyz": args.reference_xyz}, progress=progress, bins=args.bins,
                            spectral_weight=args.spectral_weight, incumbents=[calibration_lights(profile)])
    result.extra["stand"]["calibration"] = str(profile.path)
    return _write(args, result, stand_preset(result, model, f"{args.mode} for stand {profile.id}")
                  if args.preset_out else None)


def _apply_stand(args: argparse.Namespace) -> None:
    """``--stand-dir``: the measured LED spectra and minimum stable level, where not given explicitly."""
    if args.stand_dir is None:
        return
    from dualrgb.app.workflow.calibration.led_stand import load_stand

    stand = load_stand(args.stand_dir)
    if args.leds_csv is None and stand.leds_csv is not None:
        args.leds_csv = str(stand.leds_csv)
    if args.min_level is None and stand.min_stable_level is not None:
        args.min_level = stand.min_stable_level
    args.level_curves = stand.level_curves
    print(f"stand {stand.folder}: LED spectra {args.leds_csv or 'nominal'}, minimum stable level "
          f"{args.min_level if args.min_level is not None else 'nominal'}, level -> output "
          f"{'measured per LED' if stand.level_curves else 'proportional'}", file=sys.stderr)


def _capture(args: argparse.Namespace):
    """The capture model from the options (the virtual lab's for the mode, with the user's changes)."""
    from dataclasses import replace

    from dualrgb.simulation.capture_model import CaptureModel
    from dualrgb.simulation.sphere import SphereProperties

    cap = CaptureModel.virtual_lab(args.mode, reference_gain_sd=args.reference_sd, drift_sd_nm=args.drift_nm)
    curves = getattr(args, "level_curves", ())                # a stand folder's (_apply_stand)
    if args.min_level is not None or curves:
        cap = replace(cap, sphere=SphereProperties().measured(args.min_level, curves))
    if args.pixels is not None:
        cap = replace(cap, camera=replace(cap.camera, pixels_per_patch=args.pixels))
    return cap
