"""The virtual lab's dose figures are right (issue 28 item 9): a lit exposure lasts its exposure time on the
sphere emulator's clock, so the emulator's record of the lit period and the session's light dose both hold the
exposure (an 8 s exposure was logged as 0.2 s of light)."""
from __future__ import annotations

import pytest
from light_record import LS1, lit_spans

from dualrgb.core.light_safety import SafetySettings
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.shooter import Shooter


@pytest.mark.fault("light safety")
@pytest.mark.parametrize("exposure_s", [0.25, 1.0])
def test_a_lit_exposure_lasts_its_time_on_the_emulators_clock(lab, tmp_path, exposure_s):
    session = CaptureSession.create(tmp_path / "s", {"test": "dose"})
    shooter = Shooter(lab.camera, lab.sphere, session, safety=SafetySettings(settle_s=0.05, latency_s=0.5))
    since = lab.emulator.clock()
    shooter.shoot("target", LS1.light, exposure_s, "dose/1")
    spans = lit_spans(lab.emulator, since)
    record = lab.camera.exposure_log[-1]
    assert len(spans) == 1 and record.lit
    exposed = record.t_close - record.t_open
    assert exposed >= exposure_s * 0.99 and spans[0].duration(0) >= exposure_s
    dose = sum(d.on_s for d in session.doses())
    assert dose >= exposure_s and dose == pytest.approx(spans[0].duration(0), abs=0.15)
    session.close()
