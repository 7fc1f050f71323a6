"""The stand model fitted to the calibration captures, end to end on the virtual lab in the mismatched world
(another measured camera, LED peaks +-3 nm, 0.5 % flare): ``dualrgb study stand`` once for the module (600x400
frames, 3 capture seeds per light set, about 4 minutes on the shared 2 cores), then its figures and files checked.

Must show: the fitted model predicts the captured patch DNs with R^2 >= 0.999 (training target, fitted; test target,
checked) and the captured test dE00 within 10 %, the nominal model's misses beside; lights re-optimised on the fitted
model are captured at least as accurately as the nominal preset and within 5 % of the world's own optimum (lights
optimised on the world's true camera and LEDs). Which combination meets it is stated, not hidden: the fit from the
measured camera and LEDs (the monochromator sweep and the LED measurement in the same world: the docs' measurement
workflow, whose predictions are also checked per seed) meets every target; from the nominal camera with its
curves' shift and width fitted it meets the R^2 and dE00 prediction targets but its re-optimised lights are not
better than the preset; LED and gain parameters alone cannot reach R^2 0.999 (a gain cannot fix a camera's shape).
R^2 is recomputed here from the profile's stored observations (no line refitted: gain and offset errors count).
Why 600x400 frames and not the usual 240x160: there a training patch averages 9 superpixels and one capture's test
dE00 varies by +-6 % between seeds (0.284-0.321 for the same lights), as much as the differences checked here.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from dualrgb.app.cli import main
from dualrgb.app.workflow.calibration.profile import load_profile
from dualrgb.simulation.stand_fit import predict
from dualrgb.simulation.stand_model import StandModel

pytestmark = [pytest.mark.slow, pytest.mark.timeout(3600)]     # a hang guard: ~3 min quiet, ~15 at load 8
MEASURED, NOMINAL_CAMERA, LEDS_ONLY = "fitted, measured camera and LEDs", "fitted, nominal camera", \
    "fitted, nominal camera, LEDs only"


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("stand-study")
    assert main(["study", "stand", "--out", str(out), "--seeds", "3", "--frame-size", "600x400"]) == 0
    whole = json.loads((out / "stand.json").read_text())
    assert whole["format"] == "dualrgb-study-stand/2" and "software" in whole and list(whole["worlds"]) == [
        "mismatched-d700"]
    return out, whole["worlds"]["mismatched-d700"]


def r2(pred: np.ndarray, captured: np.ndarray) -> float:
    """Worst channel's 1 - SS_res / SS_tot."""
    p, y = pred.reshape(len(pred), -1), captured.reshape(len(captured), -1)
    return float(np.min(1 - ((y - p) ** 2).sum(0) / ((y - y.mean(0)) ** 2).sum(0)))


def test_the_fitted_model_predicts_the_captured_dns_and_test_de00(study):
    out, doc = study
    profile = load_profile(doc["files"]["calibration"])
    obs = profile.stand_observations
    m = doc["models"]
    measured = StandModel.from_dict(m[MEASURED]["model"])
    pred = predict(measured, obs)
    print("\n[stand] " + "; ".join(f"{k}: R2 {v['r2_train']:.5f}/{v['r2_test']:.5f}, test dE00 miss "
                                   f"{100 * v['miss']['test']:+.1f} %" for k, v in m.items()))
    assert r2(pred.train, obs.train) >= 0.999 and r2(pred.test, obs.test) >= 0.999
    assert abs(m[MEASURED]["miss"]["test"]) <= 0.10
    nominal = predict(StandModel(), obs)
    assert r2(nominal.train, obs.train) < 0.99                     # the world is not the nominal model
    assert m["nominal"]["r2_train"] == pytest.approx(r2(nominal.train, obs.train), abs=1e-9)
    assert m[NOMINAL_CAMERA]["r2_train"] >= 0.999 and abs(m[NOMINAL_CAMERA]["miss"]["test"]) <= 0.10
    assert m[LEDS_ONLY]["r2_train"] < 0.999                         # a gain cannot fix the camera's shape


def test_lights_reoptimised_on_the_fitted_model_are_captured_better(study):
    _, doc = study
    cap = {k: v["captured"] for k, v in doc["lights"].items()}
    print("\n[stand] captured train / test dE00: " + "; ".join(f"{k} {v['train']:.4f} / {v['test']:.4f}"
                                                             for k, v in cap.items()))
    preset, mine, world = cap["nominal preset"], cap[f"re-optimised: {MEASURED}"], cap["re-optimised: world"]
    assert mine["train"] <= preset["train"] and mine["test"] <= preset["test"]
    assert mine["train"] <= 1.05 * world["train"]
    assert all(len(v["train_each"]) == 3 for v in cap.values())


def test_the_study_writes_its_figures_and_the_calibration_its_stand_model(study, capsys):
    out, doc = study
    assert (out / "study_stand.png").stat().st_size > 10_000 and "| fitted, measured camera and LEDs |" in \
        (out / "SUMMARY.md").read_text()
    assert (out / "study_stand_models.png").stat().st_size > 10_000
    profile = load_profile(doc["files"]["calibration"])
    report = json.loads((profile.path.parent / "report" / "report.json").read_text())
    assert report["dn_validation"]["min_r2"] < 0.99 < report["stand_model"]["dn_validation"]["min_r2"]
    assert (profile.path.parent / "report" / "dn_validation_fitted.png").is_file()
    assert main(["calibration", "show", str(profile.path)]) == 0
    shown = capsys.readouterr().out
    assert "stand model: fitted to the training target and flats from the nominal camera" in shown
    assert "  flare: 0.004" in shown or "  flare: 0.005" in shown


def test_the_measurement_workflow_predicts_each_seeds_capture(study):
    """The docs' workflow (docs/how-to/measure-stand.md: measure the LEDs and the camera, calibrate with both,
    re-optimise, calibrate again): each calibration's fit from the measured camera and LEDs predicts its own test
    dE00 within 12 % (10 % with the lab's own placement; the patches found in the image add a placement error the
    model does not predict: +10.4 % at worst, issue 36)."""
    _, doc = study
    flow = doc["workflow"]
    print("\n[stand] workflow test dE00 misses: preset " + ", ".join(f"{100 * m:+.1f} %" for m in
                                                                     flow["preset"]["miss"]["test_each"])
          + "; re-optimised " + ", ".join(f"{100 * m:+.1f} %" for m in flow["re-optimised"]["miss"]["test_each"]))
    for which in ("preset", "re-optimised"):
        assert len(flow[which]["miss"]["test_each"]) == 3
        assert max(abs(m) for m in flow[which]["miss"]["test_each"]) <= 0.12
    assert flow["start"]["level_curves"] and flow["start"]["leds_csv"].endswith("leds.csv")
