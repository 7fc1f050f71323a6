"""The command line's refusals that need no device (issue 43): an unknown option is refused by its subcommand with
the closest valid one; options that do not apply together are refused in one line; the session's newest
calibration is named by the session folder (no glob that can match two files), of the wanted mode."""
from __future__ import annotations

import json

import pytest

from dualrgb.app import cli
from dualrgb.app.cli_refusals import check_sessions, newest_calibration


@pytest.mark.parametrize("argv, usage, hint", [
    (["capture", "--sesion", "day1", "--id", "A", "--virtual-lab"], "usage: dualrgb capture",
     "did you mean --session?"),
    (["calibration", "show", __file__, "--virtal-lab"], "usage: dualrgb calibration show",
     "did you mean --virtual-lab?"),
    (["process", "day1", "--calibraton", "c.json"], "usage: dualrgb process", "did you mean --calibration?"),
])
def test_an_unknown_option_names_the_closest_of_its_command(capsys, argv, usage, hint):
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    err = capsys.readouterr().err
    assert stop.value.code == 2 and err.startswith(usage) and err.strip().endswith(f"({hint})"), err


def test_an_unknown_word_far_from_every_option_gets_no_guess(capsys):
    with pytest.raises(SystemExit):
        cli.main(["capture", "--id", "A", "--virtual-lab", "--zzzzzzzz"])
    assert "did you mean" not in capsys.readouterr().err


@pytest.mark.parametrize("extra", [["--camera", "auto"], ["--port", "/dev/ttyACM0"], ["--stand", "socket://x:1"]])
def test_a_device_with_the_virtual_lab_is_refused_in_one_line(capsys, tmp_path, extra):
    rc = cli.main(["capture", "--session", str(tmp_path / "day"), "--id", "A", "--virtual-lab", *extra])
    err = capsys.readouterr().err
    assert rc == 1 and len(err.splitlines()) == 1 and f"{extra[0]} {extra[1]} with --virtual-lab" in err, err
    assert not (tmp_path / "day").exists()


def _profile(folder, stamp: str, mode: str):
    (folder / "calibration").mkdir(parents=True, exist_ok=True)
    path = folder / "calibration" / f"cal-{stamp}.json"
    path.write_text(json.dumps({"mode": mode}), encoding="utf-8")
    return path


def test_a_session_names_its_newest_calibration_of_the_mode(tmp_path):
    day = tmp_path / "day1"
    _profile(day, "20260101T080000Z-a", "reflective")
    film = _profile(day, "20260101T090000Z-b", "transmissive")
    newest = _profile(day, "20260101T100000Z-c", "reflective")
    assert newest_calibration(day) == newest and newest_calibration(day, "transmissive") == film
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no calibration in it yet"):
        newest_calibration(tmp_path / "empty")
    with pytest.raises(ValueError, match="no such session folder"):
        newest_calibration(tmp_path / "nope")


def test_process_is_refused_at_once_without_a_session_or_a_calibration(tmp_path):
    (tmp_path / "bare").mkdir()
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "session.json").write_text("{}", encoding="utf-8")
    with pytest.raises(ValueError, match="no such session folder"):
        check_sessions([tmp_path / "nope"], None)
    with pytest.raises(ValueError, match="not a capture session"):
        check_sessions([tmp_path / "bare"], None)
    with pytest.raises(ValueError, match="no calibration in it or named by its originals"):
        check_sessions([tmp_path / "empty"], None)
    check_sessions([tmp_path / "empty"], tmp_path / "cal.json")           # a calibration named: its own check
