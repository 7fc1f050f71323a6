"""``dualrgb measure leds`` and ``dualrgb measure import-leds``: the sphere's LEDs from spectroradiometer readings
(thesis 4.3): the spectra at full level, the level -> output curve (finely at the low end) and the warm-up drift,
written as a stand folder (app/workflow/led_stand.py) that ``simulate --stand-dir`` takes.

    dualrgb measure leds --virtual-lab [--world W] --out DIR [--leds 1,2] [--warmup-leds all|none|1,4,10]
    dualrgb measure import-leds READINGS... --out DIR
"""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from dualrgb.app.commands.options import add_world_option, input_file, leds, number, numbers, seed

log = logging.getLogger(__name__)

MAX_WARMUP_MIN = 59.5          # the sphere's longest lit period is one hour, less the margin


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("leds", help="measure each LED's spectrum, level linearity and warm-up drift",
                       description="Each LED alone at a series of PWM levels (finely from 0.2 %% to 5 %%), then held "
                                   "on at full level with spectra every --interval-s for --warmup-min; analysed "
                                   "into a stand folder (leds.csv, levels.csv, stand.json, figures) with the "
                                   "instrument's files under readings/. Needs a spectroradiometer driver: for now "
                                   "the virtual lab's (with a real instrument, take the readings with its "
                                   "software and run `dualrgb measure import-leds`). No original on the stand: "
                                   "a warm-up keeps one LED lit up to an hour (the sphere itself holds the limit).")
    p.add_argument("--virtual-lab", action="store_true", help="the virtual lab's sphere and spectroradiometer")
    add_world_option(p)
    p.add_argument("--out", type=Path, required=True, help="the stand folder to write")
    p.add_argument("--leds", type=leds(), default=tuple(range(1, 11)), help="LEDs to measure (default all)")
    p.add_argument("--levels", type=numbers(0.0, 1.0), default=None,
                   help="PWM levels, comma-separated (default 0, 0.2 %%..5 %% finely, then up to 1)")
    p.add_argument("--warmup-leds", type=leds(words=("all", "none")), default=tuple(range(1, 11)),
                   help="LEDs to hold on for the warm-up series: all (default), none or e.g. 1,4,10")
    p.add_argument("--warmup-min", type=number(0.1, MAX_WARMUP_MIN, unit=" min"), default=59.0,
                   help="warm-up length per LED in minutes (default 59)")
    p.add_argument("--interval-s", type=number(1.0, 600.0, unit=" s"), default=60.0,
                   help="seconds between warm-up spectra (default 60)")
    p.add_argument("--step-nm", type=number(0.5, 10.0, unit=" nm"), default=1.0,
                   help="the spectroradiometer's sampling, 380-780 nm by this (default 1)")
    p.add_argument("--seed", type=seed, default=0, help="instrument and lab noise seed")
    p.set_defaults(func=main)
    q = sub.add_parser("import-leds", help="a real spectroradiometer's LED readings -> a stand folder",
                       description="Read spectroradiometer files (spectral CGATS .ti3 / ArgyllCMS .sp, or spectral "
                                   "CSV), each reading named LED<n>_level<x> (LED n alone at PWM level x) or "
                                   "LED<n>_t<seconds> (a warm-up reading at full level) as its SAMPLE_ID, CSV "
                                   "column or file name; analyse them into a stand folder.")
    q.add_argument("readings", nargs="+", type=input_file, metavar="READINGS", help="reading files")
    q.add_argument("--out", type=Path, required=True, help="the stand folder to write")
    q.add_argument("--tolerance", type=number(0.001, 0.5), default=0.05,
                   help="departure from proportional output still counted as stable (default 0.05)")
    q.set_defaults(func=import_main)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.lab.led_bench import measure_virtual
    from dualrgb.app.sequences.led_measurement import DEFAULT_LEVELS, LedMeasurementPlan
    from dualrgb.app.terminal_progress import TerminalProgress
    from dualrgb.drivers.virtual.spectroradiometer import RadiometerSettings

    if not args.virtual_lab:
        raise ValueError("measure leds drives a spectroradiometer, and only the virtual lab's has a driver: use "
                         "--virtual-lab, or take the readings with your instrument's software and run "
                         "`dualrgb measure import-leds`")
    plan = LedMeasurementPlan(leds=args.leds, levels=args.levels or DEFAULT_LEVELS, warmup_leds=args.warmup_leds,
                              warmup_s=60.0 * args.warmup_min, interval_s=min(args.interval_s, 60 * args.warmup_min))
    print(f"dualrgb: {plan.light_mode()}", file=sys.stderr)
    with TerminalProgress("measure leds", lines=True) as progress:
        result, files = measure_virtual(args.out, args.world, plan, RadiometerSettings(step_nm=args.step_nm),
                                        args.seed, progress)
    _print(result, args.out)
    return 0


def import_main(args: argparse.Namespace) -> int:
    from dualrgb.app.workflow.led_stand import import_readings

    result, _files = import_readings(args.readings, args.out, args.tolerance)
    _print(result, args.out)
    return 0


def _print(result, out: Path) -> None:
    print(f"{'LED':>3} {'peak nm':>8} {'FWHM nm':>8} {'dead band':>9} {'knee':>6} {'exp':>5} {'stable':>7} "
          f"{'drift nm':>8} {'tau min':>7}")
    print(f"{'':>3} {'':>8} {'':>8} {'(fitted low-level response)':>29} {'':>7} {'at end':>8}")
    for led, r in sorted(result.leds.items()):
        shape, fit = r.shape or {}, (r.levels or {}).get("fit") or {}
        drift = (r.warmup or {}).get("fit") or {}

        def cell(d: dict, key: str, w: int, fmt: str, scale: float = 1.0) -> str:
            return f"{d[key] * scale:>{w}{fmt}}" if d.get(key) is not None else f"{'-':>{w}}"
        print(f"{led:>3} {cell(shape, 'peak_nm', 8, '.2f')} {cell(shape, 'fwhm_nm', 8, '.2f')} "
              f"{cell(fit, 'dead_band', 9, '.4f')} {cell(fit, 'knee', 6, '.3f')} {cell(fit, 'exponent', 5, '.2f')} "
              f"{cell(fit, 'min_stable_level', 7, '.4f')} {cell(drift, 'shift_at_end_nm', 8, '.2f')} "
              f"{cell(drift, 'tau_s', 7, '.1f', 1 / 60)}")
    level = result.min_stable_level
    print(f"minimum stable level {level:.4f}" if level is not None else "minimum stable level: not measured")
    print(f"stand folder: {out} (simulate --stand-dir {out})")

