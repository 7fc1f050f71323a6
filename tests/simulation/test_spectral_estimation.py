"""Spectral estimation methods against independent computations (scipy.linalg, textbook formulas written here),
bounded output, JSON round trip, cross-validation on the training target alone."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg as sla

from dualrgb import resources
from dualrgb.simulation.camera_model import flat_fielded_sensitivities
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.presets import load_preset
from dualrgb.simulation.spectral_estimation import (
    QUANTITIES,
    SPECTRAL_METHODS,
    SpectralEstimationError,
    SpectralEstimator,
    SpectralPrior,
    SpectralTraining,
    fit_spectral,
)
from dualrgb.simulation.spectral_metrics import seen_wavelengths, spectral_rmse
from dualrgb.simulation.spectral_selection import candidates, cross_validate, select_estimator


def _system(mode: str = "reflective", noise: float = 1e-6):
    """The packaged setup under the shipped colour preset (PSO lights), noise-free values."""
    s = default_setup(mode)
    preset = load_preset(resources.path("presets", f"{mode}_pso.json"))
    S = flat_fielded_sensitivities(np.stack([src.spectrum(s.leds) for src in preset.sources]), s.camera)
    A = s.illuminant[:, None] * s.cmfs * 100.0 / float(s.illuminant @ s.cmfs[:, 1])
    training = SpectralTraining(s.train.spectra @ S, s.train.spectra, s.grid.wavelengths, sensitivities=S,
                                quantity=QUANTITIES[mode], noise_var=np.full(S.shape[1], noise), colour_weights=A)
    return s, S, training


def test_wiener_equals_the_information_form():
    """M = K S (S^T K S + N)^-1 against the textbook's other form (S N^-1 S^T + K^-1)^-1 S N^-1 (scipy)."""
    _, S, training = _system(noise=1e-4)
    for prior in (SpectralPrior(0.95, 0.0), SpectralPrior(0.99, 0.5)):
        est = fit_spectral(training, "wiener", prior=prior)
        K = prior.matrix(training.spectra, training.wavelengths)
        Ninv = np.diag(1.0 / training.noise_var)
        info = sla.solve(S @ Ninv @ S.T + sla.inv(K), S @ Ninv, assume_a="sym")
        assert np.allclose(est.matrix, info, rtol=1e-5, atol=1e-6 * np.abs(info).max())   # inv(K) costs digits


def test_pinv_equals_scipy_least_squares_and_ridge():
    _, _, training = _system()
    C, R = training.values, training.spectra
    plain = fit_spectral(training, "pinv")
    assert np.allclose(plain.matrix, sla.lstsq(C, R)[0].T, atol=1e-9)
    lam = 1e-3 * np.trace(C.T @ C) / C.shape[1]          # the ridge as an augmented least-squares problem
    aug = sla.lstsq(np.vstack([C, np.sqrt(lam) * np.eye(C.shape[1])]), np.vstack([R, np.zeros((C.shape[1],
                                                                                              R.shape[1]))]))[0]
    assert np.allclose(fit_spectral(training, "pinv", ridge=1e-3).matrix, aug.T, atol=1e-9)


def test_matrix_r_is_colorimetrically_exact_with_the_wiener_black():
    """Zhao & Berns: the estimate's XYZ under the reference illuminant is the colour matrix's, and its
    metameric black (the part outside the span of illuminant x CMFs, projected with scipy's orthonormal basis)
    is the Wiener estimate's."""
    _, _, training = _system()
    A = training.colour_weights
    M_xyz = sla.lstsq(training.values, training.spectra @ A)[0]
    mr = fit_spectral(training, "matrix-r", prior=SpectralPrior(0.98, 0.75))
    w = fit_spectral(training, "wiener", prior=SpectralPrior(0.98, 0.75))
    values = training.values[:40]
    assert np.allclose(values @ mr.matrix.T @ A, values @ M_xyz, rtol=1e-8, atol=1e-8)
    Q = sla.orth(A)
    black = np.eye(len(A)) - Q @ Q.T
    assert np.allclose(black @ mr.matrix, black @ w.matrix, atol=1e-10)
    given = fit_spectral(SpectralTraining(**{**training.__dict__, "xyz_matrix": 1.01 * M_xyz}), "matrix-r")
    assert np.allclose(values @ given.matrix.T @ A, values @ (1.01 * M_xyz), rtol=1e-8, atol=1e-8)


def test_estimates_are_bounded_and_keep_float32_and_nan():
    _, _, training = _system()
    est = fit_spectral(training, "pinv")
    wild = np.random.default_rng(0).normal(0, 5, (50, 6))
    out = est.apply(wild)
    assert out.min() >= 0.0 and out.max() <= 1.0 and (out == 1.0).any() and (out == 0.0).any()
    band = wild.astype(np.float32).reshape(5, 10, 6)
    band[0, 0, 2] = np.nan
    cube = est.apply(band)
    assert cube.dtype == np.float32 and cube.shape == (5, 10, 38)
    assert np.isnan(cube[0, 0]).all() and np.isfinite(cube[1:]).all()
    assert np.allclose(cube[1:], np.clip(band[1:] @ est.matrix.T, 0, 1), atol=1e-5)


def test_json_round_trip_and_damaged_input():
    _, _, training = _system()
    est = fit_spectral(training, "wiener")
    back = SpectralEstimator.from_dict(json.loads(json.dumps(est.to_dict())))
    assert back.method == "wiener" and back.channels == est.channels and back.bounds == (0.0, 1.0)
    assert np.array_equal(back.apply(training.values), est.apply(training.values))
    assert back.settings["prior"] == {"smoothness": 0.98, "training_weight": 0.75}
    bad = est.to_dict()
    bad["matrix"] = bad["matrix"][:-1]
    with pytest.raises(SpectralEstimationError, match="cal.json: matrix"):
        SpectralEstimator.from_dict(bad, "cal.json")
    with pytest.raises(SpectralEstimationError, match="format"):
        SpectralEstimator.from_dict({"matrix": []}, "cal.json")
    with pytest.raises(SpectralEstimationError, match="expects 6 channels"):
        est.apply(np.ones((3, 5)))


def test_wiener_needs_sensitivities_and_unknown_methods_are_named():
    _, _, training = _system()
    blind = SpectralTraining(training.values, training.spectra, training.wavelengths)
    with pytest.raises(SpectralEstimationError, match="sensitivities"):
        fit_spectral(blind, "wiener")
    with pytest.raises(SpectralEstimationError, match="expected one of wiener, matrix-r, pinv"):
        fit_spectral(training, "pca")
    assert {c.method for c in candidates(blind)} == {"pinv"}          # no colour weights, no sensitivities
    assert set(SPECTRAL_METHODS) == {c.method for c in candidates(training)}


def test_cross_validation_is_held_out_and_picks_the_minimum():
    _, _, training = _system()
    cands = [c for c in candidates(training) if c.method == "pinv"]
    errors = cross_validate(training, cands, folds=5, seed=3)
    # by hand for plain least squares: the same seeded folds, numpy's lstsq
    parts = np.array_split(np.random.default_rng(3).permutation(len(training.values)), 5)
    by_hand = np.empty(len(training.values))
    for held in parts:
        keep = np.setdiff1d(np.arange(len(training.values)), held)
        M = np.linalg.lstsq(training.values[keep], training.spectra[keep], rcond=None)[0]
        by_hand[held] = np.sqrt(np.mean((np.clip(training.values[held] @ M, 0, 1) - training.spectra[held]) ** 2,
                                        axis=1))
    assert np.allclose(errors[0], by_hand, atol=1e-10)
    sel = select_estimator(training)
    assert sel.cv_rmse[sel.chosen.label()] == min(sel.cv_rmse.values())
    assert np.allclose(sel.estimator.matrix, sel.chosen.fit(training).matrix)


def test_default_estimate_on_the_packaged_cc24():
    """Noise-free, shipped PSO lights, chosen on rawtoaces-190 by cross-validation: CC24 mean spectral RMSE 0.042
    over 410-780 nm (the camera is blind above ~690 nm, where the estimate is the prior's) and 0.011 where it
    sees; better than least squares (0.056)."""
    s, S, training = _system()
    sel = select_estimator(training)
    test_values = s.test.spectra @ S
    rmse = spectral_rmse(sel.estimator.apply(test_values), s.test.spectra)
    seen = spectral_rmse(sel.estimator.apply(test_values), s.test.spectra, seen_wavelengths(S))
    plain = spectral_rmse(fit_spectral(training, "pinv").apply(test_values), s.test.spectra)
    assert sel.chosen.method == "wiener" and rmse.mean() < 0.045 and seen.mean() < 0.013
    assert rmse.mean() < plain.mean() - 0.01


def test_the_affine_maps_against_independent_computations():
    """offset=True: pinv is scipy's least squares with a column of ones (the ridge, when given, on the centred
    problem: the intercept is not shrunk); the affine Wiener is the linear Wiener of the spectra minus their mean,
    plus that mean (the LMMSE estimate with a mean), written out here with scipy's solver."""
    _, S, training = _system("transmissive")
    C, R = training.values, training.spectra
    ones = np.c_[C, np.ones(len(C))]
    full = sla.lstsq(ones, R)[0]                                     # (C + 1, n_wl)
    est = fit_spectral(training, "pinv", offset=True)
    assert np.allclose(est.matrix, full[:-1].T, atol=1e-8) and np.allclose(est.offset, full[-1], atol=1e-8)
    assert est.settings == {"ridge": 0.0, "offset": True}
    prior = SpectralPrior(0.98, 0.5)
    mu = R.mean(axis=0)
    K = prior.matrix(R - mu, training.wavelengths)
    noise = np.diag(training.noise_var)
    M = K @ S @ sla.solve(S.T @ K @ S + noise, np.eye(S.shape[1]), assume_a="pos")
    wiener = fit_spectral(training, "wiener", prior=prior, offset=True)
    values = training.values[:7]
    assert np.allclose(wiener.apply(values), np.clip(mu + (values - mu @ S) @ M.T, 0, 1), atol=1e-7)
    back = SpectralEstimator.from_dict(json.loads(json.dumps(wiener.to_dict())))
    assert np.array_equal(back.offset, wiener.offset) and np.array_equal(back.apply(values), wiener.apply(values))
    bad = wiener.to_dict()
    bad["offset"] = bad["offset"][:-1]
    with pytest.raises(SpectralEstimationError, match="cal.json: offset"):
        SpectralEstimator.from_dict(bad, "cal.json")
    assert fit_spectral(training, "pinv").offset is None and "offset" not in fit_spectral(training, "pinv").to_dict()


def test_film_is_estimated_with_an_offset_and_reflectances_without():
    """Film: the base's transmittance where the camera is blind is an offset, which cross-validation on the
    training film finds (the affine map chosen; the CC24 on film 0.057 -> 0.020 mean RMSE, noise-free). Reflective
    candidates stay linear (simulation.spectral_selection.OFFSETS says why)."""
    s, S, training = _system("transmissive")
    sel = select_estimator(training)
    test_values = s.test.spectra @ S
    rmse = spectral_rmse(sel.estimator.apply(test_values), s.test.spectra).mean()
    linear = select_estimator(replace(training, quantity=QUANTITIES["reflective"]))   # the same, linear maps only
    rmse_linear = spectral_rmse(linear.estimator.apply(test_values), s.test.spectra).mean()
    print(f"\nfilm CC24: affine {sel.chosen.label()} {rmse:.4f}, linear {linear.chosen.label()} {rmse_linear:.4f}")
    assert sel.chosen.offset and sel.estimator.offset is not None and "+offset" in sel.chosen.label()
    assert rmse < 0.025 < 0.05 < rmse_linear
    assert not any(c.offset for c in candidates(_system("reflective")[2]))
