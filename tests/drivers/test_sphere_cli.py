"""``dualrgb sphere`` and ``dualrgb sphere-emulator``: exit codes, one-line errors, LEDs off after a failure."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from sphere_fakes import FakeClock
from transports import TRANSPORTS, assert_port

from dualrgb.app.cli import main
from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def emu():
    emulator = SphereEmulator(watchdog_s=30, clock=FakeClock())
    emulator.start()
    yield emulator
    emulator.stop()


def run(emu, *args, capsys, timeout="2"):
    rc = main(["sphere", "--port", emu.port, "--timeout", timeout, *args])
    out, err = capsys.readouterr()
    return rc, out, err


def assert_one_line_error(rc, err):
    assert rc == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dualrgb: error: "), err
    assert "Traceback" not in err


def write_preset(path: Path) -> Path:
    path.write_text(json.dumps({"format": "dualrgb-preset/1", "name": "test",
                                "sources": [{"leds": [1, 6, 8], "levels": [1.0, 0.5, 0.25]},
                                            {"leds": [3, 5, 9], "levels": [1.0, 1.0, 1.0]}]}),
                    encoding="utf-8")
    return path


def test_identify_status_set_on_off(emu, capsys):
    rc, out, _ = run(emu, "identify", capsys=capsys)
    assert rc == 0 and out == "model DRGB-SPHERE10-EMU, firmware 1.1.0, serial EMU-0001\n"
    rc, out, _ = run(emu, "set", "4", "0.5", capsys=capsys)
    assert rc == 0 and out == "LED 4 level 0.5000\n"
    assert emu.commanded_levels()[3] == pytest.approx(0.5, abs=1e-4)
    rc, out, _ = run(emu, "on", capsys=capsys)
    assert rc == 0 and out == "light on for at most 10 s (the sphere switches it off by itself)\n"
    assert emu.snapshot().levels[3] > 0.49
    rc, out, _ = run(emu, "status", capsys=capsys)
    assert rc == 0 and "light_on: True" in out and "levels: 0.0000 0.0000 0.0000 0.5000" in out
    rc, out, _ = run(emu, "off", capsys=capsys)
    assert rc == 0 and out == "all LEDs off, light off (read back)\n"
    assert not emu.snapshot().light_on and emu.commanded_levels().sum() == 0


def test_apply_preset_sources(emu, capsys, tmp_path):
    preset = write_preset(tmp_path / "p.json")
    rc, out, _ = run(emu, "apply", str(preset), capsys=capsys)
    assert rc == 0 and out.startswith("applied source 1 (1, 6, 8)")
    expected = np.zeros(10)
    expected[[0, 5, 7]] = [1.0, 0.5, 0.25]
    assert emu.commanded_levels() == pytest.approx(expected, abs=1e-4)
    rc, out, _ = run(emu, "apply", str(preset), "--source", "2", capsys=capsys)
    assert rc == 0
    expected = np.zeros(10)
    expected[[2, 4, 8]] = 1.0
    assert emu.commanded_levels() == pytest.approx(expected)


@pytest.mark.parametrize("args", [["set", "11", "0.5"], ["set", "3", "1.5"], ["set", "3", "nan"]])
def test_bad_values_refused_while_parsing_and_leds_off(emu, capsys, args):
    assert run(emu, "set", "2", "1.0", capsys=capsys)[0] == 0
    assert run(emu, "on", capsys=capsys)[0] == 0
    with pytest.raises(SystemExit) as info:
        run(emu, *args, capsys=capsys)
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert info.value.code == 2 and "Traceback" not in last
    assert "error: argument " in last and last.endswith("; all LEDs and the light were switched off")
    assert not emu.snapshot().light_on and emu.commanded_levels().sum() == 0


def test_failure_mid_way_leaves_leds_off(emu, capsys, tmp_path):
    assert run(emu, "set", "2", "1.0", capsys=capsys)[0] == 0
    assert run(emu, "on", capsys=capsys)[0] == 0
    emu.inject("no_reply")              # replies lost; the sphere still obeys the off requests
    rc, _, err = run(emu, "apply", str(write_preset(tmp_path / "p.json")), capsys=capsys, timeout="0.2")
    assert_one_line_error(rc, err)
    assert "no reply" in err and "the light's state is unknown" in err
    # ALLOFF and LIGHT 0 were written without waiting (this port never answered): the sphere obeys them at once
    deadline = time.monotonic() + 1.0
    while emu.snapshot().light_on and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not emu.snapshot().light_on and emu.commanded_levels().sum() == 0


def test_led_fault_reported_in_one_line(emu, capsys):
    emu.inject("led_fail", led=6, mode="dark")
    assert run(emu, "set", "6", "1.0", capsys=capsys)[0] == 0
    rc, _, err = run(emu, "on", capsys=capsys)
    assert_one_line_error(rc, err)
    assert "LED 6 reports a fault" in err and not emu.snapshot().light_on


def test_port_and_file_errors(emu, capsys, tmp_path, monkeypatch):
    monkeypatch.delenv("DUALRGB_SPHERE_PORT", raising=False)
    for argv in (["sphere", "identify"],
                 ["sphere", "--port", str(tmp_path / "nope"), "identify"],
                 ["sphere", "--port", emu.port, "apply", str(tmp_path / "missing.json")],
                 ["sphere", "--port", emu.port, "apply", str(write_preset(tmp_path / "p.json")), "--source", "3"]):
        rc = main(argv)
        _, err = capsys.readouterr()
        assert_one_line_error(rc, err)
    bad = tmp_path / "bad.json"
    bad.write_text('{"sources": [{"leds": [1, 12]}]}')
    rc = main(["sphere", "--port", emu.port, "apply", str(bad)])
    _, err = capsys.readouterr()
    assert_one_line_error(rc, err)
    assert "bad.json" in err


def test_disconnected_emulator(emu, capsys):
    emu.inject("disconnect")
    rc, _, err = run(emu, "identify", capsys=capsys, timeout="0.2")
    assert_one_line_error(rc, err)


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_subprocess_emulator_and_cli(transport):
    """The real entry points: `dualrgb sphere-emulator` in one process, `dualrgb sphere` in another."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONWARNINGS": "ignore"}
    # Ctrl-C's handler restored first: a test run started in the background of a non-interactive shell (nohup, `&`,
    # some CI runners) ignores SIGINT, its children inherit that, and Python then installs no KeyboardInterrupt
    cmd = [sys.executable, "-c", "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
                                 "from dualrgb.app.cli import main; sys.exit(main(sys.argv[1:]))"]
    server = subprocess.Popen(cmd + ["sphere-emulator", "--watchdog", "5", "--transport", transport], cwd=ROOT,
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        port = server.stdout.readline().strip()
        if server.poll() is not None:
            pytest.fail(f"the emulator exited: {server.stderr.read()}")
        assert_port(port, transport)
        ok = subprocess.run(cmd + ["sphere", "--port", port, "--timeout", "1", "identify"], cwd=ROOT, env=env,
                            capture_output=True, text=True, timeout=60)
        assert ok.returncode == 0 and ok.stdout.startswith("model DRGB-SPHERE10-EMU"), ok
        bad = subprocess.run(cmd + ["sphere", "--port", port, "--timeout", "1", "set", "12", "1"], cwd=ROOT,
                             env=env, capture_output=True, text=True, timeout=60)
        assert bad.returncode == 2 and bad.stdout == ""
        last = bad.stderr.strip().splitlines()[-1]
        assert "argument led: '12'" in last and last.endswith("all LEDs and the light were switched off")
    finally:
        server.send_signal(signal.SIGINT)
        try:
            rc = server.wait(timeout=120)              # a hang guard: it exits in well under a second
        except subprocess.TimeoutExpired:
            server.kill()
            raise
    assert rc == 0


def test_status_json_to_stdout_and_to_a_file(emu, capsys, tmp_path):
    """``status --json PATH``: '-' prints only the JSON (format tag, versions, the status); a PATH gets the file
    and stdout the usual text."""
    assert run(emu, "set", "4", "0.5", capsys=capsys)[0] == 0
    rc, out, _ = run(emu, "status", "--json", "-", capsys=capsys)
    status = json.loads(out)
    assert rc == 0 and status["format"] == "dualrgb-sphere-status/1" and status["software"]["dualrgb"]
    assert status["light_on"] is False and status["levels"][3] == pytest.approx(0.5, abs=1e-3)
    assert status["port"] == emu.port
    path = tmp_path / "status.json"
    rc, out, _ = run(emu, "status", "--json", str(path), capsys=capsys)
    assert rc == 0 and "light_on: False" in out
    assert json.loads(path.read_text())["levels"] == status["levels"]
