"""A calibration profile with a spectral estimator, and a stack to deliver, for the spectral deliverables' tests
(tests/app/test_spectral_deliverables.py, tests/gui/test_spectra_views.py)."""
from __future__ import annotations

import numpy as np
from workflow_profiles import make_profile

from dualrgb.app.processing.pipeline import ChannelStack
from dualrgb.simulation.grid import DEFAULT_GRID
from dualrgb.simulation.spectral_estimation import SpectralEstimator

WL = DEFAULT_GRID.wavelengths
SPECTRAL = {"test": {"rmse": {"mean": 0.042, "p90": 0.071}, "gfc": {"mean": 0.991},
                     "de00": {"D65": {"mean": 0.24}, "A": {"mean": 0.43}}}}


def estimator(channels=("R1", "G1", "B1"), seed: int = 3) -> SpectralEstimator:
    """A plausible map: each channel a smooth bump over the grid (values ~ 0.5 give factors within [0, 1])."""
    centres = np.linspace(450, 650, len(channels))
    M = np.stack([np.exp(-0.5 * ((WL - c) / 60.0) ** 2) for c in centres], axis=1)
    M += np.random.default_rng(seed).normal(0, 0.05, M.shape)
    return SpectralEstimator(M, WL.copy(), list(channels), "wiener", {"prior": {"smoothness": 0.98}})


def spectral_profile(tmp_path):
    return make_profile(tmp_path, estimator=estimator(), spectral=SPECTRAL)


def stack(h: int = 23, w: int = 31, seed: int = 5) -> ChannelStack:
    data = np.random.default_rng(seed).uniform(-0.1, 1.4, (h, w, 3)).astype(np.float32)   # some clip at 0 and 1
    data[4, 7, 2] = np.nan
    return ChannelStack(data, ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0})
