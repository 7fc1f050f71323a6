"""``dualrgb simulate``: the light-source search of thesis chapters 5, 6 and 9 from the command line."""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from app.commands.options import count, input_file, number, seed
from app.json_output import add_json_option, write_json
from app.terminal_progress import TerminalProgress
from simulation.choices import METHODS, MODES

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
    p = sub.add_parser("simulate", help="search light-source pairs (three-channel, exhaustive, PSO, GA)",
                       description="Simulate dual-RGB capture and search the sphere's light-source pairs.")
    p.add_argument("--mode", choices=MODES, default="reflective")
    p.add_argument("--method", choices=METHODS, default="exhaustive")
    p.add_argument("--seed", type=seed, default=0)
    p.add_argument("--top", type=count(1, 630), default=5, help="how many light sets to print and write (default 5)")
    add_json_option(p)
    p.add_argument("--preset-out", type=Path, help="save the best light pair as a preset JSON here")
    p.add_argument("--bins", type=_bins, default=(3, 3, 4), help="LED bins, shortest wavelengths first (3,3,4)")
    p.add_argument("--step", type=number(1.0, 50.0, unit=" nm"), default=None,
                   help="spectral step in nm (default: the parsimony study's choice, resources/parsimony.json: 10)")
    p.add_argument("--camera-csv", type=input_file, help="measured camera sensitivities (wavelength_nm,R,G,B)")
    p.add_argument("--leds-csv", type=input_file, help="measured LED spectra (wavelength_nm,LED1..LED10)")
    p.add_argument("--train-csv", type=input_file,
                   help="measured training target spectra (spectral CSV or CGATS / X-Rite file)")
    p.add_argument("--test-csv", type=input_file, help="measured test target spectra (spectral CSV or CGATS / X-Rite file)")
    p.add_argument("--reference-xyz", choices=("eq-4.2", "astm-e308"), default="eq-4.2",
                   help="targets' reference XYZ: the thesis' eq 4.2 sum over 410-780 nm (default) or ASTM E308 "
                        "(colour-science) over the measured spectra")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    # imported here so that other subcommands start without loading colour-science and numba
    from simulation.datasets import default_setup
    from simulation.grid import SpectralGrid
    from simulation.presets import save_preset
    from simulation.runner import format_table, run
    from simulation.studies.parsimony import load_defaults

    step = args.step if args.step is not None else float(load_defaults()["spectral_step_nm"])
    setup = default_setup(args.mode, SpectralGrid(410.0, 780.0, step), camera_csv=args.camera_csv,
                          leds_csv=args.leds_csv, train_csv=args.train_csv, test_csv=args.test_csv,
                          reference_xyz=args.reference_xyz)
    if args.top < 1:
        raise ValueError(f"--top {args.top}: expected at least 1")
    with TerminalProgress(f"simulate {args.method}") as progress:
        result = run(setup, args.method, seed=args.seed, top=args.top, bins=args.bins, progress=progress)
    if args.json != "-":
        print(format_table(result))
    if args.json:
        if write_json(args.json, FORMAT, result.to_json()):
            print(f"wrote {args.json}", file=sys.stderr)
    if args.preset_out:
        save_preset(result.preset(), args.preset_out)
        print(f"wrote preset {args.preset_out}", file=sys.stderr)
    return 0
