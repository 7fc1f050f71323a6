"""Progress that moves (issue 42 point 3): a calibration in the window reports the report's figures one by one, its
time left comes from the measured phase costs (the plan's estimate too), the run's phases are recorded for the
next one, and no time left stays after the run."""
from __future__ import annotations

import json
import re
from pathlib import Path

from dualrgb.app.workflow.phase_costs import FORMAT
from dualrgb.app.workflow.stand.run_phases import calibration_phases
from dualrgb.core.engine import RUN_PROGRESS
from dualrgb.core.messages import PlannedFrame
from tests.gui.conftest import connect_devices, quick_calibrate

FIGURE = re.compile(r"report: figure (\d+) of (\d+), \S")


def _earlier_costs(folder) -> dict:
    """Every calibration phase measured once before (fake durations: 1 s per frame, 2 s per other phase)."""
    plan = [PlannedFrame(role, 0.01, "L", note) for role, note in
            (("metering", ""), ("dark", ""), ("flat", ""), ("target", "training target"), ("target", "test target"))]
    runs = {p.name: [{"seconds": 1.0, "size": 1} if p.size else {"seconds": 2.0}] for p in calibration_phases(plan)}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "phase_costs.json").write_text(json.dumps({"format": FORMAT, "runs": {"calibration": runs}}))
    return runs


def test_a_calibration_says_each_report_figure_and_its_time_left_from_measured_costs(qtbot, make_window,
                                                                                      user_data_dir):
    before = _earlier_costs(user_data_dir)
    w = make_window()
    connect_devices(qtbot, w)
    quick_calibrate(qtbot, w)
    view, profile = w.capture.view, w.ctx.workspace.calibration
    assert view.outcome == "done" and profile is not None
    run = [e for e in view.events if e.data.get(RUN_PROGRESS)]
    figures = [(int(m[1]), int(m[2]), e.step) for e in run if (m := FIGURE.match(e.message))]
    report = Path(profile.statistics["report"]).parent
    pngs = sorted(report.glob("*.png"))
    # one progress event per figure written, counting 1..n, the bar moving with them
    assert [k for k, _n, _s in figures] == list(range(1, len(pngs) + 1)) and len(pngs) >= 8
    assert {n for _k, n, _s in figures} == {len(pngs)}
    steps = [s for *_, s in figures]
    assert steps == sorted(steps) and steps[0] < steps[-1]
    # every phase was measured before: the time left is known all along, and the plan's estimate is theirs
    assert all(e.time_left_s is not None for e in run), [e.message for e in run if e.time_left_s is None][:3]
    assert "as measured on earlier runs" in view.summary.text(), view.summary.text()
    assert view.time_left.text() == ""                                   # nothing stale once the run has ended
    # this run's phases are recorded beside the earlier ones
    after = json.loads((user_data_dir / "phase_costs.json").read_text())["runs"]["calibration"]
    assert set(after) == set(before) and all(len(after[name]) == 2 for name in before), after
