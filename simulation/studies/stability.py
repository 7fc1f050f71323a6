"""How stable and how robust are the optima? (``dualrgb study stability``)

1. Seed spread: every optimiser with several seeds; which light set each seed picks, the spread of the
   levels among the seeds that agree on the most common set, and of the errors.
2. LED clipping: each LED removed in turn (its spectrum set to 0; also LEDs 6+7 together): the full-intensity
   ranking (where the original best set falls), the PSO optimum with that LED at 0 (not re-optimised) and a
   re-optimised PSO: how far the best error moves.
3. Dim LEDs 6 and 7 (relative peaks 0.014 and 0.003): the exposure each optimum light needs and the share of
   its open-gate signal from LEDs 6 and 7; thesis Table 7.1's exposures beside the model's.
4. Sensitivity of each optimum (fit re-done on the perturbed capture, as the lab would) to camera noise at
   those exposures (:mod:`.noise`), to LED peak drift (1 nm spectra shifted, setup rebuilt) and to target
   measurement error (camera sees perturbed reflectances, ground truth from the measured ones).
5. Predicted against captured, both modes, both objectives (:mod:`.objectives`): the exhaustive and the default
   optimiser's optima under the noise-free and the expected-captured objective, each captured (the virtual lab
   through app.processing when available, else the pixel-level capture simulation); the transmissive
   (2, 5, 9) + (2, 6, 9) pair is the worked example of a method that fails (and what fixes it).

Outputs: ``stability.json``, ``stability.png`` (four panels), ``predicted_vs_captured.png`` and ``SUMMARY.md``.
"""
from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from dualrgb import resources
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.camera_model import led_responses
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.colorimetry import delta_e_2000, tristimulus, white_point, xyz_to_lab
from dualrgb.simulation.datasets import SimulationSetup, Target
from dualrgb.simulation.ga import GaSettings
from dualrgb.simulation.matrix_fit import fit_matrix
from dualrgb.simulation.objective import Evaluator
from dualrgb.simulation.pso import PsoSettings, pso
from dualrgb.simulation.search import exhaustive, light_pairs, refine_top
from dualrgb.simulation.spectral_io import read_spectral_csv
from dualrgb.simulation.studies.common import SetupSpec, StudyOutput, evaluator_for, median_spread
from dualrgb.simulation.studies.distributed import Runner, SerialRunner
from dualrgb.simulation.studies.noise import CameraNoise, NoiseModel, thesis_exposures_check
from dualrgb.simulation.studies.objectives import (
    ObjectivesConfig,
    ObjectivesResult,
    objectives_study,
    predicted_vs_captured_chart,
    study_capture_model,
    summary_lines,
)
from dualrgb.simulation.studies.optimisers import DeSettings, HalvingSettings, LbfgsSettings, PyswarmsSettings
from dualrgb.simulation.studies.speed_accuracy import Config, RunTask, run_task

log = logging.getLogger(__name__)

Capture = Callable[[SimulationSetup, np.ndarray, np.ndarray], dict]


@dataclass(frozen=True)
class StabilityConfig:
    seeds: int = 3
    light_sets: int | None = None                    # None: all 630
    methods: tuple[Config, ...] = (
        Config("pso", "pso 200x10 (thesis)", PsoSettings()),
        Config("ga", "ga (thesis budget)", GaSettings()),
        Config("halving", "halving", HalvingSettings()),
        Config("pyswarms", "pyswarms 50x10", PyswarmsSettings(particles=50, iterations=10)),
        Config("de", "de pop5x6", DeSettings(popsize=5, maxiter=6)),
        Config("lbfgs", "lbfgs top12x2", LbfgsSettings(top_sets=12, starts=2)),
    )
    clip_pso: PsoSettings = PsoSettings(particles=100, iterations=10)
    camera: CameraNoise = CameraNoise()
    check_draws: int = 32                               # Monte-Carlo draws of the noise sensitivity
    objectives: ObjectivesConfig = ObjectivesConfig(objectives=("noise-free", "expected-captured"),
                                                    methods=("exhaustive", "halving"))
    drift_nm: tuple[float, ...] = (-5.0, -2.0, 2.0, 5.0)
    drift_random: int = 6
    drift_sigma_nm: float = 2.0
    target_draws: int = 6
    target_gain_sigma: float = 0.01
    target_spectral_sigma: float = 0.01
    lab_repeats: int = 2                                # virtual-lab captures per candidate (when available)

    @classmethod
    def tiny(cls) -> StabilityConfig:
        return cls(seeds=2, light_sets=10,
                   methods=(Config("pso", "pso 10x2", PsoSettings(particles=10, iterations=2)),
                            Config("ga", "ga tiny", GaSettings(mu=6, lam=20, generations=2)),
                            Config("halving", "halving tiny", HalvingSettings(particles=8, iterations=1,
                                                                               min_sets=2))),
                   clip_pso=PsoSettings(particles=8, iterations=2), check_draws=2,
                   objectives=replace(ObjectivesConfig.tiny(), objectives=("noise-free", "expected-captured"),
                                      methods=("exhaustive", "halving")),
                   drift_nm=(2.0,), drift_random=1, target_draws=1, lab_repeats=1)


# ---------------------------------------------------------------------------------------------------------
def _weights(best: dict, n_leds: int = 10) -> np.ndarray:
    """Dense (L, K) levels from a Candidate.to_dict() (full precision is kept in 'levels_exact')."""
    W = np.zeros((2, n_leds))
    for li in range(2):
        leds = best[f"source{li + 1}"]
        levels = best.get("levels_exact", {}).get(str(li + 1)) or best[f"intensities{li + 1}"]
        W[li, np.asarray(leds) - 1] = levels
    return W


def _pair_key(best: dict) -> str:
    return f"{tuple(best['source1'])}+{tuple(best['source2'])}"


def seed_spread(spec: SetupSpec, cfg: StabilityConfig, runner: Runner | None = None, progress=None,
                cancel=None) -> dict:
    tasks = [RunTask(spec, c, s, cfg.light_sets) for c in cfg.methods for s in range(cfg.seeds)]
    if runner is None or isinstance(runner, SerialRunner):
        results = []
        for i, t in enumerate(tasks):
            check(cancel)
            results.append(run_task(t))
            report(progress, 0.4 * (i + 1) / len(tasks), f"stability: {t.config.label}, seed {t.seed}")
    else:
        results = runner.map(run_task, tasks)
    out = {}
    for c in cfg.methods:
        runs = [r for r in results if r["label"] == c.label]
        pairs = Counter(_pair_key(r["best"]) for r in runs)
        top_pair, top_n = pairs.most_common(1)[0]
        same = [r for r in runs if _pair_key(r["best"]) == top_pair]
        lv = np.array([r["best"]["intensities1"] + r["best"]["intensities2"] for r in same])
        out[c.label] = {
            "method": c.method, "seeds": [r["seed"] for r in runs],
            "pairs": [_pair_key(r["best"]) for r in runs],
            "levels": [r["best"]["intensities1"] + r["best"]["intensities2"] for r in runs],
            "train": [r["train"] for r in runs], "test": [r["test"] for r in runs],
            "seconds": [r["seconds"] for r in runs],
            "distinct_pairs": len(pairs), "most_common_pair": top_pair, "most_common_count": top_n,
            "level_sd_within_common_pair": lv.std(axis=0).round(4).tolist() if len(lv) > 1 else None,
            "train_spread": median_spread([r["train"] for r in runs]),
            "best_seed": min(runs, key=lambda r: r["train"])["best"],
        }
    return out


def _without(setup: SimulationSetup, leds: tuple[int, ...]) -> SimulationSetup:
    L = setup.leds.copy()
    L[np.asarray(leds) - 1] = 0.0
    return replace(setup, leds=L)


def led_clipping(spec: SetupSpec, cfg: StabilityConfig, optimum: np.ndarray, cancel=None) -> dict:
    """Remove each LED in turn (and 6+7 together): ranks and errors before and after re-optimisation."""
    base_setup = spec.build()
    base = Evaluator(base_setup)
    groups = light_pairs()[:cfg.light_sets] if cfg.light_sets else light_pairs()
    ex0 = refine_top(base, exhaustive(base, groups), 1)
    best_pair = tuple(s.leds for s in ex0.best.sources)
    opt_train = float(base.stats(optimum)[0].mean)
    rows = []
    for leds in [(k,) for k in range(1, base.n_leds + 1)] + [(6, 7)]:
        check(cancel)
        ev = Evaluator(_without(base_setup, leds))
        ex = exhaustive(ev, groups)
        ranks = [i for i, c in enumerate(ex.candidates) if tuple(s.leds for s in c.sources) == best_pair]
        W = optimum.copy()
        W[:, np.asarray(leds) - 1] = 0.0
        clipped = float(ev.stats(W)[0].mean)
        re = refine_top(ev, pso(ev, groups, cfg.clip_pso, seed=0), 1)
        # the clipped optimum is itself a candidate without the LED: the re-optimised best is the better one
        reopt = min(re.best.train_errors.mean, clipped)
        re_pair = [list(s.leds) for s in re.best.sources] if re.best.train_errors.mean <= clipped else \
            [list(np.nonzero(w)[0] + 1) for w in W]
        rows.append({"removed": list(leds), "full_intensity_best": ex.best.train_cost,
                     "full_intensity_best_pair": [list(s.leds) for s in ex.best.sources],
                     "rank_of_original_best_pair": (ranks[0] + 1) if ranks else None,
                     "optimum_clipped_train": clipped, "optimum_clipped_delta": clipped - opt_train,
                     "reoptimised_train": reopt, "reoptimised_pair": re_pair,
                     "reoptimised_delta": reopt - opt_train})
    return {"original_full_intensity_best": ex0.best.to_dict(), "original_optimum_train": opt_train,
            "rows": rows}


def dim_leds(model: NoiseModel, optima: dict[str, np.ndarray]) -> dict:
    """Exposures each optimum light needs and the share of LEDs 6 and 7 in its open-gate brightest channel."""
    rows = []
    for name, W in optima.items():
        t = model.exposures(W)
        for li in range(W.shape[0]):
            gate = W[li] @ model.open
            c = int(np.argmax(gate))
            share = float((W[li, 5:7] * model.open[5:7, c]).sum() / gate[c]) if gate[c] > 0 else None
            rows.append({"optimum": name, "light": li + 1, "leds": (np.nonzero(W[li])[0] + 1).tolist(),
                         "levels": W[li][W[li] > 0].round(4).tolist(), "exposure_s": float(t[li]),
                         "brightest_channel": "RGB"[c], "share_led6_7": share})
    return {"lights": rows, "thesis_table_7_1": thesis_exposures_check(model.setup.mode),
            "relative_peaks": model.setup.leds.max(axis=1).round(4).tolist()}


def shifted_setup(setup: SimulationSetup, shifts_nm: np.ndarray, leds_csv: str | None = None) -> SimulationSetup:
    """LED spectra (1 nm source data) moved by ``shifts_nm`` (per LED; + = towards longer wavelengths)."""
    table = read_spectral_csv(leds_csv or resources.path("leds", "sphere10_relative.csv"))
    wl = setup.grid.wavelengths
    leds = np.stack([np.interp(wl - shifts_nm[k], table.wavelengths, table.values[:, k], left=0.0, right=0.0)
                     for k in range(table.values.shape[1])])
    return replace(setup, leds=leds)


def perturbed_targets(setup: SimulationSetup, rng: np.random.Generator, gain_sigma: float,
                      spectral_sigma: float) -> tuple[Target, Target]:
    """What the camera sees if the measured spectra are off: per patch a gain error and a smooth spectral one."""
    out = []
    wl = setup.grid.wavelengths
    for t in (setup.train, setup.test):
        n = len(t)
        gain = 1.0 + gain_sigma * rng.standard_normal((n, 1))
        knots = np.linspace(wl[0], wl[-1], 6)
        smooth = np.stack([np.interp(wl, knots, rng.standard_normal(6)) for _ in range(n)]) * spectral_sigma
        out.append(replace(t, spectra=np.clip(t.spectra * gain * (1.0 + smooth), 0.0, None)))
    return out[0], out[1]


def _mismatch_errors(setup_cam: SimulationSetup, train_true: Target, test_true: Target,
                     ref: SimulationSetup, W: np.ndarray) -> tuple[float, float]:
    """Fit on what the camera records (setup_cam's LEDs/camera, the true spectra) against the reference XYZ
    (measured spectra under ``ref``); mean dE00 train and test (float64)."""
    white = white_point(ref.illuminant, ref.cmfs)
    res = []
    A = None
    for true, meas in ((train_true, ref.train), (test_true, ref.test)):
        R = led_responses(setup_cam.leds, true.spectra, setup_cam.camera)        # (K, n, 3)
        C = np.einsum("lk,knc->nlc", W, R).reshape(R.shape[1], -1)
        xyz = tristimulus(meas.spectra, ref.illuminant, ref.cmfs)
        if A is None:
            A = fit_matrix(C, xyz)
        res.append(float(delta_e_2000(xyz_to_lab(xyz, white), xyz_to_lab(A.apply(C), white)).mean()))
    return res[0], res[1]


def sensitivity(spec: SetupSpec, cfg: StabilityConfig, optima: dict[str, np.ndarray], model: NoiseModel,
                cancel=None) -> dict:
    setup = spec.build()
    rng = np.random.default_rng(2024)
    drift_setups = [(f"all {d:+g} nm", shifted_setup(setup, np.full(10, d), spec.leds_csv)) for d in cfg.drift_nm]
    drift_random = [shifted_setup(setup, rng.normal(0, cfg.drift_sigma_nm, 10), spec.leds_csv)
                    for _ in range(cfg.drift_random)]
    targets = [perturbed_targets(setup, rng, cfg.target_gain_sigma, cfg.target_spectral_sigma)
               for _ in range(cfg.target_draws)]
    nominal_shift = shifted_setup(setup, np.zeros(10), spec.leds_csv)
    out = {}
    for name, W in optima.items():
        check(cancel)
        tr0, te0 = _mismatch_errors(setup, setup.train, setup.test, setup, W)
        row: dict[str, Any] = {"nominal": {"train": tr0, "test": te0}}
        ntr, nte = _mismatch_errors(nominal_shift, setup.train, setup.test, setup, W)
        row["drift"] = {}
        for label, s in drift_setups:
            tr, te = _mismatch_errors(s, setup.train, setup.test, setup, W)
            row["drift"][label] = {"train": tr, "test": te, "delta_train": tr - ntr}
        rd = [_mismatch_errors(s, setup.train, setup.test, setup, W) for s in drift_random]
        row["drift"][f"random sd {cfg.drift_sigma_nm:g} nm"] = {
            "train": float(np.mean([r[0] for r in rd])), "test": float(np.mean([r[1] for r in rd])),
            "delta_train": float(np.mean([r[0] for r in rd]) - ntr), "draws": len(rd)}
        te_ = [_mismatch_errors(setup, a, b, setup, W) for a, b in targets]
        row["target_error"] = {"train": float(np.mean([r[0] for r in te_])),
                               "test": float(np.mean([r[1] for r in te_])),
                               "delta_train": float(np.mean([r[0] for r in te_]) - tr0), "draws": len(te_),
                               "gain_sd": cfg.target_gain_sigma, "spectral_sd": cfg.target_spectral_sigma}
        e = model.expected_errors(W[None], cfg.check_draws, seed=99, exact=True)
        row["noise"] = {"train": float(e["train"][0]), "test": float(e["test"][0]),
                        "delta_train": float(e["train"][0]) - tr0, "exposures_s": model.exposures(W).tolist()}
        out[name] = row
    return out


@dataclass
class StabilityResult:
    spec: SetupSpec
    config: StabilityConfig
    seeds: dict
    clipping: dict
    dim: dict
    sensitivity: dict
    noise: ObjectivesResult
    elapsed_s: float

    def to_json(self) -> dict:
        return {"setup": self.spec.to_dict(), "elapsed_s": round(self.elapsed_s, 2), "seeds": self.seeds,
                "led_clipping": self.clipping, "dim_leds": self.dim, "sensitivity": self.sensitivity,
                "predicted_vs_captured": self.noise.to_json()}


def stability(spec: SetupSpec = SetupSpec(), cfg: StabilityConfig = StabilityConfig(), *,
              runner: Runner | None = None, progress: ProgressCallback | None = None,
              cancel: CancelToken | None = None, capture: Capture | None = None,
              capture_model: Callable[[SimulationSetup], CaptureModel] = study_capture_model) -> StabilityResult:
    """All five parts; only the seed runs (part 1) go through ``runner`` (the rest is quick and serial).
    ``capture(setup, W, exposures) -> {"train", "test", ...}``: a real capture chain to check the objectives
    against (the CLI passes the virtual lab's, app.captured_accuracy.captured_errors), ``capture_model(setup)``
    its model for the expected-captured objective (app.captured_accuracy.capture_model)."""
    t0 = time.perf_counter()
    seeds = seed_spread(spec, cfg, runner, progress, cancel)
    optima = {label: _weights(v["best_seed"]) for label, v in seeds.items()}
    ev = evaluator_for(spec)
    groups = light_pairs()[:cfg.light_sets] if cfg.light_sets else light_pairs()
    ex = exhaustive(ev, groups)
    optima = {"exhaustive (full intensity)": ex.best.weights(ev.n_leds), **optima}
    first_pso = next(label for label in seeds if seeds[label]["method"] == "pso")
    report(progress, 0.45, "stability: LED clipping")
    clipping = led_clipping(spec, cfg, optima[first_pso], cancel)
    model = NoiseModel(spec.build(), cfg.camera)
    dim = dim_leds(model, optima)
    report(progress, 0.6, "stability: sensitivity")
    sens = sensitivity(spec, cfg, optima, model, cancel)
    report(progress, 0.75, "stability: predicted vs captured, both modes")
    noise = objectives_study(spec, cfg.objectives, capture=capture, capture_model=capture_model, cancel=cancel)
    report(progress, 1.0, "stability: done")
    return StabilityResult(spec, cfg, seeds, clipping, dim, sens, noise, time.perf_counter() - t0)


# ---------------------------------------------------------------------------------------------------------
def stability_chart(result: StabilityResult):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 8.5), layout="constrained")
    FigureCanvasAgg(fig)
    (a1, a2), (a3, a4) = fig.subplots(2, 2)
    # (a) seed spread
    labels = list(result.seeds)
    for i, label in enumerate(labels):
        v = result.seeds[label]
        a1.plot(np.full(len(v["train"]), i) + np.linspace(-0.15, 0.15, len(v["train"])), v["train"], "o", ms=5)
        a1.annotate(f"{v['distinct_pairs']} pair(s)", (i, max(v["train"])), textcoords="offset points",
                    xytext=(0, 5), ha="center", fontsize=7)
    a1.set_xticks(range(len(labels)), [lbl.replace(" ", "\n", 1) for lbl in labels], fontsize=7)
    a1.set_ylabel("best training mean dE00 per seed")
    a1.set_title("(a) seed-to-seed spread (annotation: distinct best pairs)")
    a1.grid(True, alpha=0.3)
    # (b) LED clipping
    rows = result.clipping["rows"]
    x = np.arange(len(rows))
    names = ["+".join(map(str, r["removed"])) for r in rows]
    a2.bar(x - 0.2, [r["optimum_clipped_delta"] for r in rows], 0.4, label="PSO optimum, LED set to 0")
    a2.bar(x + 0.2, [r["reoptimised_delta"] for r in rows], 0.4, label="re-optimised without the LED")
    a2.set_yscale("symlog", linthresh=0.05)
    a2.set_xticks(x, names)
    a2.set_xlabel("LED removed")
    a2.set_ylabel("change of best training dE00")
    a2.set_title("(b) LED clipped to zero")
    a2.legend(fontsize=7)
    a2.grid(True, alpha=0.3)
    # (c) sensitivity
    sens = result.sensitivity
    opt_names = list(sens)
    kinds = [("noise", lambda r: r["noise"]["delta_train"])]
    drift_keys = list(next(iter(sens.values()))["drift"]) if sens else []
    kinds += [(f"drift {k}", (lambda key: lambda r: r["drift"][key]["delta_train"])(k)) for k in drift_keys]
    kinds += [("target error", lambda r: r["target_error"]["delta_train"])]
    w = 0.8 / max(1, len(opt_names))
    for j, name in enumerate(opt_names):
        a3.bar(np.arange(len(kinds)) + (j - (len(opt_names) - 1) / 2) * w, [f(sens[name]) for _, f in kinds], w,
               label=name)
    a3.set_xticks(range(len(kinds)), [k for k, _ in kinds], fontsize=7, rotation=20)
    a3.set_ylabel("change of training dE00 (fit redone)")
    a3.set_title("(c) sensitivity of each optimum")
    a3.legend(fontsize=6)
    a3.grid(True, alpha=0.3)
    # (d) predicted vs captured, both modes and objectives
    _predicted_vs_captured(a4, result.noise)
    return fig


def _predicted_vs_captured(ax, noise: ObjectivesResult) -> None:
    modes = dict.fromkeys(r["mode"] for r in noise.rows)     # reflective and/or transmissive
    for mode, colour in zip(modes, ("tab:blue", "tab:red")[:len(modes)], strict=True):
        rows = [r for r in noise.rows if r["mode"] == mode]
        ax.plot([r["noise_free_train"] for r in rows], [r["captured_train"] for r in rows], "o", mfc="none",
                color=colour, label=f"{mode}: noise-free prediction")
        ax.plot([r["expected_train"] for r in rows], [r["captured_train"] for r in rows], "s", color=colour,
                label=f"{mode}: expected captured prediction")
    hi = max(max(r["captured_train"], r["expected_train"]) for r in noise.rows) * 1.1
    ax.plot([0, hi], [0, hi], "k--", lw=0.8)
    ax.set_xlabel("predicted training mean dE00")
    ax.set_ylabel(f"captured ({noise.capture}) training mean dE00")
    ax.set_title("(d) predicted vs captured, both modes and objectives")
    ax.legend(fontsize=6)
    ax.grid(True, alpha=0.3)


def write_outputs(result: StabilityResult, out: StudyOutput) -> None:
    out.write_json("stability.json", result.to_json())
    out.save_figure(stability_chart(result), "stability.png")
    out.save_figure(predicted_vs_captured_chart(result.noise), "predicted_vs_captured.png")
    lines = [f"Setup: {result.spec.label()}; {result.config.seeds} seeds; total {result.elapsed_s:.0f} s.", "",
             "## Seed spread", "", "| optimiser | best train (median [min-max]) | distinct pairs | most common pair |",
             "|---|---|---:|---|"]
    for label, v in result.seeds.items():
        s = v["train_spread"]
        lines.append(f"| {label} | {s['median']:.4f} [{s['min']:.4f}-{s['max']:.4f}] | {v['distinct_pairs']} | "
                     f"{v['most_common_pair']} ({v['most_common_count']}/{len(v['seeds'])}) |")
    lines += ["", "## LED clipped to zero", "",
              f"PSO optimum training error {result.clipping['original_optimum_train']:.4f}.", "",
              "| removed | full-intensity best | rank of original best pair | optimum with LED at 0 | "
              "re-optimised |", "|---|---:|---:|---:|---:|"]
    for r in result.clipping["rows"]:
        lines.append(f"| {'+'.join(map(str, r['removed']))} | {r['full_intensity_best']:.4f} | "
                     f"{r['rank_of_original_best_pair']} | {r['optimum_clipped_train']:.4f} | "
                     f"{r['reoptimised_train']:.4f} |")
    lines += ["", "## Dim LEDs 6 and 7: exposures", "", "| optimum | light | LEDs @ levels | exposure s | "
              "share of LEDs 6+7 |", "|---|---:|---|---:|---:|"]
    for r in result.dim["lights"]:
        share = f"{r['share_led6_7']:.2f}" if r["share_led6_7"] is not None else "-"
        lines.append(f"| {r['optimum']} | {r['light']} | {r['leds']} @ {r['levels']} | {r['exposure_s']:.4f} | "
                     f"{share} |")
    lines += ["", "Thesis Table 7.1 vs model: " + "; ".join(
        f"{r['leds']}@{r['levels']}: {r['model_s']:.4f} s (thesis {r['thesis_s']:.4f} s)"
        for r in result.dim["thesis_table_7_1"]) + "."]
    lines += ["", "## Sensitivity (training dE00 change, fit redone on the perturbed capture)", "",
              "| optimum | nominal | noise | " + " | ".join(next(iter(result.sensitivity.values()))["drift"])
              + " | target error |", "|---|" + "---:|" * (3 + len(next(iter(result.sensitivity.values()))["drift"]))]
    for name, r in result.sensitivity.items():
        lines.append(f"| {name} | {r['nominal']['train']:.4f} | {r['noise']['delta_train']:+.4f} | "
                     + " | ".join(f"{v['delta_train']:+.4f}" for v in r["drift"].values())
                     + f" | {r['target_error']['delta_train']:+.4f} |")
    lines += ["", "## Predicted vs captured: both modes, noise-free and expected-captured objectives", ""]
    lines += summary_lines(result.noise)
    out.write_summary("Stability and robustness", lines)
