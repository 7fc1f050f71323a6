"""Every signal ends dark, said in one line (issue 38 item 1): SIGTERM, SIGHUP or SIGINT sent to a command while
the sphere is lit switches it off at once and reads it back (app.interrupts), the command's last line says so and
how to resume, and `dualrgb sphere status` right after shows the light off with trip=0 (the host switched it off,
not the sphere's own on-time limit or watchdog).

The virtual lab runs in its own process (`dualrgb lab serve`, as a physical stand's devices: app.lab.process), its
light watched from outside through its light record; the command drives it by its addresses (`--port --camera
--stand`) as its own process (the real CLI, ``dualrgb.app.cli.main``) under a small harness that only watches:
when the first lit exposure begins (the light is on, the shooter waits for the camera) it says LIT and waits for
the signal the test sends; lit periods get a 60 s limit so that only the signal can end this one. Then `dualrgb
sphere status` runs as a separate process on the lab's sphere.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from fault_rigs import ROOT
from workflow_profiles import make_profile

from dualrgb.app import interrupts
from dualrgb.app.interrupts import Interrupted, LightRead, interrupted_line

LAB_SHAPE = (64, 96)
LINE = "dualrgb: interrupted; light off (read back); run the same command again to resume"
HOST_ENDED = ("on-time limit", "watchdog", "power off")       # what the sphere ends by itself (not the host)

HARNESS = r"""
import signal, sys
from dualrgb.app.cli import main
from dualrgb.app.workflow.shooter import Shooter
from dualrgb.drivers.led_sphere.driver import LedSphere

argv = sys.argv[1:]
real_on, real_expose = LedSphere.on, Shooter._expose
waited = []

def on(self, max_on_s=None):
    return real_on(self, max_on_s=60.0)               # only the signal ends a lit period

def expose(self, exposure_s):                          # the first lit exposure waits for the test's signal
    if waited:
        return real_expose(self, exposure_s)
    waited.append(True)
    print("LIT", flush=True)
    while True:
        signal.pause()                                 # the handler raises out of here

LedSphere.on, Shooter._expose = on, expose
sys.exit(main(argv))
"""


def _signalled_run(argv: list[str], signum: int, record: Path) -> tuple[int, list[str]]:
    """Run ``dualrgb argv`` under the harness, send ``signum`` once the lab's record shows it lit and the harness
    says so; (exit code, stderr lines)."""
    from dualrgb.drivers.virtual.lab_server import lit_now

    proc = subprocess.Popen([sys.executable, "-c", HARNESS, *argv], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONWARNINGS": "ignore"})
    try:
        deadline = time.monotonic() + 600             # a hang guard only
        assert proc.stdout is not None
        for line in proc.stdout:
            if line.strip() == "LIT" or time.monotonic() > deadline:
                break
        while not lit_now(record) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert lit_now(record), "the sphere was not lit when the signal was to be sent"
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, err.strip().splitlines()


def _check_dark_and_said(rc: int, lines: list[str], record: Path, sphere: str, signum: int) -> None:
    from dualrgb.drivers.virtual.lab_server import lit_now, lit_periods

    assert rc == 128 + signum, (rc, lines[-5:])
    assert lines and lines[-1] == LINE, lines[-5:]
    assert not any("Traceback" in line for line in lines), lines
    assert lit_now(record) is None
    last = lit_periods(record)[-1]
    assert last["ended_by"] not in HOST_ENDED, last              # the host switched it off, not the sphere
    status = subprocess.run([sys.executable, "-m", "dualrgb", "sphere", "--port", sphere, "status", "--json", "-"],
                            capture_output=True, text=True, timeout=120)
    assert status.returncode == 0, status.stderr
    state = json.loads(status.stdout)
    assert state["light_on"] is False and state["watchdog_tripped"] is False, state   # off, trip=0
    print(f"[light safety] {signal.Signals(signum).name}: lit {last['t_off'] - last['t_on']:.3f} s, ended by "
          f"{last['ended_by']}; {lines[-1]}")


def _lab(frame: tuple[int, int], record: Path):
    from dualrgb.app.lab.process import LabOptions, LabProcess

    return LabProcess(LabOptions(frame_size=frame, light_record=record))


def _devices(lab) -> list[str]:
    a = lab.addresses
    return ["--port", a["sphere"], "--camera", a["camera"], "--stand", a["stand"]]


@pytest.mark.fault("light safety")
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT], ids=lambda s: s.name)
def test_a_signal_during_a_lit_capture_ends_dark_and_says_so(tmp_path, signum):
    profile = make_profile(tmp_path / "cal", shape=LAB_SHAPE).path
    session, record = tmp_path / "session", tmp_path / "light.jsonl"
    with _lab((96, 64), record) as lab:
        argv = ["capture", *_devices(lab), "--calibration", str(profile), "--id", "ACC-1", "--session", str(session),
                "--force", "--settle", "0"]
        rc, lines = _signalled_run(argv, signum, record)
        _check_dark_and_said(rc, lines, record, lab.addresses["sphere"], signum)
    doses = [json.loads(line) for line in (session / "manifest.jsonl").read_text().splitlines()
             if line.strip() and json.loads(line).get("kind") == "dose"]
    assert doses and doses[-1]["on_s"] < 60.0                      # the interrupted lit period is counted


@pytest.mark.fault("light safety")
def test_sigterm_during_a_lit_calibration_ends_dark_and_says_so(tmp_path):
    from dualrgb.app.lab.targets import lab_grids

    record, frame = tmp_path / "light.jsonl", (240, 160)
    grids = []
    for role, grid in lab_grids("reflective", frame).items():            # placed by hand (frames this small)
        path = tmp_path / f"{role}.json"
        path.write_text(json.dumps({"corners": grid.corners.tolist(), "rows": grid.rows, "cols": grid.cols}))
        grids += [f"--{role}-grid", str(path)]
    with _lab(frame, record) as lab:
        argv = ["calibrate", *_devices(lab), "--session", str(tmp_path / "session"), "--settle", "0", *grids]
        rc, lines = _signalled_run(argv, signal.SIGTERM, record)
        _check_dark_and_said(rc, lines, record, lab.addresses["sphere"], signal.SIGTERM)


# ---- the line says what was read back, truthfully ------------------------------------------------------------
class _Sphere:
    def __init__(self, port: str, off: bool, message: str):
        self.port, self.report = port, LightRead(port, off, message)
        self.asked = 0

    def ensure_off(self):
        self.asked += 1
        return self.report


@pytest.mark.fault("light safety")
@pytest.mark.parametrize("spheres, says", [
    ([], "dualrgb: interrupted; no LED sphere was open, so this command had nothing lit; run the same command "
         "again to resume"),
    ([("/dev/ttyACM0", True, "all LEDs and the light were switched off")], LINE),
    ([("/dev/ttyACM0", False, "LED sphere /dev/ttyACM0: no reply to 'LIGHT 0' within 1.00 s (sent twice); "
                              "switching off was not confirmed, so the light's state is unknown: the sphere "
                              "switches it off by itself at most 2.8 s after it came on")],
     "dualrgb: interrupted; the light is NOT confirmed off: LED sphere /dev/ttyACM0: LED sphere /dev/ttyACM0: no "
     "reply to 'LIGHT 0'"),
], ids=["none open", "read back off", "read back failed"])
def test_the_interrupted_line_says_what_was_read_back(monkeypatch, spheres, says):
    fakes = [_Sphere(*s) for s in spheres]
    monkeypatch.setattr(interrupts, "open_spheres", lambda: tuple(fakes))
    with pytest.raises(Interrupted) as caught:
        interrupts._handler(signal.SIGTERM, None)
    line = interrupted_line(caught.value)
    assert line.startswith(says) and line.endswith("run the same command again to resume"), line
    assert all(f.asked == 1 for f in fakes)
    assert interrupts.exit_code(caught.value) == 143
    interrupts._STATE.received.clear()
