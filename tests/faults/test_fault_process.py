"""``dualrgb process`` delivers every original it can (issue 28 item 9): a damaged frame of one original, or a
folder that holds another original's files, stops that original only; the others are delivered, the ones that
could not be are listed, and the command exits 1."""
from __future__ import annotations

import json

import pytest
from workflow_profiles import make_profile

from dualrgb.app.cli import main
from dualrgb.core.session.capture_session import CaptureSession

pytestmark = pytest.mark.fault("session integrity")


@pytest.fixture
def two_originals(tmp_path, capsys):
    profile = make_profile(tmp_path / "cal", shape=(64, 96)).path
    session = tmp_path / "session"
    for identifier in ("ACC-1", "ACC-2", "ACC-3"):
        assert main(["capture", "--virtual-lab", "--calibration", str(profile), "--id", identifier, "--session",
                     str(session), "--force", "--settle", "0", "--frame-size", "96x64"]) == 0
    capsys.readouterr()
    return session, profile


def _frame_of(session, identifier: str):
    s = CaptureSession.open(session, readonly=True)
    return next(s.file_path(e) for e in s.entries() if e.role == "original" and identifier in (e.step_id or ""))


def test_a_damaged_frame_stops_its_original_only(two_originals, capsys, tmp_path):
    session, profile = two_originals
    frame = _frame_of(session, "ACC-1")
    frame.write_bytes(frame.read_bytes()[:-100] + b"\0" * 100)            # damaged after it was recorded
    (session / "deliverables" / "ACC-3" / "ACC-3.json").write_text(json.dumps(
        {"format": "dualrgb-delivery/1", "original": {"identifier": "someone else"}}))   # not ACC-3's any more
    rc = main(["process", str(session), "--calibration", str(profile), "--json", str(tmp_path / "p.json")])
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert rc == 1 and "Traceback" not in err
    assert out.startswith("ACC-2: ") and "ACC-1" not in out
    assert lines[-3].startswith(f"ACC-1: not delivered: {frame}: ") and "resume the session to shoot it again" \
        in lines[-3]
    assert lines[-2].startswith("ACC-3: not delivered: ") and "someone else" in lines[-2]
    assert lines[-1] == ("dualrgb: error: 2 of 3 originals not delivered (listed above: ACC-1, ACC-3); the others "
                         "were delivered")
    doc = json.loads((tmp_path / "p.json").read_text())
    assert [o["identifier"] for o in doc["originals"]] == ["ACC-2"]
    assert [o["identifier"] for o in doc["not_delivered"]] == ["ACC-1", "ACC-3"]


def test_a_session_folder_whose_name_is_not_utf8_captures_and_processes(tmp_path, capsys):
    """A folder named in another encoding (Latin-1 'u-umlaut'): was 'damaged raw data (UnicodeEncodeError)'."""
    import os
    from pathlib import Path

    root = Path(tmp_path) / os.fsdecode(b"sitzung-\xfc")
    profile = make_profile(root / "cal", shape=(64, 96)).path
    args = ["--calibration", str(profile)]
    assert main(["capture", "--virtual-lab", *args, "--id", "ACC-1", "--session", str(root / "s"), "--force",
                 "--settle", "0", "--frame-size", "96x64"]) == 0
    assert main(["process", str(root / "s"), *args]) == 0
    sidecar = root / "s" / "deliverables" / "ACC-1" / "ACC-1.json"
    assert json.loads(sidecar.read_bytes())["session"] == str(root / "s")         # the exact path, escaped
    assert "sitzung-\\udcfc" in (root / "s" / "session.log").read_text(encoding="utf-8")   # named, escaped
