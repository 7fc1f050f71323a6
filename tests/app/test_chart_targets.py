"""A stand's own chart on a real stand (issue 27): the grid is placed by its four corners for any rows x columns
(the layout gives them when the grid file does not), the chart's patches are sampled in the cells their names
give, and a chart without a grid is found in the frames later (app.processing.chart_detect, from its geometry)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dualrgb.app.processing.patches import PatchGrid
from dualrgb.app.workflow.calibration.charts import ChartChoice, load_charts
from dualrgb.app.workflow.calibration.targets import load_grid, target_spec
from dualrgb.core.vocabulary import Subject

CHARTS = Path(__file__).resolve().parents[1] / "data" / "charts"


@pytest.fixture(scope="module")
def charts():
    return load_charts({"train": ChartChoice(str(CHARTS / "sg140_layout.txt"), "10x14", "A2,A3"),
                        "test": ChartChoice(str(CHARTS / "cc24_test.cie"))}, "reflective")


def test_the_grid_takes_the_charts_layout(tmp_path, charts):
    path = tmp_path / "grid.json"
    path.write_text(json.dumps({"corners": [[10, 10], [150, 10], [150, 110], [10, 110]]}))
    grid = load_grid(path, charts["train"].layout)
    assert (grid.rows, grid.cols) == (10, 14)
    spec = target_spec("reflective", Subject.target("train"), grid, chart=charts["train"])
    assert len(spec.names) == 138 and spec.layout == (10, 14)
    assert spec.cells[spec.names.index("B1")] == 1 and spec.cells[spec.names.index("A4")] == 42
    values = np.arange(140, dtype=float)                 # a stand-in per cell: what sample_target indexes
    assert values[spec.cell_indices()][spec.names.index("N10")] == 139


@pytest.mark.fault("input")
def test_a_chart_without_grid_is_found_later_and_a_wrong_grid_refused(charts):
    sg = target_spec("reflective", Subject.target("train"), None, chart=charts["train"])     # detection later
    assert sg.grid is None and sg.geometry is not None and sg.geometry.name == "ColorChecker Digital SG"
    spec = target_spec("reflective", Subject.target("test"), None, chart=charts["test"])
    assert spec.grid is None and len(spec.names) == 24 and spec.geometry.name == "ColorChecker Classic"
    wrong = PatchGrid(np.array([[0, 0], [60, 0], [60, 40], [0, 40]]), 6, 4)
    with pytest.raises(ValueError, match="the grid has 24 cells but the target 138 patches|chart's layout is 10 x 14"):
        target_spec("reflective", Subject.target("train"), wrong, chart=charts["train"])


def test_corners_place_the_chart_from_its_geometry(tmp_path, charts):
    from dualrgb.app.workflow.calibration.targets import corners_grid, parse_corners

    sensor = parse_corners("100,60,500,60,500,340,100,340")
    assert sensor.tolist() == [[100, 60], [500, 60], [500, 340], [100, 340]]
    path = tmp_path / "corners.json"
    path.write_text(json.dumps({"corners": sensor.tolist()}))
    assert np.array_equal(parse_corners(str(path)), sensor)
    grid = corners_grid(sensor, "reflective", "train", charts["train"])          # the SG, in stack pixels
    assert (grid.rows, grid.cols) == (10, 14) and grid.cell_boxes is not None
    assert np.allclose(grid.corners, (sensor + 0.5) / 2 - 0.5)
    film = corners_grid(sensor, "transmissive", "train")                          # the packaged IT8.7/1
    assert film.present().sum() == 288 and film.centres()[287][1] > film.centres()[263][1]   # the grey scale below


@pytest.mark.fault("input")
@pytest.mark.parametrize("args, message", [
    (["--train-corners", "1,2,3"], "--train-corners '1,2,3': expected 8 numbers x1,y1,x2,y2,x3,y3,x4,y4"),
    (["--test-corners", "0,0,10,10,10,0,0,10"], "the test target's corners"),
    (["--test-corners", "nosuch.json"], "nosuch.json"),
    (["--train-corners", "0,0,9,0,9,9,0,9", "--train-grid", "GRID"], "--train-grid and --train-corners both place"),
])
def test_bad_corners_are_one_line_before_any_device_opens(tmp_path, capsys, monkeypatch, args, message):
    from dualrgb.app import cli

    grid = tmp_path / "grid.json"
    grid.write_text(json.dumps({"corners": [[0, 0], [9, 0], [9, 9], [0, 9]], "rows": 4, "cols": 6}))
    monkeypatch.setattr("dualrgb.app.commands.calibrate.open_devices",
                        lambda *a, **k: pytest.fail("a device was opened"))
    rc = cli.main(["calibrate", "--virtual-lab", "--session", str(tmp_path / "s"),
                   *[str(grid) if a == "GRID" else a for a in args]])
    err = capsys.readouterr().err
    assert rc == 1 and len(err.splitlines()) == 1 and message in err, err
