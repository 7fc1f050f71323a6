"""session.json's JSON Schema: shipped in the package beside the others, a valid 2020-12 schema, and what
CaptureSession writes (created, its definition extended, originals recorded) follows it. The sessions the whole
workflows write are checked where they are made (tests/test_readme_day.py: the tutorial's day and film sessions;
tests/e2e/test_demo.py: the demo's)."""
from __future__ import annotations

import copy

import jsonschema
from session_schema import SCHEMA_FILE, problems, session_problems, session_schema

from dualrgb import resources
from dualrgb.core.session.capture_session import CaptureSession


def test_the_schema_is_packaged_and_valid():
    assert resources.path("schemas", SCHEMA_FILE).is_file()
    jsonschema.Draft202012Validator.check_schema(session_schema())


def _written(tmp_path):
    definition = {"workflow": "copy-stand", "mode": "reflective", "preset": "dual-RGB-PSO reflective", "hdr": "auto",
                  "dark_frames": 10, "flat_frames": 3, "settle_s": 0.2, "charts": {"train": "packaged"}}
    session = CaptureSession.create(tmp_path / "s", {"mode": "reflective"}, definition=definition)
    session.extend_definition(camera={"model": "D610", "serial": "1", "iso": 50, "aperture": 8.0})
    session.update_settings(originals={"ACC/1": {
        "identifier": "ACC/1", "title": "Öl auf Holz", "operator": "J. Doe", "notes": "", "mode": "reflective",
        "extra": {"Provenance": "x"}, "take": 1, "light_dose": {"on_s": 1.5, "lux_s": 138.0},
        "sidecar": "deliverables/ACC_1_8fec73f6/ACC_1_8fec73f6.json", "calibration": "calibration/cal-1.json"}})
    session.close()
    return tmp_path / "s"


def test_what_a_session_writes_follows_the_schema(tmp_path):
    folder = _written(tmp_path)
    assert session_problems(folder) == []


def test_the_schema_refuses_what_is_not_a_session(tmp_path):
    import json

    doc = json.loads((_written(tmp_path) / "session.json").read_text())
    for change, where in ((lambda d: d.update(format="dualrgb-delivery/1"), "format"),
                          (lambda d: d.pop("software"), "(top)"),
                          (lambda d: d["definition"].update(mode="film"), "definition/mode"),
                          (lambda d: d["originals"]["ACC/1"].pop("take"), "originals/ACC/1"),
                          (lambda d: d["originals"]["ACC/1"]["light_dose"].update(on_s=-1), "light_dose/on_s")):
        bad = copy.deepcopy(doc)
        change(bad)
        found = problems(bad)
        assert found and any(where in line for line in found), (where, found)
