"""``dualrgb measure``: measuring the stand itself (the camera's spectral sensitivity, ...).

Each measurement is a module in :data:`MEASURE_MODULES` with its own ``register(measure_sub)`` adding its
subcommand, so the measurements stay independent of each other.
"""
from __future__ import annotations

import argparse
import importlib
import logging

log = logging.getLogger(__name__)

MEASURE_MODULES = (
    "app.commands.measure_csrf",
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("measure", help="measure the stand: the camera's spectral sensitivity (csrf)",
                       description="Measurements of the copy stand's own instruments.")
    measure_sub = p.add_subparsers(dest="measurement", metavar="MEASUREMENT")
    measure_sub.required = True
    for name in MEASURE_MODULES:
        importlib.import_module(name).register(measure_sub)
