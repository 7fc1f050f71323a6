import numpy as np
import pytest

from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.ga import ga
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.matrix_fit import CharacterisationError, fit_matrix
from dualrgb.simulation.objective import Evaluator, three_channel
from dualrgb.simulation.pso import PsoSettings, enforce_constraints, pso
from dualrgb.simulation.search import exhaustive, light_pairs, refine_top, triplets, unbinned_pairs


@pytest.fixture(scope="module")
def reflective():
    return Evaluator(default_setup("reflective"))


def test_bins_give_36_triplets_and_630_pairs():
    assert len(triplets()) == 36 and triplets()[0] == (1, 4, 7)
    assert len(light_pairs()) == 630
    assert len(light_pairs((5, 5))) == 300
    assert len(unbinned_pairs(4)) == 15 * 14 // 2


def test_exhaustive_reproduces_thesis_ranking(reflective):
    out = refine_top(reflective, exhaustive(reflective), 3)
    best = [c.sources for c in out.candidates[:2]]
    assert [s.leds for s in best[0]] == [(1, 6, 8), (3, 5, 9)]         # thesis Table 5.1 / 9.1
    assert [s.leds for s in best[1]] == [(2, 6, 8), (3, 5, 9)]         # thesis Table 9.1, second
    tr, _, _ = three_channel(reflective.setup)
    assert tr.mean() >= 1.8 * out.best.train.mean                      # dual-RGB beats 3-channel


def test_fast_objective_matches_float64_report(reflective):
    rng = np.random.default_rng(0)
    W = np.zeros((5, 2, 10))
    W[:, 0, [0, 5, 7]] = rng.random((5, 3))
    W[:, 1, [2, 4, 8]] = rng.random((5, 3))
    fast = reflective.cost(W)
    exact = [reflective.patch_errors(w)[0].mean() for w in W]
    assert np.allclose(fast, exact, atol=2e-4)


@pytest.mark.slow
def test_pso_beats_exhaustive_and_ga_agrees(reflective):
    ex = exhaustive(reflective)
    p = refine_top(reflective, pso(reflective, seed=0), 1)
    assert p.best.train.mean <= ex.best.train_cost + 1e-9
    assert p.evaluations == 630 * 200 * 11
    g = refine_top(reflective, ga(reflective, seed=0), 1)
    assert abs(g.best.train.mean - p.best.train.mean) <= 0.05
    # every optimised light is normalised to a maximum level of 1 (eqs 6.3-6.4)
    for s in p.best.sources:
        assert max(s.levels) == pytest.approx(1.0) and min(s.levels) >= 0


def test_pso_is_reproducible_and_chunking_free(reflective):
    groups = light_pairs()[:6]
    a = pso(reflective, groups, PsoSettings(iterations=3, particles=20), seed=7, chunk=2)
    b = pso(reflective, groups, PsoSettings(iterations=3, particles=20), seed=7, chunk=6)
    assert [c.train_cost for c in a.candidates] == pytest.approx([c.train_cost for c in b.candidates], abs=1e-6)
    c = pso(reflective, groups, PsoSettings(iterations=3, particles=20), seed=8, chunk=6)
    assert [x.train_cost for x in c.candidates] != [x.train_cost for x in b.candidates]


def test_transmissive_mode_runs_the_same_way():
    ev = Evaluator(default_setup("transmissive"))
    out = refine_top(ev, exhaustive(ev), 1)
    tr, te, _ = three_channel(ev.setup)
    assert len(ev.train) == 288 and len(ev.test) == 24
    assert out.best.train.mean < tr.mean() and out.best.test.mean < te.mean()
    p = refine_top(ev, pso(ev, light_pairs()[:20], PsoSettings(iterations=4, particles=40), seed=1), 1)
    assert np.isfinite(p.best.train.mean)


def test_constraints_clip_and_normalise():
    x = np.array([[[-0.5, 0.2, 0.4], [-1.0, -2.0, -0.1]]])
    mask = np.ones_like(x)
    enforce_constraints(x, mask)
    assert np.allclose(x[0, 0], [0.0, 0.5, 1.0])
    assert np.allclose(x[0, 1], 0.0)       # a fully clipped light stays off, no NaN


def test_clipped_led_and_dark_light_give_defined_results(reflective):
    W = np.zeros((3, 2, 10))
    W[0, 0, [0, 5, 7]] = [1, 0, 1]          # LED 6 clipped to 0: a zero column in nothing, one LED less
    W[0, 1, [2, 4, 8]] = 1
    W[1, 0, [0, 5, 7]] = 1                  # second light entirely off: three zero channels
    W[2, 0, [0, 5, 7]] = 1                  # the same LED (1) in both lights
    W[2, 1, [0, 4, 8]] = 1
    costs = reflective.cost(W)
    assert np.isfinite(costs).all()
    tr, te = reflective.patch_errors(W[1])
    assert np.isfinite(tr).all() and np.isfinite(te).all()
    # a dark second light is exactly the 3-channel fit under the first light
    A = reflective.characterise(W[1])
    assert np.allclose(A.matrix[3:], 0.0)


def test_rank_safe_fit_matches_lstsq_and_handles_zero_columns():
    rng = np.random.default_rng(0)
    C = rng.random((50, 6))
    B = C @ rng.random((6, 3)) + rng.normal(0, 1e-3, (50, 3))
    A = fit_matrix(C, B).matrix
    assert np.allclose(A, np.linalg.lstsq(C, B, rcond=None)[0], atol=1e-6)
    C[:, 4] = 0.0
    A = fit_matrix(C, B).matrix
    assert np.isfinite(A).all() and np.allclose(A[4], 0.0)
    ref = np.linalg.pinv(C) @ B
    assert np.allclose(A, ref, atol=1e-6)


def test_fewer_patches_than_channels_is_a_clear_error(reflective):
    with pytest.raises(CharacterisationError, match="needs at least 6"):
        fit_matrix(np.ones((4, 6)), np.ones((4, 3)))
    with pytest.raises(CharacterisationError, match="NaN"):
        fit_matrix(np.full((10, 3), np.nan), np.ones((10, 3)))


def test_light_source_validation():
    with pytest.raises(ValueError, match="outside 1..10"):
        LightSource((0, 2, 3))
    with pytest.raises(ValueError, match="listed twice"):
        LightSource((2, 2, 3))
    with pytest.raises(ValueError, match="outside 0..1"):
        LightSource((1, 2, 3), (1.0, 1.5, 0.0))
    s = LightSource((1, 6, 8), (0.1, 0.5, 1.0))
    assert s.weights()[[0, 5, 7]].tolist() == [0.1, 0.5, 1.0]
    assert LightSource.from_dict(s.to_dict()) == s


def test_batched_normal_equations_agree_with_the_kernel_and_lstsq(reflective):
    from dualrgb.simulation.matrix_fit import solve_normal_equations
    rng = np.random.default_rng(5)
    W = np.zeros((4, 2, 10))
    W[:, 0, [0, 5, 7]] = rng.random((4, 3)) + 0.2
    W[:, 1, [2, 4, 8]] = rng.random((4, 3)) + 0.2
    W[3, 1] = 0.0                                            # one light off: zero channels
    C = reflective.train.camera_values(W)                    # (4, n, 6)
    A = solve_normal_equations(C.transpose(0, 2, 1) @ C, C.transpose(0, 2, 1) @ reflective.train.xyz)
    idx = np.broadcast_to(np.arange(10), (4, 2, 10))
    _, A_kernel = reflective.fit_indexed(idx, W)
    for p in range(3):
        ref = np.linalg.lstsq(C[p], reflective.train.xyz, rcond=None)[0]
        assert np.allclose(A[p], ref, rtol=1e-5, atol=1e-6 * np.abs(ref).max())
    assert np.allclose(A, A_kernel, rtol=1e-6, atol=1e-9)
    assert np.allclose(A[3, 3:], 0.0) and np.isfinite(A).all()
