"""The stand model in the calibration profile and for re-optimisation (app.workflow.calibration.stand_calibration,
app.workflow.calibration.stand_reoptimise, ``simulate --stand``), on captures computed by hand
(tests/simulation/stand_data.py)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dualrgb.app.cli import main
from dualrgb.app.workflow.calibration.profile import ProfileError, describe, load_profile
from dualrgb.app.workflow.calibration.stand_calibration import StandResult, centre_level
from dualrgb.app.workflow.calibration.stand_reoptimise import Measurements, assemble
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.stand_fit import fit_stand
from dualrgb.simulation.stand_model import StandModel
from tests.simulation.stand_data import hand_observations
from tests.workflow_profiles import make_profile

SHIFT = [2.0, 0.0, -3.0, 0.0, 3.0, -2.0, 1.5, 3.0, 2.5, 0.0]
D700 = "resources/cameras/nikon_d700_rawtoaces.csv"


@pytest.fixture(scope="module")
def stand():
    obs = hand_observations(SHIFT, flare=0.005, camera_csv=D700, noise=0.001)
    fit = fit_stand(obs)                                        # from the nominal camera, as a calibration does
    de = {"matrix": "least-squares", "captured": {"train": 0.5, "test": 0.3},
          "predicted": {"start": {"train": 0.45, "test": 0.27}, "fitted": {"train": 0.49, "test": 0.31}},
          "miss": {"start": {"train": -0.1, "test": -0.1}, "fitted": {"train": -0.02, "test": 0.0333}}}
    return StandResult(fit, obs, ["P light 1", "P light 2", "P light 3"], "reflective",
                       CaptureModel.virtual_lab("reflective"), de)


@pytest.fixture
def profile_path(tmp_path, stand):
    prof = make_profile(tmp_path, stand=stand.summary(), stand_observations=stand.observations)
    return prof.path


@pytest.mark.parametrize("cfa", ["RGGB", "BGGR", "GRBG"])
def test_the_open_gates_centre_level_per_cfa_colour(cfa):
    level = {"R": 100.0, "G": 200.0, "B": 300.0}
    mosaic = np.zeros((41, 63))                                  # odd sides: the crop must keep the CFA phase
    for pos, colour in enumerate(cfa):
        mosaic[pos // 2::2, pos % 2::2] = level[colour]
    mosaic[:6] = 1e6                                             # outside the central quarter: ignored
    assert centre_level(mosaic, cfa) == pytest.approx([100.0, 200.0, 300.0])


def test_the_profile_keeps_the_stand_model_and_its_observations(profile_path, stand):
    prof = load_profile(profile_path)
    assert prof.stand["model"] == json.loads(json.dumps(stand.fit.model.to_dict()))
    assert prof.stand_observations.train == pytest.approx(stand.observations.train)
    assert prof.stand_observations.test_spectra == pytest.approx(stand.observations.test_spectra)
    lines = describe(prof)
    text = "\n".join(lines)
    assert "stand model: fitted to the training target and flats from the nominal camera" in text
    assert "test mean dE00 (least-squares): captured 0.300, predicted nominal 0.270 (-10.0 %), fitted 0.310" in text
    assert any(line.startswith("  LED peak shift (nm): 1 ") for line in lines)
    assert any(line.startswith("  flare: 0.00") for line in lines)
    # identifiability (issue 29): posterior / prior sd per parameter, correlations, what the priors decide
    assert "  determined by (posterior sd / prior sd; below 0.5 the captures, from 0.71 mainly the prior):" in lines
    assert any(line.startswith("    LED peak shift (nm): 1 0.") for line in lines)
    assert any(line.startswith("  correlated (|r| >= 0.9): ") for line in lines)
    assert any(line.startswith("  left to the priors (posterior sd 1.00 of the prior's along): ") for line in lines)


def test_an_old_profile_loads_and_says_the_stand_was_not_fitted(tmp_path):
    prof = load_profile(make_profile(tmp_path).path)
    assert prof.stand == {} and prof.stand_observations is None
    assert "stand model: not fitted" in "\n".join(describe(prof))
    with pytest.raises(ProfileError, match="no stand model in it"):
        assemble(prof)


def test_the_stand_model_is_the_fit_or_a_refit_from_the_curves_given(profile_path, stand):
    prof = load_profile(profile_path)
    model, notes = assemble(prof)
    assert model.params == stand.fit.model.params and "fitted parameters of calibration cal-test" in notes[1]
    assert notes[-1].startswith("warning: the camera is the nominal one")
    refit, notes = assemble(prof, Measurements.of(camera_csv=D700, min_level=0.02))
    assert refit.camera_measured and refit.min_stable_level == 0.02 and "refitted" in notes[1]
    lit = [0, 2, 4, 5, 6, 8]
    assert np.array(refit.params.led_peak_shift_nm)[lit] == pytest.approx(np.array(SHIFT)[lit], abs=0.2)
    assert not any("warning" in n for n in notes)


def test_without_a_calibration_the_stand_model_is_nominal_plus_measurements():
    model, _ = assemble(None, Measurements.of(camera_csv=D700))
    assert model.params == StandModel().params and model.camera_measured


def test_simulate_stand_writes_a_preset_that_names_the_stand_model(profile_path, tmp_path, capsys):
    preset = tmp_path / "p.json"
    args = ["simulate", "--stand", str(profile_path), "--camera-csv", D700, "--top", "1", "--preset-out", str(preset),
            "--json", str(tmp_path / "r.json")]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "stand: refitted to calibration cal-test's captures" in err
    doc = json.loads(preset.read_text())
    assert doc["model"]["stand"]["camera_csv"].endswith("nikon_d700_rawtoaces.csv") and doc["name"].endswith("cal-test")
    shifts = doc["model"]["stand"]["params"]["led_peak_shift_nm"]
    assert shifts[2] == pytest.approx(-3.0, abs=0.2)
    assert json.loads((tmp_path / "r.json").read_text())["stand"]["calibration"] == str(profile_path)


@pytest.mark.fault("input")
def test_simulate_stand_with_a_profile_without_a_stand_model_is_one_line(tmp_path, capsys):
    path = make_profile(tmp_path).path
    assert main(["simulate", "--stand", str(path), "--top", "1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no stand model in it" in err[0], err


def _stand_folder(folder: Path) -> Path:
    """A stand folder as `dualrgb measure leds` writes it, by hand: LED 1's level curve (dead band 0.6 %, knee
    4 %) and the minimum stable level."""
    folder.mkdir()
    levels = [0.0, 0.006, 0.01, 0.02, 0.04, 0.1, 1.0]
    outputs = [0.0, 0.0, 0.002, 0.0104, 0.04, 0.1, 1.0]
    (folder / "stand.json").write_text(json.dumps({"format": "dualrgb-stand-measurement/1", "min_stable_level": 0.04,
                                                   "leds": {"1": {"levels": {"level": levels,
                                                                             "relative_output": outputs}}}}))
    return folder


def test_a_stand_folders_level_curves_join_the_model_and_refit_it(profile_path, tmp_path):
    prof = load_profile(profile_path)
    model, notes = assemble(prof, Measurements.of(stand_dir=_stand_folder(tmp_path / "stand")))
    assert "level -> output measured per LED" in notes[0] and "refitted" in notes[1]   # other curves: refitted
    assert model.level_curves[0] is not None and model.level_curves[0].outputs[1] == 0.002
    assert model.min_stable_level == 0.04 and StandModel.from_dict(model.to_dict()) == model
    sphere = model.capture(CaptureModel.virtual_lab("reflective")).sphere
    assert sphere.emitted(np.array([[0.01] + [0.0] * 9]))[0, 0] == pytest.approx(0.002, rel=2e-3)   # PWM 655
    assert sphere.realise(np.array([0.01]))[0] == 0.0                      # new lights: not below the minimum


@pytest.mark.fault("input")
def test_a_bad_level_curve_in_a_stand_folder_is_one_line(tmp_path):
    folder = _stand_folder(tmp_path / "stand")
    doc = json.loads((folder / "stand.json").read_text())
    doc["leds"]["1"]["levels"]["level"] = [0.0, 0.5, 0.1, 1.0, 0.2, 0.3, 0.4]
    doc["leds"]["1"]["levels"]["relative_output"] = [0.0, 0.5, "x", 1.0, 0.2, 0.3, 0.4]
    (folder / "stand.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"stand\.json: LED 1: level curve: expected numbers") as err:
        Measurements.of(stand_dir=folder)
    assert "\n" not in str(err.value)
