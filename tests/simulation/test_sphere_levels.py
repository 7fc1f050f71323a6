"""The sphere's one level model (simulation.sphere, issue 29): what a search may set (``realise``) and what the
LEDs emit at levels as set (``emitted``: the PWM grid, then each LED's measured level -> output curve), used by the
expected-captured model, the optimisers' kernel, a re-optimisation's incumbents and the stand fit. Checked against
scipy's interpolation, hand-transformed outputs and the float64 model, never against the same code."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import interp1d

from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.expected_error import ExpectedErrorEvaluator, ExpectedErrorModel
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.search import Candidate, SearchOutcome, add_incumbents, refine_top
from dualrgb.simulation.sphere import LevelCurve, SphereProperties, curves_from_dict, curves_to_dict

# a dead band to 0.006, a curve (exponent 1.4) to a knee at 0.04, proportional above: the measurement's levels
LEVELS = (0.002, 0.004, 0.006, 0.008, 0.01, 0.0125, 0.015, 0.0175, 0.02, 0.025, 0.03, 0.035, 0.04, 0.045, 0.05,
          0.06, 0.08, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1.0)


def dead_band_curve(lv):
    lv = np.asarray(lv, float)
    return np.where(lv >= 0.04, lv, 0.04 * np.clip((lv - 0.006) / 0.034, 0.0, None) ** 1.4)


CURVE = LevelCurve.measured(LEVELS, dead_band_curve(LEVELS))
SPHERE = SphereProperties(min_stable_level=0.04, curves=(CURVE,) + (None,) * 9)      # LED 1 measured
FINE = SphereProperties(pwm_max=2**40, min_stable_level=0.0)                           # no grid, nothing forbidden


def test_a_level_curve_is_the_measured_points_interpolated_over_the_whole_range():
    x = np.linspace(0.0, 1.0, 20001)
    scipy_curve = interp1d([0.0, *LEVELS], [0.0, *dead_band_curve(LEVELS)])
    assert CURVE.output(x) == pytest.approx(scipy_curve(x), abs=1e-15)
    half = LevelCurve((0.1, 0.5), (0.08, 0.45))                             # above its last point: proportional
    assert half.output(np.array([0.75, 1.0])) == pytest.approx([0.675, 0.9])
    assert half.output(np.array([0.0, 0.05])) == pytest.approx([0.0, 0.04])
    assert CURVE.output(np.array([0.01]))[0] == pytest.approx(0.04 * (0.004 / 0.034) ** 1.4)   # 0.0020: lit


def test_a_measurement_becomes_a_curve_off_at_zero_and_never_negative():
    c = LevelCurve.measured([0.0, 0.5, 0.1, 0.1, 1.0], [0.003, 0.5, 0.12, 0.08, 1.0])
    assert c.levels == (0.1, 0.5, 1.0) and c.outputs == pytest.approx((0.1, 0.5, 1.0))
    assert LevelCurve.measured([0.002, 1.0], [-1e-5, 1.0]).outputs[0] == 0.0
    with pytest.raises(ValueError, match="increasing levels"):
        LevelCurve((0.5, 0.1), (0.5, 0.1))


def test_curves_round_trip_and_a_bad_one_is_one_line():
    doc = curves_to_dict(SPHERE.curves)
    assert set(doc) == {"1"} and curves_from_dict(doc, 10) == SPHERE.curves
    for bad, fragment in (({"11": doc["1"]}, "LED '11'"), ({"2": {"level": [0.5]}}, "LED 2: level curve"),
                          ({"3": {"level": [0.5], "relative_output": ["x"]}}, "expected numbers")):
        with pytest.raises(ValueError, match=fragment) as err:
            curves_from_dict(bad, 10)
        assert "\n" not in str(err.value)


def test_emitted_keeps_a_captured_led_below_the_minimum_where_realise_forbids_it():
    levels = np.array([[0.010009918364232854, 0.0, 0.0, 0.0, 0.0, 0.1684748607614252, 1.0, 0.0, 0.0, 0.0]])
    assert SPHERE.realise(levels)[0, 0] == 0.0                            # a search may not set it ...
    out = SPHERE.emitted(levels)
    assert out[0, 0] == pytest.approx(float(dead_band_curve(levels[0, 0])), rel=1e-3) and out[0, 0] > 0  # ... lit
    assert out[0, 5:7] == pytest.approx(np.round(levels[0, 5:7] * 65535) / 65535, abs=0)   # no curve: PWM only
    nominal = SphereProperties()
    assert np.array_equal(nominal.emitted(levels), nominal.on_grid(levels))


def test_emitted_indexed_is_emitted_dense():
    rng = np.random.default_rng(0)
    idx = np.stack([rng.permutation(10)[:6].reshape(2, 3) for _ in range(50)])      # distinct LEDs per light set
    w = rng.uniform(0.0, 0.06, (50, 2, 3))
    dense = np.zeros((50, 2, 10))
    np.put_along_axis(dense, idx, w, axis=2)
    got = SPHERE.emitted(w, idx)
    assert np.array_equal(got, np.take_along_axis(SPHERE.emitted(dense), idx, axis=2))
    assert got[idx == 0] == pytest.approx(CURVE.output(np.round(w[idx == 0] * 65535) / 65535))
    assert np.array_equal(got[idx != 0], np.round(w[idx != 0] * 65535) / 65535)


@pytest.fixture(scope="module")
def setup():
    return default_setup("reflective")


PRESET = np.zeros((2, 10))
PRESET[0, [0, 5, 6]] = [0.010009918364232854, 0.1684748607614252, 1.0]   # the shipped reflective preset
PRESET[1, [2, 4, 8]] = [0.30031280994888226, 0.18751812008850233, 1.0]


def test_a_captured_light_is_predicted_with_what_its_leds_emitted(setup):
    cap = CaptureModel.virtual_lab("reflective")
    model = ExpectedErrorModel(setup, CaptureModel.virtual_lab("reflective", sphere=SPHERE))
    by_hand = np.round(PRESET * 65535) / 65535                   # the sphere's PWM steps ...
    by_hand[0, 0] = np.interp(by_hand[0, 0], [0.0, *LEVELS], [0.0, *dead_band_curve(LEVELS)])   # LED 1's curve
    truth = ExpectedErrorModel(setup, CaptureModel.virtual_lab("reflective", sphere=FINE)).expected(by_hand[None])
    captured = model.expected(PRESET[None], captured=True)
    assert captured["test"] == pytest.approx(truth["test"], rel=1e-6)
    assert captured["train"] == pytest.approx(truth["train"], rel=1e-6)
    led_off = PRESET.copy()
    led_off[0, 0] = 0.0                                           # what the old rounding predicted
    searched = model.expected(PRESET[None])
    assert searched["test"] == pytest.approx(ExpectedErrorModel(setup, cap).expected(led_off[None])["test"])
    assert abs(captured["test"][0] / searched["test"][0] - 1) > 0.2


def test_the_kernel_scores_what_the_leds_emit(setup):
    ev = ExpectedErrorEvaluator(setup, CaptureModel.virtual_lab("reflective", sphere=SPHERE))
    rng = np.random.default_rng(1)
    idx = np.stack([rng.permutation(10)[:6].reshape(2, 3) for _ in range(16)])
    w = rng.choice([0.03, 0.045, 0.05, 0.3, 1.0], size=(16, 2, 3))
    dense = np.zeros((16, 2, 10))
    np.put_along_axis(dense, idx, w, axis=2)
    want = ev.model.train_errors(ev.model.emitted(dense)).mean
    assert ev.cost_indexed(idx, w) == pytest.approx(want, rel=2e-3)


def test_an_incumbent_is_costed_and_kept_at_its_levels_as_set(setup):
    ev = ExpectedErrorEvaluator(setup, CaptureModel.virtual_lab("reflective", sphere=SPHERE))
    lights = tuple(LightSource(tuple(int(k) + 1 for k in np.flatnonzero(row)), tuple(row[row > 0]), f"l{i}")
                   for i, row in enumerate(PRESET))
    searched = Candidate(lights, float(ev.cost(PRESET[None])[0]))          # the same lights as a search sees them
    outcome = add_incumbents(ev, SearchOutcome("test", None, 0.0, 1, [searched]), [lights])
    mine = next(c for c in outcome.candidates if c.incumbent)
    captured = ev.model.expected(PRESET[None], captured=True)["train"][0]
    assert mine.train_cost == pytest.approx(captured, rel=2e-3)
    assert abs(mine.train_cost / searched.train_cost - 1) > 0.05           # LED 1 lit, not rounded off
    refine_top(ev, outcome, 2)
    assert mine.sources[0].levels[0] == PRESET[0, 0]                        # the level as set, kept
    assert mine.expected_train_errors.mean == pytest.approx(captured)
    assert mine.to_dict()["in_use"] is True
    assert searched.sources[0].leds == (1, 6, 7) and searched.sources[0].levels[0] == 0.0   # a search's: realised
