"""Calibration captures of a known stand, computed by hand (independently of simulation.stand_fit's forward model):
LED rows moved with np.interp, eq 5.10 as explicit sums over the grid, the flare as a fraction of a known frame
mean. For the stand-fit tests (simulation, app, GUI)."""
from __future__ import annotations

import numpy as np

from dualrgb import resources
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.spectral_io import read_spectral_csv
from dualrgb.simulation.stand_fit import StandObservations

GRID = np.arange(410.0, 781.0, 10.0)
LIGHTS = np.round(np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.6, 1.0, 0.0, 0.0, 0.0],      # LEDs 6, 7
                            [0.0, 0.0, 0.5, 0.0, 0.8, 0.0, 0.0, 0.0, 1.0, 0.0],      # LEDs 3, 5, 9
                            [0.9, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]])     # LEDs 1, 8
                  * 65535) / 65535                  # as the sphere holds them: 16-bit PWM steps


def hand_camera(csv: str | None = None) -> np.ndarray:
    table = read_spectral_csv(csv or resources.path("cameras", "nikon_5100_npl.csv"))
    return np.stack([np.interp(GRID, table.wavelengths, table.values[:, c]) for c in range(3)], axis=1)


def hand_leds(shift=None, output=None) -> np.ndarray:
    table = read_spectral_csv(resources.path("leds", "sphere10_relative.csv"))
    wl, rows = table.wavelengths, table.values.T
    shift = np.zeros(10) if shift is None else np.asarray(shift, float)
    output = np.ones(10) if output is None else np.asarray(output, float)
    moved = [np.interp(wl, wl + shift[k], rows[k], left=0.0, right=0.0) * output[k] for k in range(10)]
    return np.stack([np.interp(GRID, wl, m) for m in moved])


def hand_observations(shift=None, output=None, gains=(1.0, 1.0, 1.0), flare=0.0, *, camera_csv=None,
                      levels=LIGHTS, n_train=80, noise=0.0, seed=0, emitted=None) -> StandObservations:
    """What a calibration of this stand would capture (DN / s at the centre), with relative ``noise``;
    ``emitted``: what the LEDs emit at ``levels`` (a function of the levels array; default proportional)."""
    setup = default_setup("reflective")
    train, test = setup.train.spectra[:n_train], setup.test.spectra
    cam, nominal_cam = hand_camera(camera_csv), hand_camera(camera_csv)
    ref = hand_leds()[[0, 5, 7]].sum(axis=0)
    k = 9900.0 * 60.0 / max(float(np.sum(ref * nominal_cam[:, c])) for c in range(3))
    E = (levels if emitted is None else emitted(levels)) @ hand_leds(shift, output)      # (L, n_wl)
    g = np.asarray(gains, float)
    rng = np.random.default_rng(seed)

    def captured(spectra):
        rel = np.array([[[np.sum(E[lt] * s * cam[:, c]) for c in range(3)] for lt in range(len(E))]
                        for s in spectra])                                # (n, L, 3)
        frame = rel.mean(axis=0) * 1.1                                   # a frame a little brighter than its patches
        dn = k * g * (rel + flare * frame)
        return dn * (1 + noise * rng.standard_normal(dn.shape)), k * g * (1 + flare) * frame
    white = k * g * (1 + flare) * np.array([[np.sum(e * cam[:, c]) for c in range(3)] for e in E])
    tr, tr_frame = captured(train)
    te, te_frame = captured(test)
    return StandObservations(levels, white, tr, train, tr_frame, test=te, test_spectra=test, test_frame=te_frame)
