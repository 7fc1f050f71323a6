"""Lights that cannot work are refused before the light (issue 40): a preset whose light 2 is light 1 at half level
gives six channels that are three channels twice, so no matrix can separate them; the condition number of the
camera model's 6-channel values on the training reflectances says so before anything is lit, in the CLI (before
any device opens) and in the workflow every front end calls (the sphere emulator's own record shows no lit
period). A light set in the band below the limit is calibrated with a warning, and the calibration reports the
same figure from its captures."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from light_record import lit_spans

from dualrgb.app.cli import main
from dualrgb.app.workflow.stand.copystand import CopyStand, StandSettings
from dualrgb.app.workflow.stand.preflight import (
    CONDITION_LIMIT,
    CONDITION_WARN,
    ConditioningError,
    check_conditioning,
)
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.vocabulary import NamedLight
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.presets import load_preset

HALF = [{"leds": [1, 6, 8], "levels": [1.0, 1.0, 1.0]}, {"leds": [1, 6, 8], "levels": [0.5, 0.5, 0.5]}]


def _preset(path: Path, sources: list[dict], name: str = "half") -> Path:
    path.write_text(json.dumps({"format": "dualrgb-preset/1", "name": name, "mode": "reflective",
                                "sources": sources}))
    return path


@pytest.mark.fault("light safety")
def test_calibrate_refuses_a_light_that_is_another_at_half_level_before_any_device(tmp_path, capsys, monkeypatch):
    opened = []
    monkeypatch.setattr("dualrgb.drivers.virtual.lab.VirtualLab.start", lambda self: opened.append(self))
    rc = main(["calibrate", "--preset", str(_preset(tmp_path / "half.json", HALF)), "--virtual-lab",
               "--session", str(tmp_path / "session")])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 1 and len(lines) == 1 and lines[0].startswith("dualrgb: error: "), err
    assert "condition number infinite of the 6 channels" in lines[0] and f"limit {CONDITION_LIMIT:g}" in lines[0]
    assert "light 1 LEDs (1, 6, 8); half light 2 LEDs (1, 6, 8) @ (0.5, 0.5, 0.5)" in lines[0]
    assert "refused before any light was switched on" in lines[0]
    assert opened == [] and not (tmp_path / "session").exists()


@pytest.mark.fault("light safety")
def test_the_workflow_refuses_it_on_the_virtual_lab_with_the_sphere_dark(lab, tmp_path):
    """The GUI's and the demo's path: CopyStand.calibrate refuses before auto-exposure, nothing recorded, the
    emulator never lit."""
    session = CaptureSession.create(tmp_path / "session", {"test": "conditioning"})
    stand = CopyStand(lab.camera, lab.sphere, session, stand=lab.place, settings=StandSettings())
    since = lab.emulator.clock()
    with pytest.raises(ConditioningError, match=r"preset half: condition number infinite .* refused before any "
                                                r"light"):
        stand.calibrate(load_preset(_preset(tmp_path / "half.json", HALF)))
    assert lit_spans(lab.emulator, since) == [] and session.entries() == []
    session.close()


def _lights(*sources: LightSource) -> list[NamedLight]:
    return [NamedLight(f"P light {i}", s) for i, s in enumerate(sources, start=1)]


def test_near_collinear_lights_are_refused_and_a_band_below_is_warned(caplog):
    """Light 2 = light 1 at half level plus a trace of another LED: finite but above the limit, refused; lights that
    share two LEDs: in the warning band (the line names the condition number and the LEDs); the shipped pairs pass."""
    l1 = LightSource((1, 6, 8))
    with pytest.raises(ConditioningError, match=r"condition number [0-9.e+]+ of the 6 channels .* above the limit"):
        check_conditioning(_lights(l1, LightSource((1, 3, 6, 8), (0.5, 0.01, 0.5, 0.5))), "reflective", "P")
    cond, warning = check_conditioning(_lights(l1, LightSource((2, 6, 8))), "reflective", "P")
    assert CONDITION_WARN < cond < CONDITION_LIMIT and warning is not None
    assert f"condition number {cond:.3g}" in warning and "P light 2 LEDs (2, 6, 8)" in warning
    assert any("condition number" in r.getMessage() for r in caplog.records)
    for pair in (((1, 6, 8), (3, 5, 9)), ((1, 6, 8), (3, 5, 10))):
        cond, warning = check_conditioning(_lights(*(LightSource(p) for p in pair)), "transmissive", "P")
        assert 1.0 < cond < CONDITION_WARN and warning is None
    assert np.isnan(check_conditioning(_lights(l1), "reflective", "P")[0])          # one light: 3 channels


def test_the_band_warning_is_said_once_per_run(tmp_path, capsys, caplog):
    """The command's pre-check (before any device opens) refuses above the limit but leaves the band's warning to
    the workflow's own check before the light, so a run says it once (it was printed three times)."""
    from dualrgb.app.commands.calibrate import conditioning

    band = [{"leds": [1, 6, 8], "levels": [1.0, 1.0, 1.0]}, {"leds": [2, 6, 8], "levels": [1.0, 1.0, 1.0]}]
    conditioning(load_preset(_preset(tmp_path / "band.json", band, name="band")), None)
    assert capsys.readouterr().err == "" and not any("condition number" in r.getMessage() for r in caplog.records)
    with pytest.raises(ConditioningError):
        conditioning(load_preset(_preset(tmp_path / "half.json", HALF)), None)
