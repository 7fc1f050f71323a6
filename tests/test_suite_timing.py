"""tools.suite_timing (docs/notes/issue-26-suite.md): a stage timed into the JSON, with busy processes beside it."""
from __future__ import annotations

import json
import subprocess

from tools.suite_timing import BIN, ROOT, main, module_seconds


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


def test_module_seconds_sums_each_modules_tests():
    output = ("===== slowest durations =====\n"
              "150.25s setup    tests/e2e/test_a.py::test_one\n"
              "10.00s call     tests/e2e/test_a.py::test_one\n"
              "99.50s call     tests/test_b.py::test_two[x-y]\n"
              "0.75s teardown tests/e2e/test_a.py::test_three\n"
              "(12 durations < 0.005s hidden.)\n")
    assert module_seconds(output) == {"tests/e2e/test_a.py": 161.0, "tests/test_b.py": 99.5}
    assert module_seconds(output, top=1) == {"tests/e2e/test_a.py": 161.0}


def test_xdist_keeps_the_longest_modules_first(request):
    """pytest-xdist's --loadscope-reorder (its default) would sort the modules by their number of tests and start
    the 4-test stand study last; tests/conftest.py turns it off so LONGEST_FIRST holds."""
    top = ROOT / "tests" / "conftest.py"          # (the module name conftest may be another folder's)
    conftest = next(p for p in request.config.pluginmanager.get_plugins() if getattr(p, "__file__", None) == str(top))
    assert getattr(request.config.option, "loadscopereorder", False) is False
    assert conftest.LONGEST_FIRST[0] == "e2e/test_copystand.py" and "e2e/test_stand.py" in conftest.LONGEST_FIRST[:4]
