"""Root-polynomial models (Finlayson et al. 2015) for N channels, checked against colour-science's own 3-channel
expansion and fit; noise gain and conditioning on cases with a known answer."""
from __future__ import annotations

import numpy as np
import pytest
from colour.characterisation import matrix_colour_correction_Finlayson2015, polynomial_expansion_Finlayson2015

from dualrgb.simulation.colour_models import (
    condition_number,
    expand,
    expansion_jacobian,
    n_terms,
    noise_gain,
    root_polynomial_terms,
    term_names,
    weakest_direction,
)
from dualrgb.simulation.matrix_fit import CharacterisationMatrix, fit_matrix, fit_root_polynomial


def _same_columns(a: np.ndarray, b: np.ndarray) -> bool:
    """Every column of ``a`` equals one of ``b`` and vice versa (the two expansions order their terms apart)."""
    def covered(x: np.ndarray, y: np.ndarray) -> bool:
        return all(np.isclose(x[:, [k]], y, rtol=1e-12, atol=0).all(axis=0).any() for k in range(x.shape[1]))
    return a.shape == b.shape and covered(a, b) and covered(b, a)


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_three_channel_expansion_is_colour_sciences(degree):
    rgb = np.random.default_rng(degree).uniform(0.01, 2.0, (40, 3))
    assert _same_columns(expand(rgb, degree), polynomial_expansion_Finlayson2015(rgb, degree, True))


@pytest.mark.parametrize("degree", [2, 3])
def test_three_channel_fit_predicts_as_colour_sciences_correction(degree):
    rng = np.random.default_rng(7)
    rgb, xyz = rng.uniform(0.02, 1.0, (60, 3)), rng.uniform(0.0, 1.0, (60, 3))
    ours = fit_root_polynomial(rgb, xyz, degree)
    M = matrix_colour_correction_Finlayson2015(rgb, xyz, degree, True)
    test = rng.uniform(0.02, 1.0, (25, 3))
    theirs = polynomial_expansion_Finlayson2015(test, degree, True) @ M.T
    assert np.allclose(ours.apply(test), theirs, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("degree, terms", [(1, 6), (2, 21), (3, 71)])
def test_six_channels_every_monomial_once_each_to_the_root_of_its_degree(degree, terms):
    """An independent formulation: each term as a power of the product of its channels (exponents e, total d:
    (prod c^e)^(1/d)), no pure power repeated, exposure-invariant (k c -> k terms)."""
    v = np.random.default_rng(3).uniform(0.01, 3.0, (17, 6))
    assert n_terms(6, degree) == terms == len(set(root_polynomial_terms(6, degree)))
    E = expand(v, degree)
    for k, t in enumerate(root_polynomial_terms(6, degree)):
        e = np.bincount(t, minlength=6)
        assert len(t) == 1 or e.max() < len(t)
        assert np.allclose(E[:, k], np.prod(v ** e, axis=1) ** (1.0 / len(t)), rtol=1e-12)
    assert np.allclose(expand(4.2 * v, degree), 4.2 * E, rtol=1e-12)
    assert len(term_names([f"c{i}" for i in range(6)], degree)) == terms


def test_negative_values_keep_the_linear_terms_and_clip_the_roots():
    v = np.array([[-0.2, 0.5, 0.8]])
    E = expand(v, 2)
    assert E[0, 0] == -0.2 and np.isfinite(E).all() and E[0, 3] == 0.0       # sqrt(R G) with R < 0: 0


def test_jacobian_is_the_finite_difference_of_the_model():
    rng = np.random.default_rng(11)
    v = rng.uniform(0.1, 1.5, (5, 6))
    m = CharacterisationMatrix(rng.normal(0, 30, (71, 3)), [f"c{i}" for i in range(6)], "root-polynomial-3", 3)
    h = 1e-7
    numeric = np.stack([(m.apply(v + h * np.eye(6)[c]) - m.apply(v - h * np.eye(6)[c])) / (2 * h) for c in range(6)],
                       axis=1)
    assert np.allclose(m.jacobian(v), numeric, rtol=1e-5, atol=1e-6)
    assert expansion_jacobian(v, 1).shape == (5, 6, 6)


def test_noise_gain_is_one_for_equal_weights_and_grows_with_cancelling_ones():
    assert np.allclose(noise_gain(np.full((6, 3), 100 / 6)), 1.0)
    J = np.tile(np.array([[250.0, -150.0, 250.0, -150.0, 250.0, -350.0]]).T, (1, 3))    # sum 100, norm ~ 580
    assert np.allclose(noise_gain(J), np.linalg.norm(J[:, 0]) * np.sqrt(6) / 100)
    rng = np.random.default_rng(1)
    assert (noise_gain(rng.uniform(0.1, 5, (6, 3))) >= 1.0 - 1e-12).all()      # Cauchy-Schwarz
    linear = fit_matrix(rng.uniform(0.1, 1, (30, 6)), rng.uniform(0, 1, (30, 3)))
    assert np.allclose(linear.noise_gain(), noise_gain(linear.matrix))


def test_condition_number_infinite_for_a_light_that_is_another_dimmed_and_scale_free():
    rng = np.random.default_rng(2)
    light1 = rng.uniform(0.05, 1.0, (40, 3))
    assert condition_number(np.hstack([light1, 0.5 * light1])) == float("inf")
    other = rng.uniform(0.05, 1.0, (40, 3))
    cond = condition_number(np.hstack([light1, other]))
    assert 1.0 < cond < 1e3
    assert np.isclose(condition_number(np.hstack([light1 * 7.0, other * 0.01])), cond)     # channel gains
    almost = np.hstack([light1, 0.5 * light1 + 1e-3 * other])
    w = weakest_direction(almost)
    assert condition_number(almost) > 1e3 and np.abs(w[:3]).sum() > 0.5 and np.abs(w[3:]).sum() > 0.5
