"""The mode rule and the queue's plan (issue 27), Qt-free: an original of the other mode is refused (one line
naming it and what to do) unless forced, and the override text is what the sidecar and QA line say; the plan
lists every row to shoot, kept (delivered in the session) or refused with its reason."""
from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from dualrgb.app.workflow.day.queue_csv import read_queue_csv
from dualrgb.app.workflow.day.queue_plan import KEPT, REFUSED, SHOOT, plan_queue
from dualrgb.app.workflow.stand.mode_rule import ModeMismatch, check_mode
from dualrgb.core.metadata import Original

PROFILE = SimpleNamespace(mode="reflective", id="cal-1")


@pytest.mark.fault("input")
def test_the_mode_rule_refuses_unless_forced():
    film = Original("F-1", mode="transmissive")
    assert check_mode(Original("P-1"), PROFILE) == ""
    with pytest.raises(ModeMismatch) as info:
        check_mode(film, PROFILE)
    assert str(info.value) == ("F-1: transmissive original, reflective calibration cal-1: capture it with a "
                               "transmissive calibration (dualrgb calibrate --mode transmissive), or --force to use "
                               "this one")
    assert check_mode(film, PROFILE, force=True) == ("mode overridden (--force): transmissive original with "
                                                     "reflective calibration cal-1, colour not characterised for it")


class _Session:
    def __init__(self, originals: dict, path: Path):
        self.settings = {"originals": originals}
        self.path = path


def test_the_plan_lists_rows_to_shoot_kept_and_refused(tmp_path):
    path = tmp_path / "q.csv"
    path.write_text("identifier,title,mode\nA-1,ok,\nF-1,film,transmissive\nB-2,\x01,\nK-1,kept,\n",
                    encoding="utf-8")
    sidecar = tmp_path / "K-1.json"
    sidecar.write_text(json.dumps({"format": "dualrgb-delivery/1", "original": {"identifier": "K-1"}}))
    plan = plan_queue(read_queue_csv(path), PROFILE, session=_Session({"K-1": {"sidecar": str(sidecar)}}, tmp_path))
    states = [(r.row, r.identifier, r.state) for r in plan.rows]
    assert states == [(2, "A-1", SHOOT), (3, "F-1", REFUSED), (4, "B-2", REFUSED), (5, "K-1", KEPT)]
    assert plan.summary() == "q.csv: 4 rows with calibration cal-1: 1 to shoot, 1 kept, 2 refused"
    assert plan.rows[2].line() == ("row 4: B-2: refused (column 'title': control character U+0001 at character 1 "
                                   "is not allowed)")
    assert [o.identifier for o in plan.to_shoot] == ["A-1"]
    forced = plan_queue(read_queue_csv(path), PROFILE, force=True, reshoot=True)
    assert [(r.identifier, r.state) for r in forced.rows if r.state == SHOOT] == [("A-1", SHOOT), ("F-1", SHOOT),
                                                                                 ("K-1", SHOOT)]
    assert forced.rows[1].reason.startswith("mode overridden (--force)")
    assert json.loads(json.dumps(forced.to_dict()))["rows"][1]["state"] == SHOOT
