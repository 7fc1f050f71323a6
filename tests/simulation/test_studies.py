"""The studies (simulation.studies, ``dualrgb study``) at tiny budgets: outputs, invariants, Dask == serial."""
import json
import logging
import os
from dataclasses import replace
from itertools import pairwise

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
import numpy as np
import pytest

from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.pso import PsoSettings, pso
from dualrgb.simulation.search import group_arrays, light_pairs, unbinned_pairs
from dualrgb.simulation.studies import optimisers as opt
from dualrgb.simulation.studies.common import SetupSpec, StudyOutput, TracedEvaluator, evaluator_for, pareto_front
from dualrgb.simulation.studies.distributed import SerialRunner, open_runner
from dualrgb.simulation.studies.models import MODELS, fit_model, model_errors, root_polynomial_terms
from dualrgb.simulation.studies.noise import CameraNoise, NoiseAwareEvaluator, NoiseModel
from dualrgb.simulation.studies.unbinned import pair_count, pair_group, unbinned_group_arrays, unbinned_search

SPEC = SetupSpec()


@pytest.fixture(scope="module")
def ev():
    return evaluator_for(SPEC)


@pytest.fixture(scope="module")
def model():
    return NoiseModel(default_setup("reflective"))


@pytest.fixture(scope="module")
def dask_runner():
    """One LocalCluster (2 worker processes) for the Dask tests of this module (starting one takes seconds)."""
    with open_runner("local", workers=2) as runner:
        yield runner


def _W(l1, v1, l2, v2):
    W = np.zeros((2, 10))
    W[0, np.asarray(l1) - 1] = v1
    W[1, np.asarray(l2) - 1] = v2
    return W


# ---- unbinned space ------------------------------------------------------------------------------------
def test_vectorised_unbinned_arrays_match_core():
    for n in (3, 4, 5):
        a, b = group_arrays(unbinned_pairs(n)), unbinned_group_arrays(n)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    pairs = unbinned_pairs(10)
    assert len(pairs) == pair_count(10) == 522753
    a, b = group_arrays(pairs[400000:401000]), unbinned_group_arrays(10, 400000, 401000)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert pair_group(10, 123456) == pairs[123456]


def test_unbinned_search_chunking_free_and_dask_equals_serial(dask_runner):
    one = unbinned_search(SPEC, SerialRunner(), tasks=1, limit=3000, top=8, refine=2)
    many = unbinned_search(SPEC, SerialRunner(), tasks=5, limit=3000, top=8, refine=2)
    assert one.numbers == many.numbers and one.costs == many.costs and one.histogram == many.histogram
    assert sum(one.histogram) == 3000 and list(one.costs) == sorted(one.costs)
    dask = unbinned_search(SPEC, dask_runner, tasks=4, limit=3000, top=8, refine=2)
    assert dask.runner["runner"] == "dask"
    assert dask.numbers == one.numbers and dask.costs == one.costs and dask.histogram == one.histogram
    assert dask.candidates[0].train.mean == pytest.approx(one.candidates[0].train.mean)


# ---- optimisers ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name,settings", [
    ("pyswarms", opt.PyswarmsSettings(particles=8, iterations=3)),
    ("de", opt.DeSettings(popsize=3, maxiter=3)),
    ("lbfgs", opt.LbfgsSettings(screen=6, top_sets=2, starts=1, maxiter=4)),
    ("halving", opt.HalvingSettings(particles=6, iterations=1, min_sets=2)),
])
def test_study_optimisers_return_normalised_consistent_candidates(ev, name, settings):
    groups = light_pairs()[:5]
    traced = TracedEvaluator(ev)
    out = opt.OPTIMISERS[name](traced, groups, settings, seed=3)
    assert len(out.candidates) == 5 and out.evaluations > 0
    costs = [c.train_cost for c in out.candidates]
    assert costs == sorted(costs)
    best = out.best
    for s in best.sources:
        assert max(s.levels) == pytest.approx(1.0) and min(s.levels) >= 0
    # the reported cost is the cost of the reported (normalised) levels: scaling a light changes nothing
    assert ev.cost(best.weights(10)[None])[0] == pytest.approx(best.train_cost, abs=2e-4)
    tr = traced.trace
    assert tr.best == sorted(tr.best, reverse=True) and tr.evaluations[-1] == out.evaluations
    assert tr.best[-1] == pytest.approx(best.train_cost, abs=2e-4)


def test_pyswarms_leaves_logging_and_cwd_alone(ev, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    state = np.random.get_state()[1].copy()  # noqa: NPY002 - the global RNG pyswarms must leave as it was
    opt.pyswarms_search(ev, light_pairs()[:2], opt.PyswarmsSettings(particles=5, iterations=2))
    assert root.handlers == handlers and root.level == level
    assert not (tmp_path / "report.log").exists() and "LOG_CFG" not in os.environ
    assert np.array_equal(np.random.get_state()[1], state)  # noqa: NPY002 - as above


def test_pareto_front_is_monotone():
    pts = [(1.0, 0.5), (0.5, 0.9), (2.0, 0.4), (3.0, 0.45), (0.1, 1.0), (2.5, 0.4)]
    front = pareto_front(pts)
    assert front == [4, 1, 0, 2]
    xs, ys = zip(*(pts[i] for i in front), strict=True)
    assert list(xs) == sorted(xs) and all(b < a for a, b in pairwise(ys))


# ---- speed vs accuracy -----------------------------------------------------------------------------------
def test_speed_accuracy_tiny_writes_outputs(tmp_path):
    from dualrgb.simulation.studies.speed_accuracy import configs, speed_accuracy, write_outputs

    res = speed_accuracy(SPEC, seeds=2, budget="tiny", light_sets=6)
    out = StudyOutput(tmp_path / "sa")
    write_outputs(res, out)
    for f in ("speed_accuracy.json", "pareto.png", "convergence.png", "SUMMARY.md"):
        assert (tmp_path / "sa" / f).stat().st_size > 0
    data = json.loads((tmp_path / "sa" / "speed_accuracy.json").read_text())
    assert {"setup", "budget", "seeds", "configurations", "pareto_train", "pareto_test", "runs"} <= set(data)
    labels = [c.label for c in configs("tiny")]
    assert [c["label"] for c in data["configurations"]] == labels
    assert len(data["runs"]) == 2 * len(labels)
    methods = {c["method"] for c in data["configurations"]}
    assert methods == {"exhaustive", "pso", "ga", "halving", "pyswarms", "de", "lbfgs"}
    rows = {c["label"]: c for c in data["configurations"]}
    for key in ("pareto_train", "pareto_test"):
        pts = [(rows[label]["cpu_seconds"]["median"], rows[label][key.split("_")[1]]["median"])
               for label in data[key]]
        assert all(a[0] <= b[0] and b[1] < a[1] for a, b in pairwise(pts))
    for r in data["runs"]:
        assert r["evaluations"] > 0 and r["train"] > 0 and r["test"] > 0 and r["cpu_seconds"] > 0
        assert r["trace"]["best"] == sorted(r["trace"]["best"], reverse=True)
        # what the light set is worth captured: patch means, and per pixel well above them
        assert r["expected_train"] > 0.9 * r["train"] and r["per_pixel_train"] > r["expected_train"]
        assert r["per_pixel_test_p90"] > r["per_pixel_test"] and len(r["load"]) == 2
        lowest = r["min_stable_level"]
        assert r["below_min_level"] == [[k, v] for src, lv in zip((r["best"]["source1"], r["best"]["source2"]),
                                                                 r["best"]["levels_exact"].values(), strict=True)
                                        for k, v in zip(src, lv, strict=True) if 0 < v < lowest]
    with pytest.raises(ValueError):
        configs("huge")


def test_a_level_below_the_spheres_minimum_is_marked_and_scored_as_the_sphere_holds_it():
    """The noise-free optimum's LED 1 at a trace level: the sphere holds 0 there, so the expected captured and
    per-pixel figures are those of the light without it, and the run says which level was below the minimum."""
    from dualrgb.simulation.studies.speed_accuracy import captured_figures

    trace = captured_figures(SPEC, [[0.0017, 1.0, 1.0], [1.0, 1.0, 1.0]], [[1, 6, 8], [3, 5, 9]])
    without = captured_figures(SPEC, [[0.0, 1.0, 1.0], [1.0, 1.0, 1.0]], [[1, 6, 8], [3, 5, 9]])
    assert trace["below_min_level"] == [[1, 0.0017]] and without["below_min_level"] == []
    assert trace["min_stable_level"] == 0.01
    for key in ("expected_train", "per_pixel_train", "per_pixel_test"):
        assert trace[key] == pytest.approx(without[key], rel=1e-9)


def test_speed_accuracy_dask_equals_serial(dask_runner):
    from dualrgb.simulation.studies.speed_accuracy import speed_accuracy

    serial = speed_accuracy(SPEC, seeds=1, budget="tiny", light_sets=4)
    dask = speed_accuracy(SPEC, seeds=1, budget="tiny", light_sets=4, runner=dask_runner)
    assert dask.runner["runner"] == "dask" and len(dask.runs) == len(serial.runs)
    for a, b in zip(serial.runs, dask.runs, strict=True):
        assert (a["label"], a["seed"], a["evaluations"]) == (b["label"], b["seed"], b["evaluations"])
        assert a["train"] == pytest.approx(b["train"], abs=1e-9) and a["test"] == pytest.approx(b["test"], abs=1e-9)
        assert a["best"]["levels_exact"] == b["best"]["levels_exact"]


def test_sweep_over_setups_through_dask(dask_runner, tmp_path):
    from dualrgb.simulation.studies.sweep import sweep, write_outputs

    specs = [SetupSpec("reflective"), SetupSpec("transmissive")]
    res = sweep(specs, ("exhaustive", "pso"), budget="tiny", seeds=2, light_sets=4, runner=dask_runner)
    serial = sweep(specs, ("exhaustive", "pso"), budget="tiny", seeds=2, light_sets=4)
    assert len(res.runs) == 2 * 2 * 2 and len(res.table) == 4
    assert [r["train"] for r in res.runs] == pytest.approx([r["train"] for r in serial.runs], abs=1e-9)
    write_outputs(res, StudyOutput(tmp_path))
    assert (tmp_path / "sweep.png").exists() and json.loads((tmp_path / "sweep.json").read_text())["table"]
    with pytest.raises(ValueError):
        sweep(specs, ("nelder-mead",), budget="tiny")


# ---- noise model and noise-aware objective ---------------------------------------------------------------
def test_noise_free_path_matches_the_evaluator(ev, model):
    W = _W((1, 6, 8), (0.3, 1.0, 0.7), (3, 5, 9), 1.0)
    clean = model.expected_errors(W[None], draws=0, exact=True)
    tr, te = ev.stats(W)
    assert clean["train"][0] == pytest.approx(tr.mean, abs=1e-6)
    assert clean["test"][0] == pytest.approx(te.mean, abs=1e-6)


def test_noise_aware_objective_is_at_least_the_noise_free_cost(ev, model):
    rng = np.random.default_rng(1)
    W = np.zeros((6, 2, 10))
    W[:, 0, [0, 5, 6]] = rng.random((6, 3))
    W[:, 1, [2, 4, 8]] = rng.random((6, 3))
    noisy = model.expected_errors(W, draws=8, test=False)["train"]
    clean = ev.cost(W)
    assert np.all(noisy >= clean - 1e-3)
    assert np.mean(noisy - clean) > 0.005
    # more pixels per patch -> less noise -> closer to the noise-free cost
    big = NoiseModel(model.setup, CameraNoise(pixels_per_patch=10**6))
    assert np.allclose(big.expected_errors(W, draws=8, test=False)["train"], clean, atol=3e-3)
    # common random numbers: the objective is deterministic
    assert np.array_equal(noisy, model.expected_errors(W, draws=8, test=False)["train"])


def test_exposures_follow_the_calibration(model):
    cam = model.camera
    ref = _W((1, 6, 8), 1.0, (3, 5, 9), 1.0)
    t = model.exposures(ref)
    assert t[0] == pytest.approx(cam.reference_exposure_s * cam.headroom / (cam.reference_dn - cam.black_level))
    dim = _W((6, 7), 1.0, (2,), 1.0)                     # LEDs 6 and 7 alone need far longer exposures
    assert model.exposures(dim)[0] > 10 * t[0]
    assert np.isinf(model.exposures(np.zeros((1, 10))))[0]


def test_noise_aware_pso_and_simulated_capture(ev, model):
    na = NoiseAwareEvaluator(model, draws=2)
    out = pso(na, light_pairs()[:2], PsoSettings(particles=5, iterations=2), seed=0)
    assert na.evaluations == 2 * 5 * 3 and np.isfinite(out.best.train_cost)
    W = _W((1, 6, 8), 1.0, (3, 5, 9), 1.0)
    cap = model.captured_errors(W, repeats=2)
    expected = model.expected_errors(W[None], draws=16)
    assert cap["train"] == pytest.approx(expected["train"][0], abs=0.05)
    assert cap["train"] >= ev.cost(W[None])[0] - 0.01
    values = model.simulate_capture(W, np.random.default_rng(0))
    v, _ = model.values(W[None])
    assert values.shape == v[0].shape and np.allclose(values, v[0], atol=0.05)


# ---- characterisation models -------------------------------------------------------------------------
def test_characterisation_models(ev):
    W = _W((1, 6, 8), 1.0, (3, 5, 9), 1.0)
    tr = ev.train.camera_values(W)
    terms = root_polynomial_terms(tr)
    assert terms.shape == (len(tr), 21)
    assert np.allclose(root_polynomial_terms(3.0 * tr), 3.0 * terms)        # exposure-invariant
    errs = {m: model_errors(fit_model(m, tr, ev.train.xyz, ev.train.white), tr, ev.train.xyz,
                            ev.train.white).mean() for m in MODELS}
    assert errs["de-optimised"] <= errs["linear"] + 1e-9
    assert errs["linear"] == pytest.approx(ev.stats(W)[0].mean, abs=1e-6)
    with pytest.raises(ValueError):
        fit_model("cubic", tr, ev.train.xyz, ev.train.white)


# ---- stability and parsimony at tiny budgets ---------------------------------------------------------
def test_stability_tiny_writes_outputs(tmp_path):
    from dualrgb.simulation.studies.stability import StabilityConfig, stability, write_outputs

    res = stability(SPEC, StabilityConfig.tiny())
    write_outputs(res, StudyOutput(tmp_path))
    for f in ("stability.json", "stability.png", "predicted_vs_captured.png", "SUMMARY.md"):
        assert (tmp_path / f).stat().st_size > 0
    data = json.loads((tmp_path / "stability.json").read_text())
    assert {"seeds", "led_clipping", "dim_leds", "sensitivity", "predicted_vs_captured"} <= set(data)
    assert len(data["led_clipping"]["rows"]) == 11
    for r in data["led_clipping"]["rows"]:
        assert r["reoptimised_train"] <= r["optimum_clipped_train"] + 1e-9
    rows = data["predicted_vs_captured"]["rows"]
    assert {r["mode"] for r in rows} == {"reflective", "transmissive"}
    assert {r["objective"] for r in rows} == {"noise-free", "expected-captured"}
    for r in rows:
        assert r["expected_train"] >= r["noise_free_train"] - 1e-3 and r["captured_train"] > 0
    assert {"noise", "drift", "target_error"} <= set(next(iter(data["sensitivity"].values())))


def test_objectives_study_worked_example(tmp_path):
    """The transmissive noise-free exhaustive pick is the collinear (2,5,9)+(2,6,9); it is captured far worse than
    predicted noise-free, the expected-captured objective predicts it and picks another pair."""
    from dualrgb.simulation.studies.objectives import ObjectivesConfig, objectives_study, write_outputs

    cfg = replace(ObjectivesConfig.tiny(), modes=("transmissive",), methods=("exhaustive",))
    res = objectives_study(SPEC, cfg)
    write_outputs(res, StudyOutput(tmp_path))
    for f in ("objectives.json", "objectives.png", "predicted_vs_captured.png", "SUMMARY.md"):
        assert (tmp_path / f).stat().st_size > 0
    by = {r["objective"]: r for r in res.rows}
    nf, ec = by["noise-free"], by["expected-captured"]
    assert nf["pair"] == [[2, 5, 9], [2, 6, 9]]
    assert nf["captured_train"] > 2.5 * nf["noise_free_train"]
    assert abs(nf["expected_train"] - nf["captured_train"]) < 0.1 * nf["captured_train"]
    assert ec["pair"] != nf["pair"] and ec["captured_train"] < 0.8 * nf["captured_train"]
    assert by["robust"]["robust_train"] <= nf["robust_train"]


def test_parsimony_tiny_picks_valid_options_per_mode_on_training_data(tmp_path):
    from dualrgb.simulation.defaults import FORMAT, load_defaults
    from dualrgb.simulation.studies.parsimony import ParsimonyConfig, parsimony
    from dualrgb.simulation.studies.parsimony_report import write_outputs

    cfg = ParsimonyConfig.tiny()
    results = [parsimony(replace(SPEC, mode=m), cfg) for m in ("reflective", "transmissive")]
    defaults_file = tmp_path / "defaults.json"
    write_outputs(results, StudyOutput(tmp_path / "p"), str(defaults_file))
    for f in ("parsimony_study.json", "parsimony.json", "parsimony.png", "SUMMARY.md"):
        assert (tmp_path / "p" / f).stat().st_size > 0
    d = json.loads(defaults_file.read_text())
    assert d["format"] == FORMAT and set(d["modes"]) == {"reflective", "transmissive"}
    for res in results:
        entry = d["modes"][res.mode]
        assert (entry["spectral_start_nm"], entry["spectral_step_nm"]) in cfg.grids
        assert entry["characterisation_model"] in MODELS
        assert entry["hdr_exposures"] in cfg.exposures
        # every choice is made on training data: the model and bracket by cross-validation on the captured
        # training target, within the tolerance of the best option; the test figures are only reported
        m, e = res.models, res.exposures
        assert m["chosen"] in m["candidates"] == ["linear", "de-optimised"]       # what the processing delivers
        assert m["scores"][m["chosen"]] <= min(m["scores"][k] for k in m["candidates"]) + cfg.tolerance
        assert "cross-validation" in m["criterion"] and "cross-validation" in e["criterion"]
        cv = {k: max(r["captured"][k]["cv"] for r in m["results"].values()) for k in MODELS}
        assert m["scores"] == cv
        assert e["scores"][[r["exposures"] for r in e["rows"]].index(e["chosen"])] <= e["best"] + cfg.tolerance
        rows = res.steps["rows"]
        assert all(r["noise_free_us_per_evaluation"] > 0 and r["optimiser_s"] > 0 for r in rows)   # cost shown
        assert load_defaults(res.mode, defaults_file)["hdr_exposures"] == entry["hdr_exposures"]
    assert load_defaults("transmissive", tmp_path / "missing.json")["spectral_step_nm"] == 10.0


def test_captured_errors_cross_validation_never_sees_the_test_target(model):
    """The CV figure is computed from the training capture alone: changing the test target leaves it unchanged,
    and it is at least the in-sample training error (a held-out patch is predicted by a fit without it)."""
    W = np.zeros((2, 10))
    W[0, [0, 5, 7]] = 1.0
    W[1, [2, 4, 8]] = 1.0
    a = model.captured_errors(W, 2, folds=5)
    other = NoiseModel(model.setup, model.camera, test=replace(model.setup.test,
                                                               spectra=model.setup.test.spectra * 0.5))
    b = other.captured_errors(W, 2, folds=5)
    assert a["train_cv"] == pytest.approx(b["train_cv"], rel=1e-12) and a["test"] != pytest.approx(b["test"])
    assert a["train_cv"] > a["train"]


def test_packaged_parsimony_defaults_load_per_mode():
    from dualrgb.simulation.defaults import FORMAT, default_grid, load_defaults
    from dualrgb.simulation.hdr_estimators import HDR_MERGE_METHODS

    data = json.loads(__import__("resources").path("parsimony.json").read_text())
    assert data["format"] == FORMAT
    for mode in ("reflective", "transmissive"):
        d = load_defaults(mode)
        assert d["spectral_step_nm"] in (1.0, 5.0, 10.0, 20.0) and d["characterisation_model"] in MODELS
        assert d["hdr_merge"] in HDR_MERGE_METHODS
        assert "cross-validation" in data["modes"][mode]["criteria"]["characterisation_model"]
        assert "cross-validation" in data["modes"][mode]["criteria"]["hdr_merge"]
        assert len(default_grid(mode)) > 10


def test_hdr_study_tiny_chooses_an_estimator_per_mode_and_keeps_other_defaults(tmp_path):
    from dualrgb.simulation.defaults import FORMAT_V1, load_defaults
    from dualrgb.simulation.hdr_estimators import HDR_MERGE_METHODS
    from dualrgb.simulation.studies.hdr import HdrStudyConfig, hdr_study, write_defaults, write_outputs

    cfg = HdrStudyConfig.tiny()
    res = hdr_study([replace(SPEC, mode=m) for m in ("reflective", "transmissive")], cfg)
    write_outputs(res, StudyOutput(tmp_path / "h"))
    for f in ("hdr_study.json", "hdr.png", "SUMMARY.md"):
        assert (tmp_path / "h" / f).stat().st_size > 0
    for mode in ("reflective", "transmissive"):
        assert res.chosen(mode) in HDR_MERGE_METHODS
        assert set(res.originals[mode]["scores"]) == set(HDR_MERGE_METHODS)
    b = res.bias
    thesis, variance = b["thesis"]["bias_per_decade"], b["variance"]["bias_per_decade"]
    assert thesis["10-100"]["mean"] > 0.2 + 3 * thesis["10-100"]["se"]      # eq 8.9: far too bright in the shadows
    assert abs(variance["100-1000"]["mean"]) < 0.01
    # the standard error is the Monte Carlo's: sd / sqrt(pixels) at each level (hand computation at one level)
    i = int(np.argmin(np.abs(np.asarray(b["levels_dn_s"]) - 100.0)))
    L = b["levels_dn_s"][i]
    assert b["variance"]["relative_bias_se"][i] == pytest.approx(b["variance"]["relative_noise"][i]
                                                                  / np.sqrt(cfg.pixels), rel=1e-9)
    assert 0.01 < b["variance"]["relative_noise"][i] * L / np.sqrt(L / 8.0 + 2.5 ** 2) < 1.5
    defaults = tmp_path / "defaults.json"          # an old single-mode file: its keys are kept for every mode
    defaults.write_text(json.dumps({"format": FORMAT_V1, "spectral_step_nm": 5.0, "evidence": {"x": 1}}))
    assert load_defaults("transmissive", defaults)["spectral_step_nm"] == 5.0
    write_defaults(res, str(defaults))
    d = json.loads(defaults.read_text())
    for mode in ("reflective", "transmissive"):
        entry = d["modes"][mode]
        assert entry["spectral_step_nm"] == 5.0 and entry["evidence"]["x"] == 1
        assert entry["hdr_merge"] == res.chosen(mode) == load_defaults(mode, defaults)["hdr_merge"]


# ---- CLI ---------------------------------------------------------------------------------------------
def test_cli_unbinned_serial_and_errors(tmp_path, capsys):
    from dualrgb.app.cli import main

    out = tmp_path / "u"
    assert main(["study", "unbinned", "--scheduler", "serial", "--limit", "500", "--tasks", "2", "--top", "3",
                 "--out", str(out)]) == 0
    data = json.loads((out / "unbinned.json").read_text())
    assert data["pairs"] == 500 and len(data["top"]) == 3 and data["binned_best"]["source1"] == [1, 6, 8]
    assert (out / "unbinned.png").exists() and (out / "SUMMARY.md").exists()
    with pytest.raises(SystemExit) as info:       # refused while parsing (app.commands.options.input_file)
        main(["study", "unbinned", "--scheduler", "serial", "--camera-csv", str(tmp_path / "nope.csv"),
              "--out", str(out)])
    assert info.value.code == 2 and "nope.csv': no such file" in capsys.readouterr().err
