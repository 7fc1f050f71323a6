"""tools.suite_timing (docs/notes/issue-26-suite.md): a stage timed into the JSON, with busy processes beside it."""
from __future__ import annotations

import json
import subprocess

from tools.suite_timing import BIN, ROOT, main


def test_a_stage_is_timed_with_the_load_asked_for(tmp_path):
    out = tmp_path / "suite.json"
    lint = subprocess.run([str(BIN / "ruff"), "check", "."], cwd=ROOT, capture_output=True).returncode
    assert main(["--out", str(out), "--stages", "ruff", "--load", "1"]) == lint       # ruff's exit is the stage's
    doc = json.loads(out.read_text())
    assert doc["format"] == "dualrgb-suite-timing/1" and doc["software"]["dualrgb"]
    ruff = doc["stages"]["ruff"]
    assert list(doc["stages"]) == ["ruff"] and ruff["exit"] == lint and ruff["busy_processes"] == 1
    assert ruff["command"].endswith("ruff check .") and ruff["last_line"]
    assert 0 < ruff["wall_s"] == doc["total_wall_s"] and 0 <= ruff["cpu_s"] == doc["total_cpu_s"]
    assert ruff["load_1min_max"] >= ruff["load_1min_mean"] > 0
