"""``dualrgb measure``: measuring the stand before trusting any simulation (thesis chapter 4): the camera's
spectral sensitivity with a monochromator (``measure csrf``), the LEDs' spectra, level linearity and warm-up
drift with a spectroradiometer (``measure leds`` / ``measure import-leds``). A command group: each module in
:data:`MEASURE_MODULES` adds its subcommands with ``register(measure_subparsers)``, so the measurements stay
independent of each other."""
from __future__ import annotations

import argparse
import importlib
import logging

log = logging.getLogger(__name__)

MEASURE_MODULES = (
    "dualrgb.app.commands.measure_csrf",
    "dualrgb.app.commands.measure_leds",
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("measure", help="measure the stand: camera sensitivity (csrf), LED spectra, level linearity, "
                                       "warm-up drift",
                       description="Measure the copy stand (thesis chapter 4) and write what the simulation can "
                                   "use instead of the nominal model.")
    measure_sub = p.add_subparsers(dest="measure_command", metavar="WHAT")
    measure_sub.required = True
    for name in MEASURE_MODULES:
        importlib.import_module(name).register(measure_sub)
