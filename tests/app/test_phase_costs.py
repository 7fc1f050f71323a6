"""Time left from measured phase costs (issue 42, "progress that moves"): the store of phase durations round-trips
and shrugs off a damaged file in one log line; the clock's time left uses the measured costs, is corrected by this
run's pace and records the phases a run went through. Every time is a fake (``now=``): no wall clock."""
from __future__ import annotations

import json
import logging

import pytest

from dualrgb.app.workflow.phase_costs import FORMAT, KEEP, Phase, PhaseClock, PhaseCosts
from dualrgb.app.workflow.stand.run_phases import (
    DARKS,
    PROCESSING,
    calibration_clock,
    calibration_phases,
    plan_seconds,
)
from dualrgb.core.messages import PlannedFrame, ProgressEvent

PHASES = [Phase("shoot", 0.0, 0.5, size=10, plan_s=50.0), Phase("process", 0.5, 0.8), Phase("report", 0.8, 1.0)]


def costs_with(tmp_path, runs: dict) -> PhaseCosts:
    store = PhaseCosts(tmp_path / "phase_costs.json")
    store.path.write_text(json.dumps({"format": FORMAT, "runs": runs}))
    return store


def run_through(clock: PhaseClock, times: list[tuple[float, float]], outcome: str = "done", end: float | None = None):
    """``times``: (fraction, now) progress calls after begin at 0; then the run's end at ``end``."""
    clock.begin(now=0.0)
    lefts = [clock.time_left(f, now=t) for f, t in times]
    clock.finish(outcome, now=end if end is not None else times[-1][1])
    return lefts


def test_the_store_round_trips_keeps_the_last_few_and_writes_its_folder(tmp_path):
    store = PhaseCosts(tmp_path / "deep" / "phase_costs.json")
    assert store.load() == {} and store.expected("calibration", PHASES[1]) is None
    for k in range(KEEP + 2):
        store.record("calibration", [(PHASES[0], 10.0 + k), (PHASES[1], 3.0 + k)])
    again = PhaseCosts(store.path).load()["calibration"]
    assert [s["seconds"] for s in again["process"]] == [3.0 + k for k in range(2, KEEP + 2)]   # the last KEEP
    assert all(s["size"] == 10 for s in again["shoot"]) and "size" not in again["process"][0]
    assert PhaseCosts(store.path).expected("calibration", PHASES[1]) == pytest.approx(3.0 + 4)   # the median
    # per frame for a phase that shoots frames: 20 frames now cost twice what 10 did
    twenty = Phase("shoot", 0.0, 0.5, size=20)
    assert store.expected("calibration", twenty) == pytest.approx(2 * (10.0 + 4))
    assert store.expected("another run", PHASES[1]) is None


@pytest.mark.parametrize("text", ["{not json", json.dumps({"format": "other/1", "runs": {}}),
                                  json.dumps({"format": FORMAT, "runs": {"calibration": {"x": [{"seconds": -1}]}}}),
                                  json.dumps({"format": FORMAT, "runs": []})])
def test_a_damaged_file_is_ignored_with_one_log_line_and_written_again(tmp_path, caplog, text):
    store = PhaseCosts(tmp_path / "phase_costs.json")
    store.path.write_text(text)
    with caplog.at_level(logging.WARNING, logger="dualrgb.app.workflow.phase_costs"):
        clock = PhaseClock("calibration", PHASES[1:], store)          # read when a run starts ...
        assert store.load() == {} and clock.expected_total_s() is None
        run_through(clock, [(0.6, 1.0), (0.8, 5.0)])                 # ... and again when it records
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1 and str(store.path) in lines[0] and "ignored" in lines[0], lines
    assert store.load() == {"calibration": {"process": [{"seconds": 5.0}], "report": [{"seconds": 0.0}]}}


def test_time_left_falls_back_to_the_plan_and_the_run_pace_when_nothing_is_measured(tmp_path):
    clock = PhaseClock("r", PHASES, PhaseCosts(tmp_path / "none.json"))
    assert clock.expected_total_s() is None                    # the processing has no estimate of its own yet
    clock.begin(now=0.0)
    left = clock.time_left(0.0, now=0.0)
    assert left is None                                        # nothing known of the processing, no pace yet
    # half way through the shooting at the plan's pace: 25 s of it left, the rest at the run's pace (50 s per 0.5)
    assert clock.time_left(0.25, now=25.0) == pytest.approx(25.0 + 100.0 * 0.5)


def test_time_left_uses_the_measured_costs_and_the_plan_estimate_is_their_sum(tmp_path):
    store = costs_with(tmp_path, {"r": {"shoot": [{"seconds": 20.0, "size": 10}], "process": [{"seconds": 30.0}],
                                        "report": [{"seconds": 40.0}, {"seconds": 44.0}, {"seconds": 99.0}]}})
    clock = PhaseClock("r", PHASES, store)
    assert clock.expected_total_s() == pytest.approx(20.0 + 30.0 + 44.0)      # the median of the report's
    clock.begin(now=0.0)
    assert clock.time_left(0.0, now=0.0) == pytest.approx(94.0)
    # the shooting took 20 s as measured: the rest as measured, not the run's pace (elapsed / fraction)
    assert clock.time_left(0.5, now=20.0) == pytest.approx(74.0)
    # the processing ran twice as long as measured: the report is expected twice as long too
    assert clock.time_left(0.8, now=20.0 + 70.0) == pytest.approx(44.0 * (90.0 / 50.0), rel=1e-6)


def test_the_current_phase_follows_its_own_sub_steps(tmp_path):
    store = costs_with(tmp_path, {"r": {"shoot": [{"seconds": 20.0, "size": 10}], "process": [{"seconds": 30.0}],
                                        "report": [{"seconds": 40.0}]}})
    clock = PhaseClock("r", PHASES, store)
    clock.begin(now=0.0)
    clock.time_left(0.5, now=20.0)
    clock.time_left(0.8, now=50.0)                           # on time so far
    # the report at figure 9 of 10 after 80 s (planned 40): its own pace says 8.9 s left, the cost says 0 left
    left = clock.time_left(0.8 + 0.2 * 0.9, now=130.0)
    assert left == pytest.approx(0.9 * (80.0 * 0.1 / 0.9) + 0.1 * 0.0)
    assert left > 0                                          # never a stuck "0 s" while figures are still drawn


def test_a_finished_run_records_its_phases_and_a_cancelled_one_only_those_it_left(tmp_path):
    store = PhaseCosts(tmp_path / "phase_costs.json")
    run_through(PhaseClock("r", PHASES, store), [(0.1, 5.0), (0.5, 12.0), (0.9, 20.0)], "done", end=26.0)
    got = store.load()["r"]
    assert {k: [s["seconds"] for s in v] for k, v in got.items()} == {"shoot": [12.0], "process": [8.0],
                                                                       "report": [6.0]}
    run_through(PhaseClock("r", PHASES, store), [(0.5, 30.0), (0.9, 40.0)], "cancelled", end=41.0)
    got = store.load()["r"]
    assert [s["seconds"] for s in got["shoot"]] == [12.0, 30.0] and [s["seconds"] for s in got["process"]] == [8, 10]
    assert len(got["report"]) == 1                           # the cancelled report phase was not left: unrecorded
    run_through(PhaseClock("r", PHASES, store, record=False), [(0.5, 1.0), (1.0, 2.0)], "done")
    assert len(store.load()["r"]["shoot"]) == 2                                   # a run that says nothing of the next


def test_the_calibration_phases_cover_the_run_and_take_the_plan_announced_after_auto_exposure(tmp_path):
    metering = [PlannedFrame("metering", 0.01, "L1", "open gate"), PlannedFrame("metering", 0.01, "L2", "open gate")]
    phases = calibration_phases(metering)
    assert phases[0].lo == 0.0 and phases[-1].hi == 1.0
    assert all(a.hi == pytest.approx(b.lo) for a, b in zip(phases, phases[1:], strict=False))   # no gap, no overlap
    names = [p.name for p in phases]
    assert names[:3] == ["auto-exposure", "darks", "flats"] and "processing: report" in names
    report = phases[names.index("processing: report")]
    assert PROCESSING[0] < report.lo < report.hi <= PROCESSING[1]
    darks = [PlannedFrame("dark", 0.5, "", "lens cap on")] * 4
    store = costs_with(tmp_path, {"calibration": {"darks": [{"seconds": 8.0, "size": 2}]}})
    clock = calibration_clock(metering, settle_s=0.0, overhead_s=1.0, costs=store)
    assert clock.phases[1].size is None and clock.phases[0].plan_s == pytest.approx(plan_seconds(metering, 0, 1))
    clock.saw(ProgressEvent(0, 0, "auto-exposure done", data={"plan": darks}))
    assert (clock.phases[1].name, clock.phases[1].size, (clock.phases[1].lo, clock.phases[1].hi)) == \
        ("darks", 4, DARKS)
    assert clock.phases[0].size == 2                           # auto-exposure's frames kept from the first plan
    assert clock._cost[1] == pytest.approx(16.0)                # 4 frames at the measured 4 s each
