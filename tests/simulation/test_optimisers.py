"""The thesis PSO pinned by a hand computation (issue 12), and the default optimiser (successive halving over PSO
with the L-BFGS-B polish)."""
import numpy as np
import pytest

from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.halving import HalvingSettings, successive_halving
from dualrgb.simulation.objective import Evaluator
from dualrgb.simulation.pso import PsoSettings, pso
from dualrgb.simulation.runner import DEFAULT_METHOD, DEFAULT_OBJECTIVE, METHODS, OBJECTIVES, run
from dualrgb.simulation.search import light_pairs, refine_top


def rugged(w: np.ndarray, target: np.ndarray) -> np.ndarray:
    """A cost with many local minima, so that many particles do not improve and x_i,best != x matters."""
    return ((w - target) ** 2).sum(axis=(1, 2)) + 0.3 * np.sin(25 * w).sum(axis=(1, 2))


class Recorder:
    """A known cost (:func:`rugged`) that records every batch of levels the optimiser evaluates."""

    def __init__(self, target: np.ndarray) -> None:
        self.target = target
        self.batches: list[np.ndarray] = []
        self.evaluations = 0
        self.n_leds = 10

    def cost_indexed(self, idx, w):
        w = np.array(w, dtype=float)
        self.batches.append(w.copy())
        self.evaluations += len(w)
        return rugged(w, self.target)


def _constrain(x: np.ndarray) -> np.ndarray:
    """Eqs 6.2-6.4 written out: clip negatives, divide each light's levels by their maximum."""
    out = np.array(x, dtype=float)
    for p in range(out.shape[0]):
        for light in range(out.shape[1]):
            for i in range(out.shape[2]):
                out[p, light, i] = max(0.0, out[p, light, i])
            mx = max(out[p, light])
            if mx > 0:
                for i in range(out.shape[2]):
                    out[p, light, i] = out[p, light, i] / mx
    return out


def test_thesis_pso_defaults_are_algorithm_1():
    s = PsoSettings()
    assert (s.c0, s.c1, s.c2, s.iterations, s.particles) == (0.95, 2.0, 2.0, 10, 200)


def test_thesis_pso_update_steps_match_a_hand_computation():
    """Two iterations of Algorithm 1 with the thesis defaults (C0 0.95, C1 = C2 = 2, 200 particles), seed 11,
    recomputed by hand from the same random stream: v <- C0 v + C1 r1 (x_i,best - x) + C2 r2 (x_best - x),
    x <- x + v, constraints, cost, bests. The first step only sees C2 (v = 0, x_i,best = x); the second sees
    all three coefficients, so changing any of them fails this test."""
    group = ((1, 6, 7), (3, 5, 9))
    target = np.array([[0.3, 0.6, 1.0], [0.9, 0.2, 1.0]])
    rec = Recorder(target)
    seed = 11
    pso(rec, [group], PsoSettings(iterations=2), seed=seed)
    N = PsoSettings().particles
    C0, C1, C2 = 0.95, 2.0, 2.0
    rng = np.random.default_rng([seed, 0])                  # one generator per light set: (seed, set number)

    def cost(x):
        return rugged(x, target)

    x = _constrain(rng.random((N, 2, 3)))
    v = np.zeros_like(x)
    c = cost(x)
    pbest, pbest_c = x.copy(), c.copy()
    g = int(np.argmin(c))
    gbest, gbest_c = x[g].copy(), c[g]
    assert np.allclose(rec.batches[0], x, rtol=0, atol=1e-12)
    for step in (1, 2):
        r1 = rng.random((N, 2, 3))
        r2 = rng.random((N, 2, 3))
        for p in range(N):
            v[p] = C0 * v[p] + C1 * r1[p] * (pbest[p] - x[p]) + C2 * r2[p] * (gbest - x[p])
        x = _constrain(x + v)
        assert np.allclose(rec.batches[step], x, rtol=0, atol=1e-12), f"iteration {step}"
        c = cost(x)
        assert step == 2 or 20 < (c >= pbest_c).sum() < N - 20        # C1's term is exercised next step
        for p in range(N):
            if c[p] < pbest_c[p]:
                pbest_c[p], pbest[p] = c[p], x[p]
            if c[p] < gbest_c:
                gbest_c, gbest = c[p], x[p].copy()
    assert len(rec.batches) == 3 and rec.evaluations == 3 * N


def test_defaults_are_halving_on_the_expected_captured_error():
    assert DEFAULT_METHOD == "halving" and METHODS[0] == "halving"
    assert DEFAULT_OBJECTIVE == "expected-captured" and OBJECTIVES[0] == "expected-captured"
    assert {"pso", "ga", "exhaustive", "three-channel"} <= set(METHODS)


@pytest.fixture(scope="module")
def reflective():
    return Evaluator(default_setup("reflective"))


@pytest.mark.slow
def test_default_optimiser_reaches_the_best_known_optimum(reflective):
    """Issue 12: <= 0.400 mean training dE00 (reflective, noise-free objective) at ~7 % of the thesis PSO's
    evaluations (the time is `make bench`'s)."""
    for seed in (0, 1):
        out = refine_top(reflective, successive_halving(reflective, seed=seed), 1)
        assert out.best.train.mean <= 0.400
        assert [s.leds for s in out.best.sources] == [(1, 6, 7), (3, 5, 9)]
        assert out.evaluations < 0.1 * 630 * 200 * 11


def test_halving_polish_never_makes_a_set_worse(reflective):
    groups = light_pairs()[:12]
    plain = successive_halving(reflective, groups, HalvingSettings(particles=6, polish_sets=0, min_sets=2), seed=4)
    polished = successive_halving(reflective, groups, HalvingSettings(particles=6, polish_sets=2, min_sets=2,
                                                                      polish_iterations=5), seed=4)
    assert polished.best.train_cost <= plain.best.train_cost
    assert len(polished.settings["polished"]) == 2
    for step in polished.settings["polished"]:
        assert step["to"] <= step["from"] or not step["kept"]
    for s in polished.best.sources:
        assert max(s.levels) == pytest.approx(1.0) and min(s.levels) >= 0


def test_run_reports_both_figures_and_realised_levels():
    setup = default_setup("transmissive")
    res = run(setup, "exhaustive", top=2)
    assert res.objective == "expected-captured"
    best = res.outcome.best
    assert [s.leds for s in best.sources] == [(1, 6, 8), (3, 5, 9)]      # not the collinear (2,5,9)+(2,6,9)
    d = best.to_dict()
    assert d["expected_train_de00_mean"] >= d["train_de00_mean"] - 1e-3
    preset = res.preset()
    assert set(preset.errors) == {"train", "test", "expected_captured", "per_pixel"}
    # per pixel (the matrix on single pixels) well above the patch means, as a master shows it
    assert preset.errors["per_pixel"]["test"]["mean"] > 1.5 * preset.errors["expected_captured"]["test"]["mean"]
    assert d["per_pixel_test_de00_mean"] == preset.errors["per_pixel"]["test"]["mean"]
    nf = run(setup, "exhaustive", top=2, objective="noise-free")
    assert [s.leds for s in nf.outcome.best.sources] == [(2, 5, 9), (2, 6, 9)]
    assert nf.outcome.best.expected_train.mean > 3 * best.expected_train.mean
