"""kill -9 of the program that lit the virtual lab's sphere: the lab runs in a process of its own, so only the
sphere's own on-time limit (and watchdog) can switch the light off, as a physical sphere's firmware does - watched
from outside through the lab's light record, on the emulator's clock (bench/lab_kill.py measures the same for the
docs' reliability table: docs/notes/issue-36/lab-kill.json)."""
from __future__ import annotations

import pytest

from bench.lab_kill import kill_cli, kill_window
from dualrgb.drivers.led_sphere.limits import DEFAULT_MAX_ON_S

TICK_S = 0.06          # the emulator evaluates its limits at least every 50 ms


@pytest.mark.fault("light safety")
def test_a_cli_killed_during_a_lit_exposure_leaves_the_light_to_the_sphere_s_own_limit(tmp_path):
    out = kill_cli(tmp_path)
    assert out["ended_by"] == "on-time limit"                  # nobody else was there to switch it off
    assert out["lit_s"] <= DEFAULT_MAX_ON_S + TICK_S and out["kill_to_dark_s"] <= out["lit_s"]


@pytest.mark.fault("light safety")
def test_a_window_killed_with_the_light_on_leaves_it_to_the_sphere_and_the_lab_exits_after_dark(tmp_path):
    pytest.importorskip("PySide6")
    out = kill_window(tmp_path)
    assert out["ended_by"] == "on-time limit" and out["lit_s"] <= out["cap_s"] + TICK_S
    assert out["lab_exited_after_dark"]
