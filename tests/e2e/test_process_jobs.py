"""``dualrgb process`` at archive scale (issue 41): many sessions, each original one task, run here, on worker
processes (``--jobs 2``) or on a real Dask cluster (``dask scheduler`` + two ``dask worker``): every delivered file
byte for byte the serial run's; a killed run resumed keeps what it finished and does the rest; a task that fails
transiently is tried once more, one that fails for its own reason is reported without stopping the others."""
from __future__ import annotations

import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from import_folders import tree

from dualrgb.app.workflow.delivery.redelivery_jobs import (
    RedeliveryOptions,
    RedeliveryTask,
    TaskResult,
    run_tasks,
)

FRAME = ["--frame-size", "96x64", "--settle", "0"]
EPOCH = "1767225600"                   # 2026-01-01T00:00:00Z: the run's one delivery time, in every file
ENV = {**os.environ, "PYTHONUNBUFFERED": "1", "SOURCE_DATE_EPOCH": EPOCH}
BIN = Path(sys.executable).parent


def dualrgb(*args: str, ok: bool = True, env: dict | None = None) -> subprocess.CompletedProcess:
    r = subprocess.run([sys.executable, "-m", "dualrgb", *args], capture_output=True, text=True, env=env or ENV,
                       timeout=1200)
    if ok:
        assert r.returncode == 0, r.stderr[-3000:]
    return r


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """Two sessions of two originals each, both captured with the first's calibration (passed with --calibration:
    the second's session.json names a calibration outside its folder, never used from there), and a serial
    re-delivery of both as the reference."""
    root = tmp_path_factory.mktemp("jobs")
    s1, s2 = root / "s1", root / "s2"
    dualrgb("calibrate", "--session", str(s1), "--virtual-lab", "--dark-frames", "1", "--flat-frames", "1",
            "--no-de-fit", "--json", str(root / "cal.json"), *FRAME)
    cal = json.loads((root / "cal.json").read_text())["calibration"]
    for session, ids in ((s1, ("A-1", "A-2")), (s2, ("B-1", "B-2"))):
        for ident in ids:
            dualrgb("capture", "--session", str(session), "--calibration", cal, "--id", ident, "--virtual-lab",
                    *FRAME)
    dualrgb("process", str(s1), str(s2), *calibrated(root), "--out", str(root / "serial"),
            "--json", str(root / "serial.json"))
    return root, s1, s2


def calibrated(root: Path) -> list[str]:
    return ["--calibration", json.loads((root / "cal.json").read_text())["calibration"]]


def test_serial_run_delivers_every_original_of_every_session(sessions):
    root, s1, s2 = sessions
    doc = json.loads((root / "serial.json").read_text())
    assert sorted(o["identifier"] for o in doc["originals"]) == ["A-1", "A-2", "B-1", "B-2"]
    assert {p.name for p in (root / "serial").iterdir()} == {"s1", "s2"}       # one folder per session
    sidecar = json.loads(Path(doc["originals"][0]["sidecar"]).read_text(encoding="utf-8"))
    assert sidecar["created_at"] == "2026-01-01T00:00:00+00:00"                 # the run's time, not a worker's


def test_jobs_2_delivers_the_serial_bytes(sessions):
    root, s1, s2 = sessions
    r = dualrgb("process", str(s1), str(s2), *calibrated(root), "--out", str(root / "jobs2"), "--jobs", "2",
                "--json", str(root / "jobs2.json"))
    assert tree(root / "jobs2") == tree(root / "serial")
    workers = {o["worker"] for o in json.loads((root / "jobs2.json").read_text())["originals"]}
    assert len(workers) >= 1 and all(str(os.getpid()) not in w for w in workers)
    assert "stderr" not in r.stdout


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def dask_cluster():
    """A real Dask cluster on this machine: ``dask scheduler`` and two ``dask worker`` processes."""
    pytest.importorskip("distributed")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = str(BIN / "dask")
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=ENV)]
    try:
        for _ in range(2):
            procs.append(subprocess.Popen([dask, "worker", address, "--nworkers", "1", "--nthreads", "1",
                                           "--no-dashboard"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                          env=ENV))
        from distributed import Client

        with Client(address, timeout=120) as client:
            client.wait_for_workers(2, timeout=600)          # a hang guard: workers start in seconds
        yield address
    finally:
        for p in reversed(procs):
            p.send_signal(signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                p.kill()


def test_dask_cluster_delivers_the_serial_bytes(sessions, dask_cluster):
    root, s1, s2 = sessions
    dualrgb("process", str(s1), str(s2), *calibrated(root), "--out", str(root / "dask"), "--scheduler", dask_cluster,
            "--json", str(root / "dask.json"))
    assert tree(root / "dask") == tree(root / "serial")
    workers = {o["worker"] for o in json.loads((root / "dask.json").read_text())["originals"]}
    assert len(workers) == 2                                  # both workers took originals


def test_a_killed_run_resumes_with_what_is_left(sessions):
    root, s1, s2 = sessions
    out = root / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "dualrgb", "process", str(s1), str(s2), *calibrated(root),
                             "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=ENV)
    assert proc.stdout is not None
    first = proc.stdout.readline()                            # the first original's result line
    proc.kill()
    proc.wait(timeout=60)
    assert re.match(r"s1: A-1: ", first), first
    r = dualrgb("process", str(s1), str(s2), *calibrated(root), "--out", str(out), "--json",
                str(root / "resumed.json"))
    doc = json.loads((root / "resumed.json").read_text())
    assert [k["identifier"] for k in doc["kept"]] == ["A-1"]
    assert sorted(o["identifier"] for o in doc["originals"]) == ["A-2", "B-1", "B-2"]
    assert "already delivered with this calibration and options, kept" in r.stdout
    assert tree(out) == tree(root / "serial")


def test_a_changed_file_is_delivered_again_not_kept(sessions):
    root, s1, s2 = sessions
    out = root / "changed"
    shutil.copytree(root / "serial", out)
    tif = next((out / "s1").rglob("*_srgb_16bit.tif"))
    data = bytearray(tif.read_bytes())
    data[-10] ^= 0xFF
    tif.write_bytes(bytes(data))
    dualrgb("process", str(s1), str(s2), *calibrated(root), "--out", str(out), "--json", str(root / "changed.json"))
    changed = json.loads(next(tif.parent.glob("*.json")).read_text(encoding="utf-8"))["original"]["identifier"]
    doc = json.loads((root / "changed.json").read_text())
    assert [o["identifier"] for o in doc["originals"]] == [changed]
    assert len(doc["kept"]) == 3
    assert tree(out / "s1" / tif.parent.name / "previous") != {}            # the damaged set kept aside


def test_a_session_without_frames_is_refused_before_any_delivery(sessions, tmp_path):
    root, s1, _ = sessions
    r = dualrgb("process", str(s1), str(tmp_path / "nowhere"), *calibrated(root), "--out", str(tmp_path / "out"),
                ok=False)
    assert r.returncode != 0 and "nowhere" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "out").exists()


class FlakyOnce:
    """An executor whose first try of task 'B' fails as a lost worker would."""

    name = "flaky"

    def __init__(self):
        self.tries: dict[str, int] = {}

    def map(self, tasks):
        for t in tasks:
            self.tries[t.identifier] = self.tries.get(t.identifier, 0) + 1
            if t.identifier == "B" and self.tries["B"] == 1:
                yield TaskResult(t, "failed", reason="worker lost: killed", transient=True)
            elif t.identifier == "C":
                yield TaskResult(t, "failed", reason="frames damaged")
            else:
                yield TaskResult(t, "delivered", qa=f"{t.identifier} ok")


def test_a_transient_failure_is_tried_once_more_and_an_own_failure_reported():
    opts = RedeliveryOptions()
    tasks = [RedeliveryTask("s", ident, opts) for ident in ("A", "B", "C")]
    executor = FlakyOnce()
    seen: list[str] = []
    results = run_tasks(tasks, executor, on_result=lambda r: seen.append(r.task.identifier))
    by = {r.task.identifier: r for r in results}
    assert executor.tries == {"A": 1, "B": 2, "C": 1}
    assert by["B"].status == "delivered" and by["B"].attempts == 2
    assert by["C"].status == "failed" and by["C"].attempts == 1
    assert sorted(seen) == ["A", "B", "C"]


def test_a_session_whose_calibration_lies_outside_it_is_refused_naming_it(sessions, tmp_path):
    root, s1, s2 = sessions
    r = dualrgb("process", str(s2), "--out", str(tmp_path / "out"), ok=False)
    assert r.returncode != 0 and "outside the session folder" in r.stderr and "--calibration" in r.stderr
    assert not (tmp_path / "out").exists()
