"""dualrgb.app.captured_accuracy: a light set captured through the virtual camera and app.processing (small frames)
gives the patch values and the accuracy the simulation predicts."""
import numpy as np
import pytest

from dualrgb.app.captured_accuracy import capture_patch_values, captured_errors
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.objective import Evaluator
from dualrgb.simulation.studies.noise import NoiseModel


def test_virtual_lab_capture_matches_the_noise_model():
    setup = default_setup("reflective")
    model = NoiseModel(setup)
    W = np.zeros((2, 10))
    W[0, [0, 5, 7]] = 1.0
    W[1, [2, 4, 8]] = 1.0
    t = model.exposures(W)
    values = capture_patch_values(setup, W, t, dark_frames=2, seed=3)
    expected, _ = model.values(W[None])
    assert values["train"].shape == expected[0].shape
    assert np.median(np.abs(values["train"] / np.maximum(expected[0], 1e-6) - 1)) < 0.01
    err = captured_errors(setup, W, t, repeats=1, dark_frames=2)
    train, test = Evaluator(setup).stats(W)
    assert err["train"] == pytest.approx(train.mean, abs=0.08)
    assert err["test"] == pytest.approx(test.mean, abs=0.15)


def test_per_pixel_captured_error_is_what_the_expected_model_predicts_for_one_pixel():
    """The matrix fitted on the captured patch means applied to each captured superpixel (the virtual camera's
    photon, read and flat-field noise): its mean and p90 dE00 are the expected-captured model's one-pixel
    prediction (simulation.expected_error.ExpectedErrorModel.pixel_errors, an independent analytic propagation
    with a Monte Carlo through CIEDE2000) within 10 %, and about twice the patch-mean figure."""
    from dualrgb.app.captured_accuracy import capture_model
    from dualrgb.simulation.expected_error import ExpectedErrorModel

    setup = default_setup("reflective")
    W = np.zeros((2, 10))
    W[0, [0, 5, 7]] = 1.0
    W[1, [2, 4, 8]] = 1.0
    err = captured_errors(setup, W, NoiseModel(setup).exposures(W), repeats=1, dark_frames=2)
    predicted = ExpectedErrorModel(setup, capture_model(setup, dark_frames=2)).pixel_errors(W, captured=True)
    for key in ("train", "test"):
        assert err[f"per_pixel_{key}"] == pytest.approx(predicted[key].mean, rel=0.10)
        assert err[f"per_pixel_{key}"] > 1.8 * err[key]
    assert err["per_pixel_test_p90"] == pytest.approx(predicted["test"].p90, rel=0.10)
