"""``dualrgb sphere`` (issue 9 item 3, issue 13): an argument error raised before the port opens still ends with
the light off when a port is given, and says so truthfully; a silent or garbage-speaking port is reported in one
line within 3 s of opening it."""
from __future__ import annotations

import json
import os
import random
import threading
import time
import tty
from pathlib import Path

import pytest

from dualrgb.app.cli import main
from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator


@pytest.fixture
def lit_emulator():
    """A sphere lit by someone else (LEVELS + LIGHT 1 straight into its firmware)."""
    emulator = SphereEmulator(watchdog_s=60)
    emulator.start()
    yield emulator
    emulator.stop()


def _preset(path: Path, leds) -> Path:
    path.write_text(json.dumps({"format": "dualrgb-preset/1", "name": "t",
                                "sources": [{"leds": leds, "levels": [1.0] * len(leds)}]}))
    return path


# args after --port (and --timeout 1 unless given) -> (exit code, what the error line starts with / contains);
# exit 2: refused while parsing (argparse's last line), 1: a preset problem found when the command runs
BEFORE_THE_PORT = {
    "LED 11": (["set", "11", "0.5"], 2, "argument led: '11': expected a whole number from 1 to 10"),
    "LED 0": (["set", "0", "0.5"], 2, "argument led: '0': expected a whole number from 1 to 10"),
    "LED 1.5": (["set", "1.5", "0.5"], 2, "argument led: '1.5': expected a whole number"),
    "LED x": (["set", "x", "0.5"], 2, "argument led: 'x': expected a whole number"),
    "level 1.5": (["set", "3", "1.5"], 2, "argument level: '1.5': expected from 0 to 1"),
    "level -0.1": (["set", "3", "-0.1"], 2, "argument level: '-0.1': expected from 0 to 1"),
    "level nan": (["set", "3", "nan"], 2, "argument level: 'nan': expected a finite number"),
    "level inf": (["set", "3", "inf"], 2, "argument level: 'inf': expected a finite number"),
    "missing preset": (["apply", "{tmp}/missing.json"], 1, "{tmp}/missing.json"),
    "preset LED 12": (["apply", "{tmp}/bad.json"], 1, "{tmp}/bad.json"),
    "preset source 3": (["apply", "{tmp}/good.json", "--source", "3"], 1, "--source 3"),
    "preset source 0": (["apply", "{tmp}/good.json", "--source", "0"], 2, "argument --source: '0'"),
    "--timeout 0": (["--timeout", "0", "identify"], 2, "argument --timeout: '0': expected more than 0 s"),
    "--timeout -1": (["--timeout", "-1", "status"], 2, "argument --timeout: '-1'"),
    "--timeout nan": (["--timeout", "nan", "off"], 2, "argument --timeout: 'nan'"),
    "--timeout 1e-9": (["--timeout", "1e-9", "identify"], 2, "argument --timeout: '1e-9': expected from 0.01 to 60 s"),
    "--max-on 0": (["on", "--max-on", "0"], 2, "argument --max-on: '0'"),
    "--max-on 1e9": (["on", "--max-on", "1e9"], 2, "argument --max-on: '1e9': expected from 0.1 to 3600 s"),
    "no action": ([], 2, "the following arguments are required: ACTION"),
}


@pytest.mark.fault("light safety")
@pytest.mark.parametrize("case", list(BEFORE_THE_PORT))
def test_argument_errors_end_with_the_light_off_and_say_so(lit_emulator, capsys, tmp_path, case):
    args, code, says = BEFORE_THE_PORT[case]
    _preset(tmp_path / "bad.json", [1, 12])
    _preset(tmp_path / "good.json", [1, 6, 8])
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    timeout = [] if "--timeout" in args else ["--timeout", "1"]
    for line in (b"LEVELS 65535 0 0 0 0 65535 0 65535 0 0", b"LIGHT 1"):
        assert lit_emulator.handle(line).startswith(b"OK")
    assert lit_emulator.snapshot().light_on
    try:
        rc = main(["sphere", "--port", lit_emulator.port, *timeout, *args])
    except SystemExit as exc:
        rc = exc.code
    out, err = capsys.readouterr()
    last = err.strip().splitlines()[-1]
    assert rc == code and out == "" and "Traceback" not in err, err
    assert says.replace("{tmp}", str(tmp_path)) in last, last
    assert last.startswith("dualrgb: error: " if code == 1 else "dualrgb sphere"), last
    assert last.endswith("; all LEDs and the light were switched off"), last
    assert "failed" not in last
    snap = lit_emulator.snapshot()
    assert not snap.light_on and not snap.levels.any()


def _silent_peer():
    master, slave = os.openpty()
    tty.setraw(slave)
    return master, slave, None


def _garbage_peer():
    master, slave = os.openpty()
    tty.setraw(slave)
    stop = threading.Event()
    rng = random.Random(13)

    def speak() -> None:
        os.set_blocking(master, False)
        while not stop.is_set():
            try:
                os.write(master, bytes(rng.randrange(256) for _ in range(rng.randint(1, 40))))
                os.read(master, 4096)
            except OSError:
                pass
            time.sleep(0.01)
    threading.Thread(target=speak, daemon=True).start()
    return master, slave, stop


@pytest.mark.fault("light safety")
@pytest.mark.parametrize("peer", [_silent_peer, _garbage_peer], ids=["silent", "garbage"])
@pytest.mark.parametrize("action", ["identify", "on", "off"])
def test_a_port_that_is_not_a_sphere_is_reported_within_3_s(capsys, peer, action):
    master, slave, stop = peer()
    try:
        started = time.monotonic()
        rc = main(["sphere", "--port", os.ttyname(slave), action])
        took = time.monotonic() - started
    finally:
        if stop is not None:
            stop.set()
        os.close(master)
        os.close(slave)
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    print(f"[light safety] {peer.__name__.strip('_')} port, {action}: reported after {took:.2f} s")
    assert rc == 1 and len(lines) == 1 and lines[0].startswith("dualrgb: error: LED sphere "), err
    assert "the port never answered like an LED sphere, so the light's state is unknown" in lines[0]
    assert took <= 3.0
