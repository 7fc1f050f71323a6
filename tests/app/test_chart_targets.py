"""A stand's own chart on a real stand (issue 27): the grid is placed by its four corners for any rows x columns
(the layout gives them when the grid file does not), the chart's patches are sampled in the cells their names
give, and a chart without a grid is found in the frames later (app.processing.chart_detect, from its geometry)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dualrgb.app.processing.patches import PatchGrid
from dualrgb.app.workflow.charts import ChartChoice, load_charts
from dualrgb.app.workflow.targets import load_grid, target_spec
from dualrgb.app.workflow.vocabulary import Subject

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
