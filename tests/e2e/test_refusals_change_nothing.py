"""A refusal changes nothing (issue 43): every refusal ``capture``, ``calibrate``, ``process`` and ``import`` can
make without a real device (on the virtual lab), run against one calibrated session, leaves the session folder
exactly as it was (every path and its SHA-256); the refused-then-corrected capture in the same session delivers;
the same identifier delivered again says so and names --reshoot; an unknown option names the closest one."""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

FRAME = ["--frame-size", "96x64", "--settle", "0"]
ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}


def dualrgb(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "dualrgb", *args], capture_output=True, text=True, env=ENV,
                          timeout=900)


def tree(folder: Path) -> dict[str, str]:
    """Every path under ``folder`` (folders too) -> the SHA-256 of its bytes ('dir' for a folder)."""
    return {str(p.relative_to(folder)): ("dir" if p.is_dir() else hashlib.sha256(p.read_bytes()).hexdigest())
            for p in sorted(folder.rglob("*"))}


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    """A session calibrated on the virtual lab at 96x64 (the fastest calibration), with an empty raw folder and a
    roles file naming a missing file for import's refusal."""
    root = tmp_path_factory.mktemp("refusals")
    r = dualrgb("calibrate", "--session", str(root / "day"), "--virtual-lab", "--dark-frames", "1",
                "--flat-frames", "1", "--no-de-fit", *FRAME)
    assert r.returncode == 0, r.stderr[-3000:]
    (root / "raw").mkdir()
    (root / "roles.csv").write_text("file,role,light,identifier\nmissing.dng,original,1,ACC-9\n", encoding="utf-8")
    (root / "queue.csv").write_text("identifier,mode\nACC-7,reflective\nACC-8,transmissive\n", encoding="utf-8")
    return root


def _refusals(root: Path) -> dict[str, list[str]]:
    day = str(root / "day")
    lab = ["--virtual-lab", *FRAME]
    return {
        "capture: frames of another size": ["capture", "--session", day, "--id", "ACC-1", "--virtual-lab",
                                            "--frame-size", "128x96", "--settle", "0"],
        "capture: a camera with the virtual lab": ["capture", "--session", day, "--id", "ACC-1", *lab,
                                                   "--camera", "auto"],
        "capture: an unknown option": ["capture", "--sesion", day, "--id", "ACC-1", *lab],
        "capture: a rendering at full resolution": ["capture", "--session", day, "--id", "ACC-1", *lab,
                                                    "--render-illuminant", "A"],
        "capture: a missing calibration": ["capture", "--session", day, "--id", "ACC-1", *lab,
                                           "--calibration", str(root / "nope.json")],
        "capture: an original of the other mode": ["capture", "--session", day, "--id", "ACC-1", *lab,
                                                   "--mode", "transmissive"],
        "capture: an exposure over the light-on cap": ["capture", "--session", day, "--id", "ACC-1",
                                                       "--virtual-lab", "--frame-size", "96x64", "--settle", "5"],
        "capture: a queue with a refused row": ["capture", "--session", day, "--queue", str(root / "queue.csv"),
                                                *lab],
        "capture: another world": ["capture", "--session", day, "--id", "ACC-1", *lab, "--world", "aged-leds"],
        "calibrate: frames of another size": ["calibrate", "--session", day, "--virtual-lab", "--frame-size",
                                              "128x96", "--settle", "0"],
        "calibrate: another mode": ["calibrate", "--session", day, *lab, "--mode", "transmissive"],
        "calibrate: an unknown preset": ["calibrate", "--session", day, *lab, "--preset", "no-such-preset"],
        "calibrate: a missing chart file": ["calibrate", "--session", day, *lab, "--train-target",
                                            str(root / "nope.txt")],
        "calibrate: a camera with the virtual lab": ["calibrate", "--session", day, *lab, "--port", "/dev/null"],
        "process: a rendering at full resolution": ["process", day, "--render-illuminant", "A"],
        "process: a missing calibration": ["process", day, "--calibration", str(root / "nope.json")],
        "process: nothing captured yet": ["process", day],
        "import: a roles file naming a missing file": ["import", str(root / "raw"), "--roles",
                                                       str(root / "roles.csv"), "--session", day],
    }


def test_every_refusal_leaves_the_session_as_it_was(day):
    session = day / "day"
    before = tree(session)
    ran = {}
    for what, argv in _refusals(day).items():
        r = dualrgb(*argv)
        ran[what] = r
        assert r.returncode != 0, f"{what}: not refused\n{r.stdout[-2000:]}{r.stderr[-2000:]}"
        assert "Traceback" not in r.stderr, f"{what}: {r.stderr[-3000:]}"
        assert tree(session) == before, f"{what}: the session changed\n{r.stderr[-2000:]}"
    assert "did you mean --session?" in ran["capture: an unknown option"].stderr
    assert "--camera auto with --virtual-lab" in ran["capture: a camera with the virtual lab"].stderr
    assert "128x96 px" in ran["capture: frames of another size"].stderr
    assert "the session was made with other settings" in ran["calibrate: frames of another size"].stderr


def test_a_refused_capture_then_the_corrected_one_delivers_in_the_same_session(day):
    session = day / "day"
    refused = dualrgb("capture", "--session", str(session), "--id", "ACC-2", "--virtual-lab", "--frame-size",
                      "128x96", "--settle", "0")
    assert refused.returncode == 1 and "128x96 px" in refused.stderr
    r = dualrgb("capture", "--session", str(session), "--id", "ACC-2", "--virtual-lab", *FRAME)
    assert r.returncode == 0, r.stderr[-3000:]
    sidecar = session / "deliverables" / "ACC-2" / "ACC-2.json"
    assert json.loads(sidecar.read_text(encoding="utf-8"))["original"]["identifier"] == "ACC-2"
    assert "ACC-2" in (session / "session.log").read_text(encoding="utf-8")       # the run's log in the session
    again = dualrgb("capture", "--session", str(session), "--id", "ACC-2", "--virtual-lab", *FRAME)
    assert again.returncode == 0, again.stderr[-3000:]
    said = [line for line in again.stderr.splitlines() if "already in the session" in line]
    assert len(said) == 1 and "--reshoot" in said[0], again.stderr[-3000:]
