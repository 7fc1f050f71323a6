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
