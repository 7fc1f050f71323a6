"""The spectral estimate of a capture (app.processing.spectral): the model's sensitivities scaled to the captured
values, the choice on the training target alone, the report section, and the estimator in the calibration
profile (round trip; an old profile without it says spectra are unavailable)."""
from __future__ import annotations

import json

import numpy as np
import pytest
from workflow_profiles import make_profile

from dualrgb import resources
from dualrgb.app.processing.spectral import SpectralInputs, characterise_spectra, fitted_gain, model_sensitivities
from dualrgb.app.workflow.calibration.profile import ProfileError, describe, load_profile
from dualrgb.app.workflow.calibration.profile_check import seal
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.presets import load_preset
from dualrgb.simulation.spectral_estimation import SpectralEstimator


def _capture(mode: str = "reflective", gain: float = 1.0):
    setup = default_setup(mode)
    lights = list(load_preset(resources.path("presets", f"{mode}_pso.json")).sources)
    S = model_sensitivities(mode, lights)
    return setup, lights, gain * (setup.train.spectra @ S), gain * (setup.test.spectra @ S)


def test_the_models_gain_is_fitted_per_channel():
    setup, lights, vt, _ = _capture()
    S = model_sensitivities("reflective", lights)
    scale = np.array([2.0, 1.0, 0.5, 1.5, 1.0, 3.0])
    assert np.allclose(fitted_gain(S, setup.train.spectra, vt * scale), scale)


def test_a_capture_scaled_twice_gives_the_same_spectra():
    """Flat-fielded values on another scale (the model's units are arbitrary): the fitted gain absorbs it, so
    the estimate of the same patches is the same."""
    setup, lights, vt, vs = _capture()
    names = ["R1", "G1", "B1", "R2", "G2", "B2"]
    one = characterise_spectra(SpectralInputs("reflective", names, vt, setup.train.spectra, None, vs,
                                              setup.test.spectra, lights=lights))
    two = characterise_spectra(SpectralInputs("reflective", names, 2 * vt, setup.train.spectra, None, 2 * vs,
                                              setup.test.spectra, lights=lights))
    assert one.sensitivities_gain == pytest.approx([1.0] * 6) and two.sensitivities_gain == pytest.approx([2.0] * 6)
    assert np.allclose(one.estimates["test"], two.estimates["test"], atol=1e-9)
    assert one.selection.chosen.method == "wiener" and one.test["rmse"]["mean"] < 0.045
    assert set(one.summary()["de00_mean"]) == {"D65", "A", "D50", "FL11", "LED 2880 K"}


def test_without_the_lights_wiener_is_not_offered():
    setup, _, vt, vs = _capture()
    sc = characterise_spectra(SpectralInputs("reflective", [f"c{i}" for i in range(6)], vt, setup.train.spectra,
                                             np.full_like(vt, 1e-3), vs, setup.test.spectra))
    assert sc.selection.chosen.method in ("matrix-r", "pinv") and sc.sensitivities_gain is None
    assert "wiener" not in sc.selection.best_per_method()
    with pytest.raises(ValueError, match="2 lights give 6 channels but the capture has 3"):
        characterise_spectra(SpectralInputs("reflective", ["R1", "G1", "B1"], vt[:, :3], setup.train.spectra,
                                            lights=_capture()[1]))


def _estimator(channels) -> SpectralEstimator:
    wl = default_setup().grid.wavelengths
    return SpectralEstimator(np.full((len(wl), len(channels)), 0.01), wl, list(channels), "wiener",
                             {"prior": {"smoothness": 0.98, "training_weight": 0.75}})


def test_the_profile_stores_the_estimator_and_old_ones_say_unavailable(tmp_path):
    figures = {"rmse": {"mean": 0.04, "median": 0.04, "p90": 0.07, "max": 0.1},
               "gfc": {"mean": 0.99, "median": 0.99, "min": 0.9, "good": 0.8, "very_good": 0.1},
               "de00": {"D65": {"mean": 0.3}, "A": {"mean": 0.4}}}
    prof = make_profile(tmp_path / "new", estimator=_estimator(["R1", "G1", "B1"]),
                        spectral={"selection": {"chosen": "wiener (smoothness 0.98, training weight 0.75)"},
                                  "test": figures})
    back = load_profile(prof.path)
    est = back.spectral_estimator()
    values = np.random.default_rng(0).uniform(0, 20, (4, 3))
    assert np.array_equal(est.apply(values), prof.estimator.apply(values))
    assert back.spectral["test"]["rmse"]["p90"] == 0.07
    assert any(line.startswith("spectra: wiener") and "RMSE mean 0.0400 / p90 0.0700" in line
               for line in describe(back))
    with pytest.raises(ProfileError, match="maps channels R1, G1, B1, not R1, G1"):
        back.spectral_estimator(["R1", "G1"])
    old = load_profile(make_profile(tmp_path / "old").path)
    assert old.estimator is None and "spectral" not in json.loads(old.path.read_text())
    assert "spectra: unavailable" in "\n".join(describe(old))
    with pytest.raises(ProfileError, match="cal-test: spectra unavailable"):
        old.spectral_estimator()


def test_a_profile_whose_estimator_maps_other_channels_is_refused(tmp_path):
    prof = make_profile(tmp_path, estimator=_estimator(["R1", "G1", "B1"]))
    doc = json.loads(prof.path.read_text())
    doc["spectral"]["estimator"]["channels"] = ["R2", "G2", "B2"]
    prof.path.write_text(json.dumps(seal(doc)))          # as a writer would leave it (sealed: not an edit)
    with pytest.raises(ProfileError, match="spectral estimator maps R2, G2, B2 but the matrix R1, G1, B1"):
        load_profile(prof.path)
