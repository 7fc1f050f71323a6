"""Least-squares vs mean-dE00-optimised characterisation on simulated dual-RGB patch values."""
from __future__ import annotations

import inspect

import numpy as np
import pytest

from dualrgb.app.processing.characterise import (
    DE2000,
    LEAST_SQUARES,
    ROOT_POLYNOMIAL_2,
    ROOT_POLYNOMIAL_3,
    characterise,
    fit_de2000,
    fit_least_squares,
    one_standard_error,
    patch_errors,
    select_model,
)
from dualrgb.common.progress import Cancelled, CancelToken
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.objective import PatchSet


@pytest.fixture(scope="module")
def data():
    setup = default_setup("reflective")
    train, test = PatchSet(setup, setup.train), PatchSet(setup, setup.test)
    W = np.stack([LightSource((1, 6, 8)).weights(), LightSource((3, 5, 9)).weights()])
    rng = np.random.default_rng(0)
    vt = train.camera_values(W) * (1 + 0.01 * rng.standard_normal((len(train), 6)))   # 1 % capture noise
    vs = test.camera_values(W) * (1 + 0.01 * rng.standard_normal((len(test), 6)))
    return vt, train.xyz, vs, test.xyz, train.white


def test_de2000_matrix_is_not_worse_than_least_squares_on_train(data):
    vt, xt, vs, xs, white = data
    ls = fit_least_squares(vt, xt)
    opt = fit_de2000(vt, xt, white, start=ls)
    e_ls = patch_errors(ls, vt, xt, white).mean()
    e_opt = patch_errors(opt, vt, xt, white).mean()
    assert e_opt <= e_ls
    assert e_opt < 0.99 * e_ls, "the optimiser should find a real improvement on the training set"
    assert opt.method == DE2000 and ls.method == LEAST_SQUARES


def test_characterise_reports_both_and_chooses_by_cross_validation_on_train(data):
    vt, xt, vs, xs, white = data
    seen = []
    c = characterise(vt, xt, white, vs, xs, ["R1", "G1", "B1", "R2", "G2", "B2"],
                     progress=lambda f, m: seen.append(f))
    assert set(c.results) == {LEAST_SQUARES, DE2000, ROOT_POLYNOMIAL_2, ROOT_POLYNOMIAL_3}
    r = c.results
    assert r[DE2000].train.mean <= r[LEAST_SQUARES].train.mean
    assert r[ROOT_POLYNOMIAL_3].train.mean < r[ROOT_POLYNOMIAL_2].train.mean < r[LEAST_SQUARES].train.mean
    sel = select_model(vt, xt, white, ["R1", "G1", "B1", "R2", "G2", "B2"])
    assert c.best == sel.chosen == one_standard_error(sel.cv_mean, sel.cv_se) and c.matrix is r[c.best].matrix
    # cross-validated errors are held-out errors: above each method's own training error
    assert all(sel.cv_mean[m] > r[m].train.mean for m in r)
    assert np.allclose(r[LEAST_SQUARES].test_errors, patch_errors(r[LEAST_SQUARES].matrix, vs, xs, white))
    assert 0 < r[LEAST_SQUARES].train.mean < 3 and seen and seen[-1] == 1.0
    d = c.to_dict()
    assert d["best"] == c.best and d["selection"]["folds"] == 5 and d["methods"][DE2000]["test"]["p90"] > 0


def test_model_selection_never_reads_the_test_target(data):
    """The delivered matrix is the same whatever the test target says: a test target on which the chosen
    method is far worse (and one on which it is far better) leaves the choice unchanged, and the reported test
    error is the chosen matrix's, however bad."""
    vt, xt, vs, xs, white = data
    honest = characterise(vt, xt, white, vs, xs)
    chosen = honest.best
    other = next(m for m in honest.results if m != chosen)
    # forge test 'measurements' that the other matrix reproduces exactly and the chosen one does not
    forged_xyz = honest.results[other].matrix.apply(vs)
    adversarial = characterise(vt, xt, white, vs, forged_xyz)
    assert adversarial.best == chosen
    assert adversarial.results[other].test.mean < 1e-6 < adversarial.results[chosen].test.mean
    forged_xyz = honest.results[chosen].matrix.apply(vs)                   # and the reverse
    assert characterise(vt, xt, white, vs, forged_xyz).best == chosen
    assert characterise(vt, xt, white).best == chosen                       # and with no test target at all
    assert "test" not in inspect.signature(select_model).parameters.keys().__str__()


def test_characterise_rejects_nan_patches_and_can_be_cancelled(data):
    vt, xt, vs, xs, white = data
    bad = vt.copy()
    bad[3, 2] = np.nan
    with pytest.raises(ValueError, match="training patches 4"):
        characterise(bad, xt, white)
    tok = CancelToken()
    tok.cancel()
    with pytest.raises(Cancelled):
        fit_de2000(vt, xt, white, cancel=tok)


def test_zero_channel_stays_zero(data):
    vt, xt, _, _, white = data
    v = vt.copy()
    v[:, 4] = 0.0                                     # an LED clipped to 0: one channel carries nothing
    opt = fit_de2000(v, xt, white)
    assert np.all(opt.matrix[4] == 0) and np.isfinite(opt.matrix).all()


def test_one_standard_error_rule_prefers_the_simpler_model_within_the_error():
    cv = {LEAST_SQUARES: 0.70, DE2000: 0.69, ROOT_POLYNOMIAL_2: 0.60, ROOT_POLYNOMIAL_3: 0.58}
    assert one_standard_error(cv, dict.fromkeys(cv, 0.01)) == ROOT_POLYNOMIAL_3
    assert one_standard_error(cv, dict.fromkeys(cv, 0.03)) == ROOT_POLYNOMIAL_2       # 0.60 <= 0.58 + 0.03
    assert one_standard_error(cv, dict.fromkeys(cv, 0.12)) == LEAST_SQUARES
    assert one_standard_error({DE2000: 0.5, LEAST_SQUARES: 0.9}, {DE2000: 0.1, LEAST_SQUARES: 0.1}) == DE2000


def test_root_polynomials_need_as_many_patches_per_fold_as_terms(data):
    """24 training patches keep 19 per fold: the 21-term degree-2 root-polynomial cannot be fitted, and the
    selection says so; the table lists the models fitted, with the chosen one marked."""
    vt, xt, vs, xs, white = data
    c = characterise(vt[:24], xt[:24], white, vs, xs, optimise=False)
    assert set(c.results) == {LEAST_SQUARES} and c.best == LEAST_SQUARES
    assert "a fold keeps 19" in c.selection.skipped[ROOT_POLYNOMIAL_2]
    rows = c.to_dict()["models"]
    assert [r["model"] for r in rows] == [LEAST_SQUARES] and rows[0]["chosen"] and rows[0]["terms"] == 6


def test_per_pixel_error_and_noise_gain_of_every_model(data):
    """Pixels of a patch scattered about its mean: the per-pixel dE00 exceeds the patch mean's, more where the
    scatter is larger, and a model's noise gain is reported beside it."""
    vt, xt, vs, xs, white = data
    rng = np.random.default_rng(5)
    figures = []
    for spread in (0.005, 0.03):
        pixels = {"test": [v * (1 + spread * rng.standard_normal((300, 6))) for v in vs]}
        c = characterise(vt, xt, white, vs, xs, optimise=False, pixels=pixels)
        d = c.to_dict()
        px = d["per_pixel_de00"]["test"]
        assert px["p90"] > px["mean"] > c.results[c.best].test.mean
        figures.append(px["mean"])
        assert all(r["per_pixel_de00_mean"] > r["test_de00"] for r in d["models"])
        assert d["noise_gain"]["Y"] >= 1.0 and 1.0 < d["condition_number"] < 1e3
    assert figures[1] > 2 * figures[0]
