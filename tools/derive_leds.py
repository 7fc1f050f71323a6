"""Derive the absolute LED table from the relative one: one source for the sphere's LED spectra.

``resources/leds/sphere10_relative.csv`` (thesis Table 4.2's relative peak values, shaped by
tools/generate_resources.py) is the source every simulated figure is computed with. The absolute table
(``sphere10_absolute.csv``: spectral radiance, W sr^-1 m^-2 nm^-1, for the light dose and the virtual
spectroradiometer) is that table times one constant: LED 2's absolute peak in Table 4.2 per relative unit (LED 2's
relative peak is 1). Before (issue 40) the absolute file was shaped from the table's own absolute column, whose ratios
differ from the rounded relative column by up to 3.8 % (LED 7: 0.0000795212 / 0.0275599 = 0.00289 against 0.003),
so the two packaged files described two spheres. ``python -m tools.derive_leds`` rewrites the absolute file;
``make resources`` runs it after tools.generate_resources; tests/simulation/test_led_tables.py checks the packaged
files agree.
"""
from __future__ import annotations

import logging
from pathlib import Path

from dualrgb.resources import path
from dualrgb.simulation.spectral_io import read_spectral_csv, write_spectral_csv

log = logging.getLogger(__name__)

LED2_ABSOLUTE_PEAK = 0.0275599      # W sr^-1 m^-2 nm^-1 (thesis Table 4.2, LED 2 at 448 nm: relative peak 1)


def derive(relative: Path, absolute: Path) -> None:
    """Write ``absolute`` = the ``relative`` table x :data:`LED2_ABSOLUTE_PEAK`, with the relative file's header
    plus what was done."""
    table = read_spectral_csv(relative)
    meta = {k: v for k, v in table.meta.items() if k not in ("title", "units", "generated_by")}
    write_spectral_csv(absolute, table.wavelengths, table.values * LED2_ABSOLUTE_PEAK, list(table.columns),
                       {"title": "10-LED sphere spectra, absolute", "units": "spectral radiance W sr^-1 m^-2 nm^-1",
                        **meta,
                        "derived_from": f"{relative.name} x {LED2_ABSOLUTE_PEAK:g} (LED 2's absolute peak, thesis "
                                        "Table 4.2, per relative unit): one source for both tables",
                        "generated_by": "tools/derive_leds.py (python -m tools.derive_leds)"})


def main() -> None:
    derive(path("leds", "sphere10_relative.csv"), path("leds", "sphere10_absolute.csv"))
    log.info("wrote %s", path("leds", "sphere10_absolute.csv"))


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO)
    main()
