"""The simulate panel's "Re-optimise for this stand": the loaded calibration's stand model, off the GUI thread,
the same result as ``dualrgb simulate --stand`` (app.workflow.calibration.stand_reoptimise)."""
from __future__ import annotations

import pytest

from tests.gui.conftest import HANG_GUARD_MS, click, wait_idle


@pytest.fixture
def stand_profile(tmp_path):
    from dualrgb.app.workflow.calibration.profile import load_profile
    from dualrgb.app.workflow.calibration.stand_calibration import StandResult
    from dualrgb.simulation.capture_model import CaptureModel
    from dualrgb.simulation.stand_fit import fit_stand
    from dualrgb.simulation.stand_model import StandModel
    from tests.simulation.stand_data import hand_observations
    from tests.workflow_profiles import make_profile

    d700 = "resources/cameras/nikon_d700_rawtoaces.csv"
    obs = hand_observations([2, 0, -3, 0, 3, -2, 1.5, 3, 2.5, 0], flare=0.005, camera_csv=d700)
    fit = fit_stand(obs, StandModel(camera_csv=d700))
    result = StandResult(fit, obs, ["a", "b", "c"], "reflective", CaptureModel.virtual_lab("reflective"), {})
    return load_profile(make_profile(tmp_path, stand=result.summary(), stand_observations=obs).path)


def test_reoptimise_for_the_loaded_calibrations_stand(qtbot, make_window, stand_profile):
    from dualrgb.app.workflow.calibration.stand_reoptimise import assemble, reoptimise

    w = make_window()
    sim = w.simulate
    assert not sim.stand_button.isEnabled()                     # no calibration yet
    w.ctx.workspace.set_calibration(stand_profile)
    click(qtbot, sim.stand_button)
    assert not sim.stand_button.isEnabled() and not sim.run_button.isEnabled()     # running, off the GUI thread
    qtbot.waitUntil(lambda: sim.result is not None, timeout=HANG_GUARD_MS)
    wait_idle(qtbot, w)
    assert sim.result.extra["stand"]["calibration"] == "cal-test" and sim.stand_button.isEnabled()
    assert "on the stand model" in sim.status.text() and sim.table.rowCount() >= 1
    direct = reoptimise(assemble(stand_profile)[0], "reflective", top=1)        # what `simulate --stand` finds
    assert sim.result.outcome.candidates[0].sources == direct.outcome.candidates[0].sources
    path = sim.save_preset("for this stand")
    wait_idle(qtbot, w)
    import json

    assert json.loads(path.read_text())["model"]["stand"]["camera_csv"].endswith("nikon_d700_rawtoaces.csv")
    first = sim.result
    click(qtbot, sim.run_button)                                # the plain search is still the nominal one
    qtbot.waitUntil(lambda: sim.result is not first, timeout=HANG_GUARD_MS)
    wait_idle(qtbot, w)
    assert "stand" not in sim.result.extra and sim.result.outcome is not None
