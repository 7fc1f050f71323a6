"""The user docs' commands run as written: the tutorial's copy-stand day (docs/tutorial/first-day.md) and the
how-to's own-charts block (docs/how-to/own-charts.md) are parsed out of the pages and run literally with bash
(tests/doc_blocks.py), on the virtual lab, the only addition being the --frame-size 240x160 the pages' text
allows; then the deliverables the day promises are checked, and every JSON the day wrote is parsed strictly (no NaN
or Infinity). README's short first day is a part of the tutorial's: each of its commands is one of the block's."""
from __future__ import annotations

import hashlib
import json
import os
import re
import shlex
import shutil
import sys
from pathlib import Path

import pytest
from dask_procs import stop_dask_on_port
from doc_blocks import block_names, dualrgb_prelude, fenced_block, run_block
from session_schema import session_problems

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
TUTORIAL = ROOT / "docs" / "tutorial" / "first-day.md"
OWN_CHARTS = ROOT / "docs" / "how-to" / "own-charts.md"
REDELIVERY = ROOT / "docs" / "how-to" / "redelivery.md"
VERIFY_BAG = ROOT / "docs" / "how-to" / "verify-bag.md"
FRAME = "240x160"


@pytest.fixture
def workdir(tmp_path):
    """A folder laid out like a checkout for the files README names (docs/, tests/data/)."""
    (tmp_path / "docs").mkdir()
    shutil.copy(ROOT / "docs" / "queue-example.csv", tmp_path / "docs")
    shutil.copytree(ROOT / "tests" / "data", tmp_path / "tests" / "data")
    env = {**os.environ, "DUALRGB_DATA_DIR": str(tmp_path / "data"), "PYTHONUNBUFFERED": "1"}
    return tmp_path, env


def strict_json_files(root: Path) -> list[Path]:
    """Every .json / .jsonl under ``root`` parsed with NaN / Infinity refused; returns the files."""
    def refuse(token: str) -> float:
        raise AssertionError(f"{token} in a JSON file")
    files = sorted(p for p in root.rglob("*") if p.suffix in (".json", ".jsonl") and p.is_file())
    for path in files:
        text = path.read_text(encoding="utf-8")
        for line in (text.splitlines() if path.suffix == ".jsonl" else [text]):
            if line.strip():
                try:
                    json.loads(line, parse_constant=refuse)
                except AssertionError as exc:
                    raise AssertionError(f"{path}: {exc}") from None
    return files


def test_the_pages_name_their_runnable_blocks():
    assert block_names(TUTORIAL) == ["copy-stand-day"] and block_names(OWN_CHARTS) == ["own-charts"]
    assert block_names(REDELIVERY) == ["redelivery", "redelivery-cluster"]
    assert block_names(VERIFY_BAG) == ["verify-and-bag"]
    assert "dualrgb calibrate --session day1 --virtual-lab" in fenced_block(TUTORIAL, "copy-stand-day")


def test_readmes_first_day_is_the_tutorials():
    """README's commands are run by the tutorial's test: every `dualrgb` line README shows is one of its lines."""
    tutorial = {line.strip() for line in fenced_block(TUTORIAL, "copy-stand-day").splitlines()}
    shown = [line.strip() for block in re.findall(r"```sh\n(.*?)```", README.read_text(encoding="utf-8"), re.S)
             for line in block.splitlines() if line.startswith("dualrgb ")]
    assert len(shown) >= 4
    assert [line for line in shown if line not in tutorial] == []


def test_readme_copy_stand_day_runs_as_written(workdir):
    root, env = workdir
    ran = run_block(TUTORIAL, "copy-stand-day", root, env=env, prelude=dualrgb_prelude(FRAME))
    assert len(ran) == 11
    score = ran[8].stdout.splitlines()                       # `dualrgb lab score day1`
    assert len(score) == 6 and all(": virtual truth (painting, full): dE00 mean " in line for line in score), score
    day = root / "day1" / "deliverables"
    for stem in ("ACC-123", "MBA-2003.4.1"):
        assert (day / stem / f"{stem}_srgb_16bit.tif").is_file() and (day / stem / f"{stem}.json").is_file()
    sidecars = sorted(day.glob("*/*.json"))
    delivered = {json.loads(p.read_text())["original"]["identifier"] for p in sidecars}
    assert delivered == {"ACC-123", "GM-1987/12", "GM-1987/13", "MBA-2003.4.1", "MBA-2003.4.2", "東博-A-1"}
    films = {json.loads(p.read_text())["original"]["identifier"]
             for p in (root / "films1" / "deliverables").glob("*/*.json")}
    assert films == {"東博-F-7"}                                   # the film row: only in the film session
    check = ran[2]
    assert "5 to shoot, 0 kept, 1 refused" in check.stdout and "row 7: 東博-F-7: refused" in check.stdout
    assert "queue-example.csv: row 7: 東博-F-7: transmissive original, reflective calibration" in ran[3].stderr
    assert "skipped 1 refused row: 7" in ran[3].stderr
    redelivered = {json.loads(p.read_text())["original"]["identifier"]
                   for p in (root / "redelivered").glob("*/*.json")}
    assert redelivered == delivered
    assert ran[7].stdout.strip().endswith("all match"), ran[7].stdout         # verify: exit 0 said so
    bagged = {p.parent.name for p in (root / "day1-bag" / "data").glob("*/*.json")}
    assert (root / "day1-bag" / "bagit.txt").is_file() and len(bagged) == len(delivered)
    assert "checks: ok" in ran[10].stdout                # calibration show
    for session in ("day1", "films1"):                    # session.json as its JSON Schema says (reference page)
        assert session_problems(root / session) == [], session
    _how_tos_run_on_the_day(root, env, delivered)


def _how_tos_run_on_the_day(root: Path, env: dict[str, str], delivered: set[str]) -> None:
    """The re-delivery and verify-and-bag how-tos' blocks, as written, on the tutorial's day (same folder)."""
    run_block(REDELIVERY, "redelivery", root, env=env, prelude=dualrgb_prelude(FRAME))
    half = [json.loads(p.read_text()) for p in (root / "day1-half").glob("*/*.json")]
    assert {d["original"]["identifier"] for d in half} == delivered
    assert {d["resolution"]["mode"] for d in half} == {"half"}
    assert {p.parent.name for p in (root / "day1-recal").glob("*/*.json")} == \
        {p.parent.name for p in (root / "day1" / "deliverables").glob("*/*.json")}
    assert list((root / "day1" / "deliverables").glob("*/previous/*/*.json"))      # the in-place run kept them
    _cluster_block_runs(root, env)
    ran = run_block(VERIFY_BAG, "verify-and-bag", root, env=env, prelude=dualrgb_prelude(FRAME))
    assert ran[0].stdout.strip().endswith("all match") and ran[1].stdout.strip().endswith("all match")
    assert "Contact-Name: J. Doe" in (root / "day1-archive" / "bag-info.txt").read_text(encoding="utf-8")
    assert len(strict_json_files(root)) > 20


def test_readme_own_charts_block_runs_as_written(workdir):
    root, env = workdir
    ran = run_block(OWN_CHARTS, "own-charts", root, env=env, prelude=dualrgb_prelude(FRAME))
    assert len(ran) == 2
    profile = json.loads(next((root / "day2" / "calibration").glob("cal-*.json")).read_text())
    assert profile["charts"]["train"]["file"] == "sg140_layout.txt"
    assert profile["charts"]["test"]["file"] == "cc24_test.cie"
    assert (root / "day2" / "deliverables" / "ACC-200" / "ACC-200_prophoto_16bit.tif").is_file()
    strict_json_files(root)


def _cluster_block_runs(root: Path, env: dict[str, str]) -> None:
    """The re-delivery how-to's cluster block, as written: --jobs 2 and a real Dask cluster (scheduler and two
    workers started in the background by the block) deliver the same files as each other."""
    prelude = f"export PATH={shlex.quote(str(Path(sys.executable).parent))}:$PATH\n" + dualrgb_prelude(FRAME)
    try:
        run_block(REDELIVERY, "redelivery-cluster", root, env={**env, "SOURCE_DATE_EPOCH": "1767225600"},
                  prelude=prelude)
    finally:
        stop_dask_on_port(8786)
    local, cluster = root / "recal-local", root / "recal-cluster"
    assert {p.name for p in local.iterdir()} == {"day1", "films1"}
    assert _digests(local) == _digests(cluster) and len(_digests(local)) > 20


def _digests(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}
