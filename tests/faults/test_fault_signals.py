"""Every signal ends dark, said in one line (issue 38 item 1): SIGTERM, SIGHUP or SIGINT sent to a command while
the sphere is lit switches it off at once and reads it back (app.interrupts), the command's last line says so and
how to resume, and `dualrgb sphere status` right after shows the light off with trip=0 (the host switched it off,
not the sphere's own on-time limit or watchdog).

The command runs as its own process (the real CLI, ``dualrgb.app.cli.main``) under a small harness that only
watches: when the first lit exposure begins (the light is on, the shooter waits for the camera) it says LIT and
waits for the signal the test sends; lit periods get a 60 s limit so that only the signal can end this one. The
virtual lab lives in the command's process, so the harness records, at the first moment of the unwinding and
before the lab stops, what the sphere emulator's own record says (who switched the light off, whether it was
still lit), and runs `dualrgb sphere status` as a separate process on the emulator's port.
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

HARNESS = r"""
import json, signal, subprocess, sys
from dualrgb.app.cli import main
from dualrgb.app.workflow.shooter import Shooter
from dualrgb.drivers.led_sphere.driver import LedSphere
from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator

record_path, argv = sys.argv[1], sys.argv[2:]
record, emulators = {}, []
real_on, real_expose, real_start, real_stop = LedSphere.on, Shooter._expose, SphereEmulator.start, SphereEmulator.stop

def start(self, *a, **k):
    emulators.append(self)
    return real_start(self, *a, **k)

def on(self, max_on_s=None):
    return real_on(self, max_on_s=60.0)               # only the signal ends a lit period

def expose(self, exposure_s):                          # the first lit exposure waits for the test's signal
    if "lit_at_signal" in record:
        return real_expose(self, exposure_s)
    record["lit_at_signal"] = emulators[-1].snapshot().light_on
    try:
        print("LIT", flush=True)                       # (inside the try: the signal may land in print)
        while True:
            signal.pause()                             # the handler raises out of here
    finally:
        record["lit_when_unwinding_began"] = emulators[-1].snapshot().light_on

def stop(self):
    status = subprocess.run([sys.executable, "-m", "dualrgb", "sphere", "--port", self.port, "status", "--json", "-"],
                            capture_output=True, text=True, timeout=120)
    record["status"] = json.loads(status.stdout) if status.returncode == 0 else status.stderr
    record["spans"] = [[i.t_on, i.t_off, i.ended_by] for i in self.light_record()]
    with open(record_path, "w") as fh:
        json.dump(record, fh)
    real_stop(self)

LedSphere.on, Shooter._expose, SphereEmulator.start, SphereEmulator.stop = on, expose, start, stop
sys.exit(main(argv))
"""


def _signalled_run(argv: list[str], signum: int, record: Path) -> tuple[int, list[str]]:
    """Run ``dualrgb argv`` under the harness, send ``signum`` once it is lit; (exit code, stderr lines)."""
    proc = subprocess.Popen([sys.executable, "-c", HARNESS, str(record), *argv], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONWARNINGS": "ignore"})
    try:
        deadline = time.monotonic() + 600             # a hang guard only
        assert proc.stdout is not None
        for line in proc.stdout:
            if line.strip() == "LIT" or time.monotonic() > deadline:
                break
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, err.strip().splitlines()


def _check_dark_and_said(rc: int, lines: list[str], record: Path, signum: int) -> None:
    assert rc == 128 + signum, (rc, lines[-5:])
    assert lines and lines[-1] == LINE, lines[-5:]
    assert not any("Traceback" in line for line in lines), lines
    seen = json.loads(record.read_text())
    assert seen["lit_at_signal"] is True                         # the signal came while the sphere was lit
    assert seen["lit_when_unwinding_began"] is False             # switched off by the handler, before any clean-up
    t_on, t_off, ended_by = seen["spans"][-1]
    assert t_off is not None and ended_by in ("ALLOFF", "LIGHT 0"), seen["spans"]      # the host, not the sphere
    status = seen["status"]
    assert isinstance(status, dict), status
    assert status["light_on"] is False and status["watchdog_tripped"] is False, status   # off, trip=0
    print(f"[light safety] {signal.Signals(signum).name}: lit {t_off - t_on:.3f} s, ended by {ended_by}; "
          f"{lines[-1]}")


@pytest.mark.fault("light safety")
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT], ids=lambda s: s.name)
def test_a_signal_during_a_lit_capture_ends_dark_and_says_so(tmp_path, signum):
    profile = make_profile(tmp_path / "cal", shape=LAB_SHAPE).path
    session = tmp_path / "session"
    argv = ["capture", "--virtual-lab", "--calibration", str(profile), "--id", "ACC-1", "--session", str(session),
            "--force", "--settle", "0", "--frame-size", "96x64"]
    rc, lines = _signalled_run(argv, signum, tmp_path / "record.json")
    _check_dark_and_said(rc, lines, tmp_path / "record.json", signum)
    doses = [json.loads(line) for line in (session / "manifest.jsonl").read_text().splitlines()
             if line.strip() and json.loads(line).get("kind") == "dose"]
    assert doses and doses[-1]["on_s"] < 60.0                      # the interrupted lit period is counted


@pytest.mark.fault("light safety")
def test_sigterm_during_a_lit_calibration_ends_dark_and_says_so(tmp_path):
    argv = ["calibrate", "--virtual-lab", "--session", str(tmp_path / "session"), "--settle", "0",
            "--frame-size", "96x64"]
    rc, lines = _signalled_run(argv, signal.SIGTERM, tmp_path / "record.json")
    _check_dark_and_said(rc, lines, tmp_path / "record.json", signal.SIGTERM)


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
