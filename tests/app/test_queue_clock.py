"""The queue's time left (issue 42 point 3, app.workflow.day.queue_clock): the originals still to shoot times one
original's measured cost, the last delivery (overlapped by nothing) added, corrected by this queue's pace; one bar
for the whole queue; each original's phases recorded in the calibration's store; a person's time left out. Fake
durations only: a fake clock and costs written into the store."""
from __future__ import annotations

import json

import pytest

from dualrgb.app.workflow.day.queue_clock import SHOOTING_SHARE, QueueClock, queue_time_left
from dualrgb.app.workflow.phase_costs import FORMAT, PhaseCosts
from dualrgb.app.workflow.stand.run_phases import ORIGINAL_RUN, original_clock, original_phases
from dualrgb.core.messages import PlannedFrame

# an original: a metering frame per light, one frame per light (2 + 2 frames)
PLAN = [PlannedFrame("metering", 0.01, "L1", "metering A"), PlannedFrame("metering", 0.01, "L2", "metering A"),
        PlannedFrame("original", 0.01, "L1", "A"), PlannedFrame("original", 0.01, "L2", "A")]


class FakeTime:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class FakeTimeline:
    def __init__(self) -> None:
        self.spans: list[tuple[float, float, str]] = []


def _store(tmp_path, metering=1.0, frame=2.0, delivery=5.0) -> PhaseCosts:
    """Earlier originals measured: ``metering`` and ``frame`` seconds per frame, ``delivery`` seconds each."""
    runs = {"metering": [{"seconds": 2 * metering, "size": 2}], "frames": [{"seconds": 2 * frame, "size": 2}],
            "delivery": [{"seconds": delivery}]}
    path = tmp_path / "phase_costs.json"
    path.write_text(json.dumps({"format": FORMAT, "runs": {ORIGINAL_RUN: runs}}))
    return PhaseCosts(path)


def test_the_estimate_is_the_shooting_left_plus_the_last_delivery():
    # pipelined: each original costs the longer of its shooting and the delivery beside it, plus the last delivery
    assert queue_time_left([10, 10, 10], 4.0, 3) == pytest.approx(34.0)
    assert queue_time_left([10, 10, 10], 15.0, 3) == pytest.approx(3 * 15 + 15)
    # sequential: every shooting and every delivery one after the other
    assert queue_time_left([10, 10, 10], 4.0, 3, pipelined=False) == pytest.approx(42.0)
    # this queue's pace scales the measured costs
    assert queue_time_left([10, 10], 4.0, 2, shoot_pace=2.0, deliver_pace=0.5) == pytest.approx(20 + 20 + 2)
    # all shot: the delivery in flight, less what it has run
    assert queue_time_left([], 4.0, 1, delivering_s=1.0) == pytest.approx(3.0)
    assert queue_time_left([], 4.0, 0) == 0.0
    # a delivery due whose cost nothing says: no figure rather than a wrong one
    assert queue_time_left([10], None, 1) is None


def test_a_queue_of_two_from_measured_costs_corrected_by_its_pace(tmp_path):
    costs, now = _store(tmp_path), FakeTime()
    clock = QueueClock([PLAN, PLAN], costs, now=now)
    clock.begin()
    assert clock.shoot_cost(0) == pytest.approx(2 * 1.0 + 2 * 2.0)          # 6 s to shoot, 5 s to deliver
    assert clock.expected_total_s() == pytest.approx(6 + 6 + 5)             # the plan's "about ..., as measured"
    assert clock.time_left(0.0) == pytest.approx(6 + 6 + 5)
    clock.started(0)
    now.t += 2.0
    q = clock.fraction(0.1)                                   # metering done
    now.t += 6.0
    q2 = clock.fraction(0.4)                                  # half of its shooting
    assert 0 < q < q2 == pytest.approx(SHOOTING_SHARE * 0.5 / 2)
    assert clock.time_left(q2) == pytest.approx(max(3, 5) + 6 + 5)
    now.t += 4.0                                              # 12 s shooting: twice its cost
    clock.shot(0)
    assert clock.fraction(0.0) >= q2                          # the bar never goes back
    assert clock.time_left(0.5) == pytest.approx(2 * 6 + 5)   # the next one at this queue's pace
    clock.started(1)
    now.t += 2.0
    clock.fraction(0.1)
    now.t += 3.0
    clock.delivered(0, 10.0)                                  # delivered at twice its cost too
    assert clock.time_left(0.5) == pytest.approx(max(6 * 0.875 * 2, 10) + 10)
    now.t += 10.0
    clock.fraction(0.8)
    clock.shot(1)
    now.t += 4.0
    assert clock.time_left(0.9) == pytest.approx(10 - 4)      # the last delivery, less what it has run
    clock.delivered(1, 9.0)
    assert clock.fraction(1.0) == 1.0 and clock.time_left(1.0) == 0.0
    clock.finish("done")
    # both originals' phases recorded beside the earlier one: metering, frames, delivery
    runs = costs.load()[ORIGINAL_RUN]
    assert [s["seconds"] for s in runs["metering"]] == [2.0, 2.0, 2.0]
    assert [s["seconds"] for s in runs["frames"]] == [4.0, 10.0, 13.0]
    assert [s["seconds"] for s in runs["delivery"]] == [5.0, 10.0, 9.0]


def test_a_persons_placement_is_not_the_computers_time(tmp_path):
    costs, now, timeline = _store(tmp_path), FakeTime(), FakeTimeline()
    clock = QueueClock([PLAN], costs, now=now)
    clock.time.timeline = timeline
    clock.started(0)
    now.t += 1.0
    timeline.spans.append((now.t, now.t + 300.0, "prompt"))    # the operator took 5 min to place it
    now.t += 301.0
    clock.fraction(0.1)
    now.t += 4.0
    clock.shot(0)
    clock.delivered(0, 5.0)
    runs = costs.load()[ORIGINAL_RUN]
    assert runs["metering"][-1]["seconds"] == pytest.approx(2.0) and runs["frames"][-1]["seconds"] == 4.0


def test_without_a_measured_delivery_the_queue_learns_from_its_own(tmp_path):
    costs, now = PhaseCosts(tmp_path / "none.json"), FakeTime()
    clock = QueueClock([PLAN, PLAN, PLAN], costs, now=now, overhead_s=1.0)
    assert clock.time_left(0.0) is None                      # nothing measured: no delivery cost to say
    assert clock.expected_total_s() is None                  # and no "as measured" estimate
    clock.started(0)
    now.t += 3.0
    clock.shot(0)
    clock.started(1)
    clock.delivered(0, 7.0)
    assert clock.deliver_cost() == 7.0 and clock.time_left(0.3) is not None


def test_a_single_original_has_its_time_left_from_its_phases(tmp_path):
    costs, now = _store(tmp_path), FakeTime()
    assert [p.name for p in original_phases(PLAN)] == ["metering", "frames", "delivery"]
    clock = original_clock(PLAN, costs=costs, now=now)
    clock.begin()
    assert clock.expected_total_s() == pytest.approx(2 + 4 + 5)
    assert clock.time_left(0.0) == pytest.approx(11.0)
    now.t += 2.0
    assert clock.time_left(0.1) == pytest.approx(4 + 5)
