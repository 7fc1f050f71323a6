"""Light gaps (issue 41): for every lit frame the gap from the switch-on to the camera's trigger and from the end of
the exposure to the switch-off is measured and written in the session's manifest (the frame's entry and its lit
period's dose line); a host starved between the switch-on and the trigger (simulated deterministically: the
shooter's clock jumps during the settle time) never triggers the camera: the light goes off at once, the step is
shot again once, said in one line with its dose, and a second starved attempt stops the run with the light off."""
from __future__ import annotations

import json
import time

import pytest
from light_record import FAST, LS1, lit_spans

from dualrgb.core.light_safety import LightSafetyError
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.shooter import Shooter
from dualrgb.core.stand_timeline import StandTimeline

EXPOSURE_S = 1 / 60


class StarvedHost:
    """The shooter's clock and sleep: real time, plus ``jump_s`` added during each of the first ``starved``
    settle waits (what a host that did not schedule the capture's thread looks like to it)."""

    def __init__(self, jump_s: float, starved: int):
        self.jump_s, self.starved, self.offset = jump_s, starved, 0.0

    def clock(self) -> float:
        return time.monotonic() + self.offset

    def sleep(self, seconds: float) -> None:
        time.sleep(seconds)
        if self.starved > 0:
            self.starved -= 1
            self.offset += self.jump_s


def _shooter(lab, tmp_path, host: StarvedHost | None = None) -> tuple[Shooter, list[str]]:
    session = CaptureSession.create(tmp_path / "session", {"test": "light gaps"})
    lines: list[str] = []
    timeline = StandTimeline(host.clock) if host else None
    return Shooter(lab.camera, lab.sphere, session, safety=FAST, sleep=host.sleep if host else time.sleep,
                   notice=lambda line, _data: lines.append(line), timeline=timeline), lines


def _manifest(shooter: Shooter) -> list[dict]:
    return [json.loads(line) for line in (shooter.session.path / "manifest.jsonl").read_text().splitlines()]


def _doses(shooter: Shooter) -> list[dict]:
    return [r for r in _manifest(shooter) if "light_gaps" in json.dumps(r) and "sha256" not in r]


def test_every_lit_frame_has_its_light_gaps_in_the_manifest(lab, tmp_path):
    shooter, lines = _shooter(lab, tmp_path)
    for i in range(3):
        shooter.shoot("target", LS1.light, EXPOSURE_S, f"target/gaps/{i}")
    shooter.shoot("dark", None, EXPOSURE_S, "dark/unlit")
    frames = {e["step_id"]: e for e in _manifest(shooter) if "sha256" in e}
    for i in range(3):
        gaps = frames[f"target/gaps/{i}"]["meta"]["light_gaps"]
        assert gaps["on_to_trigger_s"] >= FAST.settle_s and gaps["end_to_off_s"] >= 0
        assert gaps["trigger_bound_s"] == pytest.approx(FAST.trigger_bound_s(EXPOSURE_S))
    assert "light_gaps" not in frames["dark/unlit"]["meta"]               # nothing lit, no gap
    assert len(_doses(shooter)) == 3 and lines == []


def test_a_frame_starved_before_its_trigger_is_shot_again_once_said_with_its_dose(lab, tmp_path):
    host = StarvedHost(jump_s=FAST.trigger_bound_s(EXPOSURE_S) + 0.5, starved=1)
    shooter, lines = _shooter(lab, tmp_path, host)
    since = lab.emulator.clock()
    entry = shooter.shoot("target", LS1.light, EXPOSURE_S, "target/starved")
    assert len(lines) == 1 and "\n" not in lines[0]
    assert "was not triggered" in lines[0] and "light dose" in lines[0] and "lux.s" in lines[0]
    assert lines[0].endswith("shooting it again once")
    assert entry.meta["light_gaps"]["on_to_trigger_s"] <= FAST.trigger_bound_s(EXPOSURE_S) + 0.5
    assert len(lit_spans(lab.emulator, since)) == 2 and all(s.t_off is not None for s in lit_spans(lab.emulator, since))
    doses = _doses(shooter)                                             # both lit periods, the starved one first
    assert len(doses) == 2 and doses[0]["meta"]["light_gaps"]["on_to_trigger_s"] > FAST.trigger_bound_s(EXPOSURE_S)
    assert doses[0]["meta"]["light_gaps"]["end_to_off_s"] is None       # never triggered
    assert len(lab.camera.exposure_log) == 1                            # the camera was triggered once


def test_a_frame_starved_twice_stops_the_run_with_the_light_off(lab, tmp_path):
    host = StarvedHost(jump_s=FAST.trigger_bound_s(EXPOSURE_S) + 0.5, starved=2)
    shooter, lines = _shooter(lab, tmp_path, host)
    since = lab.emulator.clock()
    with pytest.raises(LightSafetyError, match="the computer is too busy") as info:
        shooter.shoot("target", LS1.light, EXPOSURE_S, "target/starved")
    assert "\n" not in str(info.value) and "the light was switched off" in str(info.value)
    assert "light dose" in str(info.value) and len(lines) == 1
    assert not shooter.session.has_step("target/starved") and lab.camera.exposure_log == []
    spans = lit_spans(lab.emulator, since)
    assert len(spans) == 2 and all(s.t_off is not None for s in spans)
