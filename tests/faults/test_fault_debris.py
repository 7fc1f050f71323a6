"""Kills leave nothing behind for long (issue 28 item 5): the staging folders and temp files of a writer killed
with SIGKILL are named by it (common.debris) and removed by the next writer of that session or deliverables
folder; those of a writer still running are left alone."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from fault_rigs import ROOT
from workflow_profiles import make_profile

from dualrgb.app.cli import main
from dualrgb.common.debris import stage_name, sweep
from dualrgb.core.session.capture_session import CaptureSession

pytestmark = pytest.mark.fault("session integrity")

SHAPE = (800, 1200)          # large enough that writing the deliverables takes a while


def _debris(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.name.endswith((".tmp", ".new")))


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


@pytest.fixture(scope="module")
def delivered(tmp_path_factory):
    root = tmp_path_factory.mktemp("debris")
    os.environ.setdefault("DUALRGB_DATA_DIR", str(root / "user-data"))
    profile = make_profile(root / "cal", shape=SHAPE).path
    session = root / "session"
    rc = main(["capture", "--virtual-lab", "--calibration", str(profile), "--id", "ACC-1", "--session", str(session),
               "--force", "--settle", "0", "--frame-size", f"{SHAPE[1]}x{SHAPE[0]}"])
    assert rc == 0
    return session, profile


def _kill_during_delivery(session: Path, profile: Path) -> list[str]:
    """Run `dualrgb process` and SIGKILL it once its staging folder holds a file; the debris it left."""
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    proc = subprocess.Popen([sys.executable, "-m", "dualrgb", "process", str(session), "--calibration", str(profile)],
                            cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deliverables = session / "deliverables"
    deadline = time.monotonic() + 120
    try:
        while proc.poll() is None and time.monotonic() < deadline:
            stages = [p for p in deliverables.glob(f".ACC-1.{proc.pid}.*.new") if any(p.iterdir())]
            if stages:
                os.kill(proc.pid, signal.SIGKILL)
                break
            time.sleep(0.001)
    finally:
        proc.kill()
        proc.wait()
    return _debris(session)


def test_a_delivery_killed_midway_leaves_nothing_after_the_next_run(delivered):
    session, profile = delivered
    for _ in range(5):                                   # the kill must land while the files are written
        left = _kill_during_delivery(session, profile)
        if left:
            break
    assert any(name.endswith(".new") for name in left), "the kill never landed during the delivery"
    assert main(["process", str(session), "--calibration", str(profile)]) == 0
    assert _debris(session) == []
    assert (session / "deliverables" / "ACC-1" / "ACC-1.json").is_file()


def test_a_writer_reopening_the_session_removes_what_dead_writers_left(tmp_path):
    session = CaptureSession.create(tmp_path / "s", {"test": "debris"})
    session.close()
    dead = _dead_pid()
    report = tmp_path / "s" / "calibration" / "report"
    report.mkdir(parents=True)
    stale = [report / f".dn_validation.png.{dead}.tmp", tmp_path / "s" / f".session.json.{dead}.tmp"]
    stage = tmp_path / "s" / "deliverables" / f".ACC-2.{dead}.0a1b2c3d.new"
    stage.mkdir(parents=True)
    (stage / "ACC-2_srgb_16bit.img").write_bytes(b"x" * 100)
    live = tmp_path / "s" / "deliverables" / stage_name("ACC-3")          # this process: still writing
    live.mkdir()
    for p in stale:
        p.write_bytes(b"partial")
    CaptureSession.open(tmp_path / "s").close()
    assert _debris(tmp_path / "s") == [str(live.relative_to(tmp_path / "s"))]


def test_a_staging_folder_without_an_owner_is_reported_not_removed(tmp_path, caplog):
    old = tmp_path / ".ACC-4.0a1b2c3d.new"
    old.mkdir()
    found = sweep(tmp_path)
    assert found.unowned == [old] and old.exists() and not found.removed
    assert "an unfinished delivery from an older dualrgb" in caplog.text
