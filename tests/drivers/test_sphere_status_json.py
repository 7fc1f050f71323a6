"""``dualrgb sphere status --json PATH``: the status as JSON ('-' = stdout only JSON), with format and versions."""
from __future__ import annotations

import json

import pytest

from app.cli import main
from drivers.virtual.sphere_emulator import SphereEmulator
from sphere_fakes import FakeClock


@pytest.fixture
def emu():
    emulator = SphereEmulator(watchdog_s=30, clock=FakeClock())
    emulator.start()
    yield emulator
    emulator.stop()


def test_status_json_to_stdout_and_to_a_file(emu, capsys, tmp_path):
    assert main(["sphere", "--port", emu.port, "set", "4", "0.5"]) == 0
    capsys.readouterr()
    assert main(["sphere", "--port", emu.port, "status", "--json", "-"]) == 0
    status = json.loads(capsys.readouterr().out)
    assert status["format"] == "dualrgb-sphere-status/1" and status["software"]["dualrgb"]
    assert status["light_on"] is False and status["levels"][3] == pytest.approx(0.5, abs=1e-3)
    assert status["port"] == emu.port
    out = tmp_path / "status.json"
    assert main(["sphere", "--port", emu.port, "status", "--json", str(out)]) == 0
    assert "light_on: False" in capsys.readouterr().out                   # the text still goes to stdout
    assert json.loads(out.read_text())["levels"] == status["levels"]
