"""Spectral estimation study (``dualrgb study spectral``): methods x lights, both modes, in simulation.

For each mode the training target's values under three light sets:

* colour-chosen: the shipped PSO preset (``resources/presets/<mode>_pso.json``, chosen for mean dE00);
* spectral-chosen: the default optimiser (successive halving over PSO + L-BFGS-B) on the ``spectral`` objective
  (simulation.spectral_objective: expected captured spectral RMSE of the Wiener estimate);
* mixed-chosen: the same optimiser on the ``mixed`` objective (expected captured mean dE00 + 0.1 x 100 x that
  RMSE), lights for colour and spectra at once;
* 3-channel: the camera under the sphere's D65 mix (the demo's baseline);

and every spectral method (simulation.spectral_estimation), each with its settings chosen by 5-fold
cross-validation on the training target (simulation.spectral_selection). The estimators see noise-free values
(the thesis' simulation) and are told the capture model's noise of a training patch mean; they are judged on the
test target: spectral RMSE (over the mode's grid and over the wavelengths the system sees), GFC, mean CIEDE2000 under
D65, A, D50, FL11 and a warm-white LED. Time: the lights' search (spectral- and mixed-chosen; the shipped
preset's search is not repeated) plus the cross-validated fit; applying an estimator is one matrix product for every
method (its cost per megapixel is measured once).

The linear bound: least squares fitted on the *test* target itself under the same lights, the lowest mean-square
error any linear map can reach there. It is reported to show what a linear estimate cannot do (the camera is
blind above ~690 nm), never used to choose anything.

Outputs: ``spectral.json``, ``spectral.png`` (RMSE against dE00 and against time, per mode), ``SUMMARY.md``.
"""
from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.camera_model import flat_fielded_sensitivities
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.datasets import MODES, SimulationSetup
from dualrgb.simulation.defaults import default_grid
from dualrgb.simulation.halving import HalvingSettings, successive_halving
from dualrgb.simulation.search import light_pairs, refine_top
from dualrgb.simulation.spectral_estimation import SPECTRAL_METHODS, SpectralEstimator, SpectralTraining, quantity_of
from dualrgb.simulation.spectral_metrics import OTHER_LIGHTS, seen_wavelengths, spectral_figures, spectral_rmse
from dualrgb.simulation.spectral_objective import SpectralEvaluator
from dualrgb.simulation.spectral_selection import map_forms, select_estimator
from dualrgb.simulation.studies.common import SetupSpec, StudyOutput

log = logging.getLogger(__name__)

LIGHT_SETS = ("colour-chosen", "spectral-chosen", "mixed-chosen", "3-channel")
APPLY_PIXELS = 250_000          # pixels of the float32 band the apply timing runs on


@dataclass(frozen=True)
class SpectralStudyConfig:
    modes: tuple[str, ...] = MODES
    methods: tuple[str, ...] = tuple(SPECTRAL_METHODS)
    halving: HalvingSettings = HalvingSettings()
    seed: int = 0

    @classmethod
    def tiny(cls) -> SpectralStudyConfig:
        return cls(halving=HalvingSettings(particles=6, min_sets=2, polish_sets=1, polish_iterations=3))


def light_sets(setup: SimulationSetup, ev: SpectralEvaluator, cfg: SpectralStudyConfig,
               cancel: CancelToken | None = None) -> dict[str, dict]:
    """name -> {"W": levels (L, K) as the sphere holds them, "label", "search_s"} for :data:`LIGHT_SETS`."""
    from dualrgb import resources
    from dualrgb.simulation.presets import load_preset
    from dualrgb.simulation.sphere import realisable_d65_mix

    def entry(sources, search_s: float) -> dict:
        W = ev.realise(np.stack([s.weights(ev.n_leds) for s in sources]))
        return {"W": W, "label": " + ".join(s.label() for s in sources), "search_s": search_s}

    out = {"colour-chosen": entry(load_preset(resources.path("presets", f"{setup.mode}_pso.json")).sources, 0.0)}
    mixed = SpectralEvaluator(setup, ev.capture, ev.settings, mixed=True)
    mixed.spectral = ev.spectral                                     # the same prior and Gram matrices
    for name, objective in (("spectral-chosen", ev), ("mixed-chosen", mixed)):
        t0 = time.perf_counter()
        outcome = successive_halving(objective, light_pairs(), cfg.halving, cfg.seed, cancel=cancel)
        out[name] = entry(refine_top(objective, outcome, 1).best.sources, time.perf_counter() - t0)
    mix, _ = realisable_d65_mix(setup.leds, setup.illuminant, setup.cmfs, ev.capture.sphere)
    out["3-channel"] = entry((mix,), 0.0)
    return out


def training_of(setup: SimulationSetup, ev: SpectralEvaluator, W: np.ndarray) -> SpectralTraining:
    """Noise-free training values under W, the sensitivities, the capture model's noise of a patch mean."""
    S = flat_fielded_sensitivities(W @ setup.leds, setup.camera)
    model = ev.model
    noise = model.variances(model.values(W[None], "train"), model.noise_coefficients(W[None], "train"))[0]
    A = setup.illuminant[:, None] * setup.cmfs * 100.0 / float(setup.illuminant @ setup.cmfs[:, 1])
    return SpectralTraining(setup.train.spectra @ S, setup.train.spectra, setup.grid.wavelengths, sensitivities=S,
                            noise_var=noise.mean(axis=0), colour_weights=A, quantity=quantity_of(setup.mode))


def method_row(setup: SimulationSetup, training: SpectralTraining, S: np.ndarray, method: str) -> dict:
    """One method under one light set (sensitivities ``S``): its cross-validated choice, fit time and test (and
    train) figures."""
    t0 = time.perf_counter()
    sel = select_estimator(training, (method,))
    fit_s = time.perf_counter() - t0
    test_values = setup.test.spectra @ S
    f = spectral_figures(sel.estimator.apply(test_values), setup.test.spectra, setup.grid, setup.cmfs,
                         seen_wavelengths(S))
    train_rmse = float(spectral_rmse(sel.estimator.apply(training.values), training.spectra).mean())
    return {"method": method, "chosen": sel.chosen.label(), "fit_s": fit_s, "channels": S.shape[1],
            "cv_rmse": sel.cv_rmse[sel.chosen.label()], "train_rmse": train_rmse,
            "rmse": f["rmse"]["mean"], "rmse_p90": f["rmse"]["p90"], "rmse_seen": f["rmse_seen"]["mean"],
            "gfc": f["gfc"]["mean"], "de00": {k: v["mean"] for k, v in f["de00"].items()}}


def linear_bound(setup: SimulationSetup, S: np.ndarray) -> float:
    """Mean test RMSE of least squares fitted on the test target itself (a bound, never used to choose), with an
    offset where the mode's estimates may have one (simulation.spectral_selection.map_forms)."""
    values = setup.test.spectra @ S
    if True in map_forms(quantity_of(setup.mode)):
        values = np.c_[values, np.ones(len(values))]
    M = np.linalg.lstsq(values, setup.test.spectra, rcond=None)[0]
    return float(spectral_rmse(np.clip(values @ M, 0.0, 1.0), setup.test.spectra).mean())


def apply_us_per_pixel(estimator: SpectralEstimator, pixels: int = APPLY_PIXELS, repeats: int = 3) -> float:
    """Microseconds per pixel (= seconds per megapixel) to estimate spectra as the cube will: a float32 band, one
    matrix product and a clip (the best of ``repeats``)."""
    band = np.random.default_rng(0).uniform(0.0, 1.0, (pixels, estimator.n_channels)).astype(np.float32)
    out = np.empty((pixels, estimator.n_wavelengths), dtype=np.float32)
    estimator.apply(band, out=out)
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        estimator.apply(band, out=out)
        best = min(best, time.perf_counter() - t0)
    return best * 1e6 / pixels


def mode_study(setup: SimulationSetup, cfg: SpectralStudyConfig, capture: CaptureModel | None = None,
               cancel: CancelToken | None = None) -> dict:
    """Every method under every light set of one mode, with the linear bound per light set."""
    ev = SpectralEvaluator(setup, capture or CaptureModel.virtual_lab(setup.mode))
    sets = light_sets(setup, ev, cfg, cancel)
    rows, bounds, expected = [], {}, {}
    for name, entry in sets.items():
        check(cancel)
        S = flat_fielded_sensitivities(entry["W"] @ setup.leds, setup.camera)
        training = training_of(setup, ev, entry["W"])
        bounds[name] = linear_bound(setup, S)
        expected[name] = ev.spectral_stats(entry["W"])
        for method in cfg.methods:
            row = method_row(setup, training, S, method)
            rows.append({"mode": setup.mode, "lights": name, **row, "search_s": entry["search_s"],
                         "time_s": entry["search_s"] + row["fit_s"]})
    return {"mode": setup.mode, "lights": {k: {"label": v["label"], "levels": v["W"], "search_s": v["search_s"]}
                                           for k, v in sets.items()},
            "prior": ev.spectral.prior.to_dict(), "rows": rows, "linear_bound": bounds,
            "expected_spectral_rmse": expected}


@dataclass
class SpectralStudyResult:
    spec: SetupSpec
    config: SpectralStudyConfig
    modes: list[dict]
    apply_us_per_pixel: dict
    elapsed_s: float
    extra: dict = field(default_factory=dict)

    @property
    def rows(self) -> list[dict]:
        return [r for m in self.modes for r in m["rows"]]

    def row(self, mode: str, lights: str, method: str) -> dict:
        return next(r for r in self.rows if (r["mode"], r["lights"], r["method"]) == (mode, lights, method))

    def to_json(self) -> dict:
        return {"setup": self.spec.to_dict(), "config": asdict(self.config), "elapsed_s": round(self.elapsed_s, 2),
                "apply_us_per_pixel": self.apply_us_per_pixel, "modes": self.modes,
                "metrics": {"rmse": "mean over test patches of the RMSE over the mode's grid (factor, 0.01 = 1 %)",
                            "rmse_seen": "the same over the wavelengths the system sees (1 % of a channel's peak)",
                            "gfc": "mean goodness-of-fit coefficient", "de00": "mean CIEDE2000 under each light",
                            "lights": list(OTHER_LIGHTS)}}


def mode_spec(mode: str, step: float) -> SetupSpec:
    """The mode's grid (the parsimony study's range, simulation.defaults.default_grid) at ``step`` nm."""
    grid = default_grid(mode)
    return SetupSpec(mode, step, grid.start, grid.end)


def spectral_study(spec: SetupSpec = SetupSpec(), cfg: SpectralStudyConfig = SpectralStudyConfig(), *,
                   progress: ProgressCallback | None = None, cancel: CancelToken | None = None
                   ) -> SpectralStudyResult:
    t0 = time.perf_counter()
    modes = []
    for i, mode in enumerate(cfg.modes):
        report(progress, i / len(cfg.modes), f"spectral study: {mode}")
        setup = mode_spec(mode, spec.step).build()
        modes.append(mode_study(setup, cfg, cancel=cancel))
    report(progress, 1.0, "spectral study done")
    wl = mode_spec(cfg.modes[0], spec.step).grid.wavelengths
    apply_us = {f"{c} channels": apply_us_per_pixel(
        SpectralEstimator(np.zeros((len(wl), c)), wl, [f"c{i}" for i in range(c)], "pinv")) for c in (3, 6)}
    return SpectralStudyResult(spec, cfg, modes, apply_us, time.perf_counter() - t0)


# ---------------------------------------------------------------------------------------------------------
_MARKERS = {"wiener": "o", "matrix-r": "s", "pinv": "^"}
_COLOURS = {"colour-chosen": "C0", "spectral-chosen": "C3", "mixed-chosen": "C2", "3-channel": "C7"}


def spectral_chart(result: SpectralStudyResult):
    """Per mode: test RMSE against mean dE00 (filled: D65, hollow: the worst other light) and against time."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12.0, 4.4 * len(result.modes)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = np.atleast_2d(fig.subplots(len(result.modes), 2))
    for (a1, a2), m in zip(axes, result.modes, strict=True):
        _plane(a1, a2, m)
    return fig


def _plane(a1, a2, m: dict) -> None:
    for r in m["rows"]:
        c, mk = _COLOURS[r["lights"]], _MARKERS.get(r["method"], "o")
        worst = max(v for k, v in r["de00"].items() if k != "D65")
        a1.plot([r["de00"]["D65"], worst], [r["rmse"], r["rmse"]], color=c, lw=0.8, alpha=0.6)
        a1.plot(r["de00"]["D65"], r["rmse"], mk, color=c, ms=7)
        a1.plot(worst, r["rmse"], mk, color=c, ms=7, mfc="none")
        a2.plot(max(r["time_s"], 1e-3), r["rmse"], mk, color=c, ms=7)
    for name, bound in m["linear_bound"].items():
        a1.axhline(bound, color=_COLOURS[name], ls=":", lw=0.8)
    for ax in (a1, a2):
        ax.axhline(0.03, color="k", ls="--", lw=0.8)
        ax.grid(True, alpha=0.3)
        ax.set_ylabel("test mean spectral RMSE (the mode's grid)")
    handles = [a1.plot([], [], "o", color=c, label=k)[0] for k, c in _COLOURS.items()]
    handles += [a1.plot([], [], _MARKERS[k], color="0.3", label=k)[0] for k in _MARKERS]
    a1.legend(handles=handles, fontsize=7, loc="best")
    a1.set_xlabel("mean dE00 under D65 (filled) and under the worst of A, D50, FL11, LED (hollow)")
    a1.set_title(f"{m['mode']}: spectra against colour (dotted: linear bound; dashed: 0.03)", fontsize=9)
    a2.set_xscale("log")
    a2.set_xlabel("seconds: light search (spectral- and mixed-chosen) + cross-validated fit")
    a2.set_title(f"{m['mode']}: spectra against time", fontsize=9)


def summary_lines(result: SpectralStudyResult) -> list[str]:
    """The README's table: method x lights x mode with RMSE, GFC and dE00 under every light."""
    lights = list(OTHER_LIGHTS)
    lines = ["| Mode | Lights | Channels | Method (CV choice) | RMSE mean | RMSE seen | GFC | "
             + " | ".join(f"dE00 {k}" for k in lights) + " |", "|---" * (7 + len(lights)) + "|"]
    for r in result.rows:
        lines.append(f"| {r['mode']} | {r['lights']} | {r['channels']} | {r['chosen']} | {r['rmse']:.4f} | "
                     f"{r['rmse_seen']:.4f} | {r['gfc']:.4f} | " + " | ".join(f"{r['de00'][k]:.3f}" for k in lights)
                     + " |")
    return lines


def write_outputs(result: SpectralStudyResult, out: StudyOutput) -> None:
    out.write_json("spectral.json", result.to_json())
    out.save_figure(spectral_chart(result), "spectral.png")
    lines = [f"Setup: {result.spec.label()}; total {result.elapsed_s:.0f} s; applying an estimator costs "
             + ", ".join(f"{v:.3f} us per pixel ({k})" for k, v in result.apply_us_per_pixel.items()) + ".", ""]
    for m in result.modes:
        lines += [f"- {m['mode']}: " + "; ".join(f"{k} {v['label']} (search {v['search_s']:.1f} s, linear bound "
                                                 f"{m['linear_bound'][k]:.4f})" for k, v in m["lights"].items())]
    lines += ["", *summary_lines(result)]
    out.write_summary("Spectral estimation: methods x lights", lines)
