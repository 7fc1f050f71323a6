"""Inputs that are wrong are refused before the light (issue 38 item 3): a chart file's unit is decided from the
whole file (a typed 5.0 among factors used to turn every value into percent, simulation/cgats.py), a percent file
is said in a warning line, and charts that hold nothing a calibration can use (all-zero, constant, a coloured
patch copied over another) are refused in one line naming the file, before any device opens (simulation/charts.py).
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from dualrgb.app.cli import main
from dualrgb.simulation.charts import read_chart
from dualrgb.simulation.datasets import default_setup

CC24 = Path(__file__).resolve().parents[1] / "data" / "charts" / "cc24_test.cie"
SG140 = CC24.with_name("sg140_layout.txt")
GRID = default_setup("reflective").grid


def _edited(path: Path, edit: Callable[[list[list[str]]], None]) -> Path:
    """The CC24 test chart with its data rows (``[name, value, ...]``) edited by ``edit``."""
    lines = CC24.read_text().splitlines()
    start, end = lines.index("BEGIN_DATA") + 1, lines.index("END_DATA")
    rows = [line.split() for line in lines[start:end]]
    edit(rows)
    path.write_text("\n".join(lines[:start] + [" ".join(r) for r in rows] + lines[end:]) + "\n")
    return path


def _set(row: int, column: int, value: str) -> Callable[[list[list[str]]], None]:
    def edit(rows: list[list[str]]) -> None:
        rows[row][column] = value
    return edit


def _percent(rows: list[list[str]]) -> None:
    for r in rows:
        r[1:] = [f"{100 * float(v):.4f}" for v in r[1:]]


def _zero_row(rows: list[list[str]]) -> None:
    rows[5][1:] = ["0"] * (len(rows[5]) - 1)


def _all_alike(rows: list[list[str]]) -> None:
    for r in rows[1:]:
        r[1:] = rows[0][1:]


def _copied_row(rows: list[list[str]]) -> None:
    rows[14][1:] = rows[6][1:]            # C3 (red) over A7 ... a coloured patch twice


# case -> (edit of the CC24 chart, what the one error line says)
REFUSED = {
    "one 5.0 among factors": (_set(9, 30, "5.0"), "cc24.cie:"),
    "a patch 0 everywhere": (_zero_row, "patch 'A6' is 0 at every wavelength"),
    "24 identical patches": (_all_alike, "its 24 patches used hold 1 different spectrum; a calibration needs at least "
                                         "3 independent colours"),
    "a coloured patch copied": (_copied_row, "hold the same coloured spectrum; a chart repeats only its neutral "
                                             "patches"),
}


@pytest.mark.fault("input")
@pytest.mark.parametrize("case", list(REFUSED))
def test_a_chart_that_cannot_calibrate_is_refused_before_any_device(tmp_path, capsys, monkeypatch, case):
    edit, says = REFUSED[case]
    chart = _edited(tmp_path / "cc24.cie", edit)
    opened = []
    monkeypatch.setattr("dualrgb.drivers.virtual.lab.VirtualLab.start", lambda self: opened.append(self))
    rc = main(["calibrate", "--virtual-lab", "--test-target", str(chart), "--session", str(tmp_path / "session")])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 1 and len(lines) == 1 and lines[0].startswith(f"dualrgb: error: {chart}"), err
    assert says in lines[0], lines[0]
    if case == "one 5.0 among factors":
        assert "values on both scales: patch B4 reaches 5 at 525 nm (1 patch above 2, as percent) while 23 of 24 " \
               "stay within 0-2 (as factors)" in lines[0], lines[0]
    assert opened == [] and not (tmp_path / "session").exists()


@pytest.mark.fault("input")
def test_a_percent_chart_is_read_as_percent_and_said_in_a_warning_line(tmp_path, caplog):
    percent = _edited(tmp_path / "cc24_percent.cie", _percent)
    with caplog.at_level(logging.WARNING, logger="dualrgb.simulation.cgats"):
        chart = read_chart(percent, GRID, role="test", mode="reflective")
    said = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert said == [f"{percent}: spectral values read as percent (0-100) and divided by 100: 24 of 24 patches reach "
                    f"above 2 (largest {100 * chart.target.measured.values.max():g})"], said
    assert chart.file.warnings == tuple(said)                         # recorded in the calibration's chart record
    factors = read_chart(CC24, GRID, role="test", mode="reflective")
    assert factors.file.warnings == ()                                 # factors: nothing to say
    assert np.allclose(chart.target.spectra, factors.target.spectra, atol=1e-6)


def test_a_percent_chart_with_very_dark_patches_names_them():
    from dualrgb.simulation.cgats import CgatsTable

    wl = [f"SPEC_{w}" for w in range(380, 790, 10)]
    rows = [["P1", *["80"] * len(wl)], ["P2", *["40"] * len(wl)], ["P3", *["1.5"] * len(wl)]]
    table = CgatsTable(["SAMPLE_ID", *wl], rows, source="dark.cie", row_lines=[10, 11, 12])
    spectra = table.spectral_table()
    assert np.allclose(spectra.values[:, 2], 0.015)
    assert table.warnings[-1].endswith("1 stay below 2 % (P3): very dark patches, or values given as factors? "
                                       "check them")


def test_the_sg_charts_repeated_neutral_border_is_no_copy():
    chart = read_chart(SG140, GRID, role="train", mode="reflective", layout="10x14")
    assert len(chart.used) == 140
