"""The stand model and its fit (simulation.led_shapes, simulation.stand_model, simulation.stand_fit), against
captures computed by hand (tests/simulation/stand_data.py: np.interp shifts, explicit eq 5.10 sums)."""
from __future__ import annotations

import numpy as np
import pytest

from dualrgb.simulation.camera_model import led_responses
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.led_shapes import shaped_led_spectra
from dualrgb.simulation.objective import PatchSet
from dualrgb.simulation.sphere import LevelCurve
from dualrgb.simulation.stand_fit import Priors, fit_stand, predict, r2_per_channel
from dualrgb.simulation.stand_model import StandModel, StandParameters
from tests.simulation.stand_data import LIGHTS, hand_observations

SHIFT = np.array([2.0, 0.0, -3.0, 0.0, 3.0, -2.0, 1.5, 3.0, 2.5, 0.0])     # LEDs 2, 4, 10 are never lit
OUTPUT = np.array([0.9, 1.0, 1.1, 1.0, 0.95, 1.05, 0.9, 1.1, 1.0, 1.0])
GAINS = (0.8, 1.1, 1.3)
D700 = "resources/cameras/nikon_d700_rawtoaces.csv"


def test_led_shapes_move_stretch_and_scale_a_spectrum():
    wl = np.arange(380.0, 781.0)
    g = np.exp(-0.5 * ((wl - 500.0) / 10.0) ** 2)[None]
    moved = shaped_led_spectra(wl, g, [4.0])[0]
    assert wl[np.argmax(moved)] == 504.0 and moved.max() == pytest.approx(1.0)
    wide = shaped_led_spectra(wl, g, None, [1.5], [0.5])[0]
    half = wl[wide >= 0.25]                                            # half of the scaled peak 0.5
    assert half[-1] - half[0] == pytest.approx(1.5 * 2.3548 * 10.0, abs=2.0) and wide.max() == pytest.approx(0.5)
    assert shaped_led_spectra(wl, g)[0] is not g[0] and np.array_equal(shaped_led_spectra(wl, g)[0], g[0])


def test_predict_is_the_hand_computation():
    obs = hand_observations(SHIFT, OUTPUT, GAINS, 0.004, camera_csv=D700)
    model = StandModel(camera_csv=D700, params=StandParameters(tuple(OUTPUT), tuple(SHIFT), channel_gain=GAINS,
                                                               flare=0.004))
    pred = predict(model, obs)
    assert pred.white == pytest.approx(obs.white, rel=1e-9)
    assert pred.train == pytest.approx(obs.train, rel=1e-9) and pred.test == pytest.approx(obs.test, rel=1e-9)
    assert min(r2_per_channel(pred.train, obs.train)) == pytest.approx(1.0)


def test_the_fit_recovers_a_known_stand_with_a_measured_camera():
    obs = hand_observations(SHIFT, OUTPUT, GAINS, 0.005, camera_csv=D700, noise=0.001)
    fit = fit_stand(obs, StandModel(camera_csv=D700))
    p = fit.model.params
    lit = [0, 2, 4, 5, 6, 7, 8]
    assert np.abs(np.array(p.led_peak_shift_nm)[lit] - SHIFT[lit]).max() < 0.3
    # outputs and gains are only known up to one common factor (a brighter sphere or a more sensitive camera):
    ratio = np.array(p.led_output_scale)[lit] / OUTPUT[lit]
    assert ratio.std() / ratio.mean() < 0.01
    assert np.array(p.channel_gain) / np.array(GAINS) * ratio.mean() == pytest.approx(1.0, rel=0.01)
    assert p.flare == pytest.approx(0.005, abs=3e-4)
    assert p.led_peak_shift_nm[1] == 0.0 and p.led_output_scale[3] == 1.0      # never lit: stay nominal, not fitted
    assert not any(par.key.startswith("camera_") for par in fit.parameters)    # a measured camera keeps its shape
    assert fit.min_r2("fitted", "test") > 0.9999 > fit.min_r2("start", "test")
    assert fit.warnings == []


def test_uncertainties_cover_the_truth():
    obs = hand_observations(SHIFT, OUTPUT, GAINS, 0.005, camera_csv=D700, noise=0.004, seed=3)
    fit = fit_stand(obs, StandModel(camera_csv=D700))
    shifts = {par.key: par for par in fit.parameters if par.key.startswith("led_peak_shift_nm")}
    z = [(par.value - SHIFT[int(key.split("[")[1][:-1])]) / par.sd for key, par in shifts.items()]
    assert max(abs(v) for v in z) < 4.0, z
    assert all(0 < par.sd < par.prior_sd for par in shifts.values())
    flare = next(par for par in fit.parameters if par.key == "flare")
    assert abs(flare.value - 0.005) < 4 * flare.sd


def test_a_parameter_on_its_bound_is_one_warning_line(caplog):
    obs = hand_observations(flare=0.3)                                   # beyond the flare's upper bound 0.2
    fit = fit_stand(obs, StandModel(), Priors(flare_sd=1.0))
    bound = [w for w in fit.warnings if "bound" in w]                  # (identifiability lines come after)
    assert len(bound) == 1 and all("\n" not in w for w in fit.warnings)
    assert bound[0].startswith("stand fit: flare = 0.2 is at its upper bound 0.2") and fit.warnings[0] == bound[0]
    assert next(p for p in fit.parameters if p.key == "flare").at_bound == "upper"
    assert bound[0] in caplog.text


def test_a_nominal_camera_gets_its_curves_shift_and_width_fitted():
    obs = hand_observations(SHIFT, OUTPUT, GAINS, 0.005, camera_csv=D700)
    with_shape, without = fit_stand(obs), fit_stand(obs, camera_shape=False)
    assert any(par.key == "camera_width_scale[2]" for par in with_shape.parameters)
    assert with_shape.min_r2("fitted") > without.min_r2("fitted")


def test_the_stand_models_setup_carries_its_leds_camera_and_flare_into_the_optimiser():
    params = StandParameters(tuple(OUTPUT), tuple(SHIFT), channel_gain=GAINS, flare=0.01)
    setup = StandModel(camera_csv=D700, params=params).setup("reflective")
    nominal = default_setup("reflective")
    from tests.simulation.stand_data import hand_camera, hand_leds

    assert setup.leds == pytest.approx(hand_leds(SHIFT, OUTPUT), rel=1e-9, abs=1e-12)
    assert setup.camera == pytest.approx(hand_camera(D700) * np.array(GAINS), rel=1e-9, abs=1e-12)
    assert setup.train.spectra is nominal.train.spectra and setup.flare == 0.01
    R = led_responses(setup.leds, setup.train.spectra, setup.camera)
    assert PatchSet(setup, setup.train).R == pytest.approx(R + 0.01 * R.mean(axis=1, keepdims=True))


@pytest.mark.fault("input")
@pytest.mark.parametrize("doc,fragment", [({"flare": "x"}, "'flare': expected a number"),
                                          ({"channel_gain": [1, 2]}, "'channel_gain': expected 3 numbers")])
def test_bad_stored_parameters_are_one_line(doc, fragment):
    with pytest.raises(ValueError, match=fragment) as info:
        StandParameters.from_dict(doc)
    assert "\n" not in str(info.value)


def test_lights_and_levels_shape_checked():
    obs = hand_observations()
    with pytest.raises(ValueError, match="white has shape"):
        type(obs)(LIGHTS, obs.white[:2], obs.train, obs.train_spectra, obs.train_frame)


def test_a_measured_level_curve_lets_the_fit_see_a_dim_led_as_it_is(caplog):
    """LED 1 set at 1 % in a sphere whose driver gives a fifth of that there (dead band 0.6 %, knee 4 %): with the
    stand folder's measured curve the fit keeps LED 1's output at its spectra's (1), without it the fit folds the
    curve into LED 1's output scale (about 0.2, many prior sd away: one warning line), as issue 29 found."""
    levels = np.round(np.array([[0.01, 0.0, 0.0, 0.0, 0.0, 0.17, 1.0, 0.0, 0.0, 0.0],
                                [0.0, 0.0, 0.3, 0.0, 0.19, 0.0, 0.0, 0.0, 1.0, 0.0]]) * 65535) / 65535
    points = np.array([0.004, 0.006, 0.008, 0.01, 0.0125, 0.02, 0.04, 0.1, 1.0])
    truth = np.where(points >= 0.04, points, 0.04 * np.clip((points - 0.006) / 0.034, 0, None) ** 1.4)

    def by_hand(lv):
        out = lv.copy()
        out[:, 0] = np.interp(lv[:, 0], [0.0, *points], [0.0, *truth])
        return out
    obs = hand_observations(camera_csv=D700, levels=levels, noise=0.001, emitted=by_hand)
    curves = (LevelCurve.measured(points, truth),) + (None,) * 9
    with_curve = fit_stand(obs, StandModel(camera_csv=D700, level_curves=curves))
    without = fit_stand(obs, StandModel(camera_csv=D700))
    led1 = {name: next(p for p in f.parameters if p.key == "led_output_scale[0]")
            for name, f in (("with", with_curve), ("without", without))}
    assert abs(led1["with"].value - 1.0) < 3 * led1["with"].sd and led1["with"].sd < 0.15
    assert led1["without"].value < 0.5 and led1["without"].moved_sd < -3
    assert any(w.startswith("stand fit: LED 1 output = ") and "moved" in w for w in without.warnings)
    assert not any("moved" in w for w in with_curve.warnings)
    assert with_curve.min_r2() > 0.9999


def test_identifiability_names_what_the_captures_leave_to_the_priors():
    """Every LED output up and every channel gain down together changes no prediction: that combination is
    reported as left to the priors (posterior sd = prior sd along it), its members as strongly correlated; the
    peak shifts, which no other parameter imitates, are determined by the captures."""
    obs = hand_observations(SHIFT, OUTPUT, GAINS, 0.004, camera_csv=D700, noise=0.001)
    fit = fit_stand(obs, StandModel(camera_csv=D700))
    weakest = fit.weak_directions[0]
    assert weakest["sd_ratio"] == pytest.approx(1.0, abs=1e-3)
    signs = {name.split(" ")[0]: np.sign(w) for name, w in weakest["combination"]}
    assert signs["LED"] == -signs["gain"]
    members = {name for name, _ in weakest["combination"]}
    assert {f"LED {n} output" for n in (1, 3, 5, 6, 7, 8, 9)} <= members
    assert all(abs(c["r"]) >= 0.9 for c in fit.correlations) and fit.correlations
    assert fit.correlations == sorted(fit.correlations, key=lambda c: -abs(c["r"]))
    shifts = [p for p in fit.parameters if p.key.startswith("led_peak_shift_nm")]
    assert all(p.determined_by == "captures" for p in shifts)
    doc = fit.to_dict()
    assert doc["identifiability"]["moved_limit"] == 3.0 and "sd_ratio" in doc["parameters"][0]
