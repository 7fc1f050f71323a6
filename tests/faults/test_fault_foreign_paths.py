"""Paths in session.json are relative to the session folder and never resolved outside it (issue 38 item 4): a copy
of a session whose calibration arrays were removed was processed with the *original* session's calibration (exit 0,
its sidecar naming the original's file). Now a session records its own files relative to its folder
(core.session.paths), a copy uses only its own, and a calibration outside the folder is passed explicitly."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from workflow_profiles import make_profile

from dualrgb.app.cli import main
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.session.paths import deliverable, inside, record

LAB_SHAPE = (64, 96)


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    """A session calibrated in its own folder (the profile in <session>/calibration) with one original delivered."""
    root = tmp_path_factory.mktemp("foreign")
    session = root / "orig" / "day1"
    CaptureSession.create(session, {}).close()                  # a session, then its calibration in its folder
    profile = make_profile(session / "calibration", shape=LAB_SHAPE).path
    assert main(["capture", "--virtual-lab", "--calibration", str(profile), "--id", "ACC-1", "--session",
                 str(session), "--force", "--settle", "0", "--frame-size", "96x64"]) == 0
    return session, profile


def _settings(session: Path) -> dict:
    return json.loads((session / "session.json").read_text())


def _copy(session: Path, where: Path) -> Path:
    copy = where / "copy" / session.name
    shutil.copytree(session, copy)
    return copy


def test_a_session_records_its_own_files_relative_to_its_folder(shot):
    session, _ = shot
    recorded = _settings(session)["originals"]["ACC-1"]
    assert recorded["calibration"] == "calibration/cal-test.json"
    assert recorded["sidecar"] == "deliverables/ACC-1/ACC-1.json"


def _rewrite_original(session: Path, **fields: str) -> None:
    doc = _settings(session)
    doc["originals"]["ACC-1"].update(fields)
    (session / "session.json").write_text(json.dumps(doc))


@pytest.mark.fault("session integrity")
@pytest.mark.parametrize("recorded", ["relative", "absolute (an older session)"])
def test_a_copied_session_without_its_calibration_arrays_never_uses_the_originals(shot, tmp_path, capsys, recorded):
    session, profile = shot
    copy = _copy(session, tmp_path)
    if recorded != "relative":                      # as sessions recorded it before: the original's absolute path
        _rewrite_original(copy, calibration=str(profile))
    (copy / "calibration" / "cal-test.npz").unlink()
    before = sorted(p.name for p in (copy / "deliverables" / "ACC-1").iterdir())
    rc = main(["process", str(copy)])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 1 and lines[-1].startswith("dualrgb: error: ") and "Traceback" not in err, err
    assert f"{copy / 'calibration' / 'cal-test.npz'}: the calibration's arrays are missing" in lines[-1], lines[-1]
    assert str(session) not in err                                    # the original session is never named
    assert sorted(p.name for p in (copy / "deliverables" / "ACC-1").iterdir()) == before      # nothing delivered


@pytest.mark.fault("session integrity")
def test_a_calibration_outside_the_session_is_passed_never_picked_up(shot, tmp_path, capsys):
    session, profile = shot
    copy = _copy(session, tmp_path)
    shutil.rmtree(copy / "calibration")             # the copy holds no calibration; session.json names the original's
    _rewrite_original(copy, calibration=str(profile))
    rc = main(["process", str(copy)])
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert rc == 1 and line == (f"dualrgb: error: {copy}: no calibration in it or named by its originals (its "
                                f"originals were captured with {profile}, outside the session folder: never used "
                                "from session.json); pass --calibration FILE"), line
    assert main(["process", str(copy), "--calibration", str(profile)]) == 0          # named: used
    side = json.loads((copy / "deliverables" / "ACC-1" / "ACC-1.json").read_text())
    assert side["calibration"]["file"] == str(profile)


@pytest.mark.fault("session integrity")
def test_a_moved_session_delivers_with_its_own_calibration(shot, tmp_path, capsys):
    session, _ = shot
    copy = _copy(session, tmp_path)
    assert main(["process", str(copy)]) == 0
    side = json.loads((copy / "deliverables" / "ACC-1" / "ACC-1.json").read_text())
    assert Path(side["calibration"]["file"]).resolve() == (copy / "calibration" / "cal-test.json").resolve()


@pytest.mark.parametrize("recorded, expected", [
    ("calibration/cal-1.json", "calibration/cal-1.json"),
    ("../day2/calibration/cal-1.json", None),                      # leaves the folder: never
    ("calibration/../../day2/cal.json", None),
    ("/elsewhere/cal-1.json", None),
])
def test_inside_never_leaves_the_session_folder(tmp_path, recorded, expected):
    folder = tmp_path / "day1"
    folder.mkdir()
    found = inside(folder, recorded)
    assert found == (None if expected is None else (folder / expected).resolve())


def test_a_sidecar_in_another_session_is_not_this_ones(tmp_path):
    mine, other, out = tmp_path / "day1", tmp_path / "day2", tmp_path / "out"
    for folder in (mine, other):
        folder.mkdir()
        (folder / "session.json").write_text("{}")
    assert record(mine, mine / "deliverables" / "A" / "A.json") == "deliverables/A/A.json"
    assert record(mine, out / "A" / "A.json") == str((out / "A" / "A.json").resolve())
    assert deliverable(mine, str(out / "A" / "A.json")) == out / "A" / "A.json"           # --out DIR: the user's
    assert deliverable(mine, str(other / "deliverables" / "A" / "A.json")) is None        # another session's
