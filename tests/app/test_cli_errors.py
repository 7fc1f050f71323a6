"""The command line's error handling (issue 28): every error a user, a device or a file can cause is one line;
anything else (a bug) is one line too, naming the crash report that holds its traceback. No traceback reaches
the terminal."""
from __future__ import annotations

import argparse
import os

import pytest

from dualrgb import resources
from dualrgb.app import cli
from dualrgb.common.errors import ReportedError, one_line
from dualrgb.drivers.camera.base import CameraError
from dualrgb.drivers.led_sphere import SphereError


def _run_raising(monkeypatch, capsys, exc: BaseException) -> tuple[int, str]:
    def boom(args: argparse.Namespace) -> int:
        raise exc

    monkeypatch.setattr("dualrgb.app.commands.devices.run", boom)       # what `dualrgb devices` runs
    rc = cli.main(["devices"])
    out, err = capsys.readouterr()
    assert out == "" and "Traceback" not in err
    return rc, err


@pytest.mark.parametrize("exc, line", [
    (SphereError("LED sphere /dev/ttyACM0: no reply to 'ALLOFF'", kind="timeout"),
     "dualrgb: error: LED sphere /dev/ttyACM0: no reply to 'ALLOFF'"),
    (CameraError("open camera: no USB/serial port usb:001,002"), "dualrgb: error: open camera: no USB/serial port"),
    (ValueError("queue.csv:3: bad"), "dualrgb: error: queue.csv:3: bad"),
])
def test_device_and_input_errors_are_one_line(monkeypatch, capsys, exc, line):
    rc, err = _run_raising(monkeypatch, capsys, exc)
    assert rc == 1 and len(err.splitlines()) == 1 and err.startswith(line)


def test_a_note_on_the_light_is_part_of_the_line(monkeypatch, capsys):
    exc = CameraError("capture: the camera failed")
    exc.add_note("all LEDs and the light were switched off")
    rc, err = _run_raising(monkeypatch, capsys, exc)
    assert rc == 1 and err == ("dualrgb: error: capture: the camera failed; all LEDs and the light were switched "
                               "off\n")


def test_a_bug_is_one_line_naming_its_crash_report(monkeypatch, capsys):
    rc, err = _run_raising(monkeypatch, capsys, ZeroDivisionError("float division by zero"))
    assert rc == 1 and len(err.splitlines()) == 1, err
    assert err.startswith("dualrgb: error: unexpected ZeroDivisionError: float division by zero (a bug in dualrgb: "
                          "the traceback is in ")
    reports = list(resources.user_path("crash").glob("dualrgb-crash-*.txt"))
    assert len(reports) == 1 and str(reports[0]) in err
    text = reports[0].read_text()
    assert "Traceback (most recent call last)" in text and "ZeroDivisionError" in text and "devices" in text


def test_a_crash_report_that_cannot_be_written_still_gives_one_line(monkeypatch, capsys, tmp_path):
    blocked = tmp_path / "blocked"
    blocked.write_text("a file where the folder should be")
    monkeypatch.setenv("DUALRGB_DATA_DIR", str(blocked))
    rc, err = _run_raising(monkeypatch, capsys, KeyError("white_0"))
    assert rc == 1 and len(err.splitlines()) == 1
    assert "unexpected KeyError: 'white_0'" in err and "the traceback could not be written" in err


def test_one_line_joins_lines_and_notes():
    exc = ReportedError("first\nsecond")
    exc.add_note("the light is off")
    assert one_line(exc) == "first second; the light is off"
    assert os.linesep not in one_line(ValueError("a\r\nb"))
