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
test target: spectral RMSE (over the wavelengths of the mode's grid that the test reference measured, and over those
the system sees too), GFC (where measured), mean CIEDE2000 under D65, A, D50, FL11 and a warm-white LED. Reflective
rows are also judged against a second CC24 reference measured to 780 nm (:data:`SECOND_TEST`: Ohta's), since the
packaged BabelColor reference ends at 730 nm. Time: the lights' search (spectral- and mixed-chosen; the shipped
preset's search is not repeated) plus the cross-validated fit; applying an estimator is one matrix product for every
method (its cost per megapixel is measured once).

The linear bound, for the metric reported (the mean over test patches of each patch's RMSE over the measured
wavelengths): its minimum over every linear map (affine for film) from the values to the spectra, fitted on the
*test* target itself, found by convex minimisation (iteratively reweighted least squares from least squares' map;
each patch's RMSE is a norm of an affine function of the map, so the mean is convex and the minimum global), before
any clip to [0, 1]
(the estimators clip; clipping can only lower an error, so a clipped map may go a little below). It shows what no
linear estimate can do under those lights, never used to choose anything. (Least squares minimises the pooled
mean-square error instead: 0.032 where the mean per-patch RMSE's own minimum is lower, issue 29.)

Outputs: ``spectral.json``, ``spectral.png`` (RMSE against dE00 and against time, per mode), ``SUMMARY.md``.
"""
from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.camera_model import flat_fielded_sensitivities
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.datasets import MODES, SimulationSetup, Target
from dualrgb.simulation.defaults import default_grid
from dualrgb.simulation.halving import HalvingSettings, successive_halving
from dualrgb.simulation.search import light_pairs, refine_top
from dualrgb.simulation.spectral_estimation import SPECTRAL_METHODS, SpectralEstimator, SpectralTraining, quantity_of
from dualrgb.simulation.spectral_metrics import OTHER_LIGHTS, seen_wavelengths, spectral_figures, spectral_rmse
from dualrgb.simulation.spectral_objective import SpectralEvaluator
from dualrgb.simulation.spectral_selection import map_forms, select_estimator
from dualrgb.simulation.studies.common import SetupSpec, StudyOutput

DOC_PAGE = "docs/explanation/spectral.md"     # the docs page holding the generated tables (`--doc`)

log = logging.getLogger(__name__)

LIGHT_SETS = ("colour-chosen", "spectral-chosen", "mixed-chosen", "3-channel")
SECOND_TEST = {"reflective": ("ColorChecker N Ohta", "reflective_test_ohta_cc24.csv")}    # measured to 780 nm
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


def test_figures(setup: SimulationSetup, target: Target, estimator: SpectralEstimator, S: np.ndarray) -> dict:
    """An estimator's figures on one test target: RMSE (p90), RMSE where the system sees, GFC, mean dE00 per
    light; RMSE and GFC over the wavelengths the target's reference measured, and that range."""
    f = spectral_figures(estimator.apply(target.spectra @ S), target.spectra, setup.grid, setup.cmfs,
                         seen_wavelengths(S), target.measured_mask(setup.grid.wavelengths))
    return {"rmse": f["rmse"]["mean"], "rmse_p90": f["rmse"]["p90"], "rmse_seen": f["rmse_seen"]["mean"],
            "gfc": f["gfc"]["mean"], "de00": {k: v["mean"] for k, v in f["de00"].items()},
            "wavelengths": f["wavelengths"]}


def method_row(setup: SimulationSetup, training: SpectralTraining, S: np.ndarray, method: str,
               second: Target | None = None) -> dict:
    """One method under one light set (sensitivities ``S``): its cross-validated choice, fit time and test (and
    train) figures; ``second``: a second test reference (its figures under ``second_test``)."""
    t0 = time.perf_counter()
    sel = select_estimator(training, (method,))
    fit_s = time.perf_counter() - t0
    train_rmse = float(spectral_rmse(sel.estimator.apply(training.values), training.spectra).mean())
    row = {"method": method, "chosen": sel.chosen.label(), "fit_s": fit_s, "channels": S.shape[1],
           "cv_rmse": sel.cv_rmse[sel.chosen.label()], "train_rmse": train_rmse,
           **test_figures(setup, setup.test, sel.estimator, S)}
    if second is not None:
        row["second_test"] = {"target": second.name, **test_figures(setup, second, sel.estimator, S)}
    return row


def linear_bound(setup: SimulationSetup, S: np.ndarray, target: Target | None = None) -> dict:
    """The reported metric's linear bound on ``target`` (default the test target; module docstring): the lowest
    mean per-patch RMSE over the measured wavelengths of any linear map (affine where the mode's estimates may
    be, simulation.spectral_selection.map_forms) fitted on the target itself, and least squares' figure."""
    target = target or setup.test
    keep = target.measured_mask(setup.grid.wavelengths)
    R = target.spectra if keep is None else target.spectra[:, keep]
    values = target.spectra @ S
    if True in map_forms(quantity_of(setup.mode)):
        values = np.c_[values, np.ones(len(values))]
    M0 = np.linalg.lstsq(values, R, rcond=None)[0]
    M, fun = min_mean_rmse_map(values, R, M0)
    return {"bound": fun, "bound_clipped": float(spectral_rmse(np.clip(values @ M, 0.0, 1.0), R).mean()),
            "least_squares": float(spectral_rmse(np.clip(values @ M0, 0.0, 1.0), R).mean()),
            "wavelengths": [float(w) for w in setup.grid.wavelengths[keep][[0, -1]]] if keep is not None else None}


def min_mean_rmse_map(values: np.ndarray, R: np.ndarray, start: np.ndarray, iterations: int = 2000,
                      delta: float = 1e-10) -> tuple[np.ndarray, float]:
    """The map M minimising mean_j RMSE(values_j M, R_j) from ``start``; returns M and the minimum.

    The objective is a sum of Euclidean norms of affine functions of M (convex, but not smooth where a patch's
    residual is 0, which its minimum reaches for a few patches, as a least-absolute-deviations fit does), so a
    smooth optimiser stalls short of it. Iteratively reweighted least squares (each step the weighted least
    squares with weights 1 / max(|residual_j|, delta): Weiszfeld's scheme) converges to it; written here because
    scipy has no solver for sums of norms and the study should not need a convex-programming package.
    """
    M = np.asarray(start, dtype=float)
    k = R.shape[1]
    for _ in range(iterations):
        E = values @ M - R
        w = 1.0 / np.maximum(np.sqrt((E * E).sum(axis=1)), delta)
        new = np.linalg.solve(values.T @ (w[:, None] * values), values.T @ (w[:, None] * R))
        done = np.abs(new - M).max() < 1e-13
        M = new
        if done:
            break
    E = values @ M - R
    return M, float(np.sqrt((E * E).sum(axis=1) / k).mean())


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
    second = second_test(setup)
    rows, bounds, bounds2, expected = [], {}, {}, {}
    for name, entry in sets.items():
        check(cancel)
        S = flat_fielded_sensitivities(entry["W"] @ setup.leds, setup.camera)
        training = training_of(setup, ev, entry["W"])
        bounds[name] = linear_bound(setup, S)
        if second is not None:
            bounds2[name] = linear_bound(setup, S, second)
        expected[name] = ev.spectral_stats(entry["W"])
        for method in cfg.methods:
            row = method_row(setup, training, S, method, second)
            rows.append({"mode": setup.mode, "lights": name, **row, "search_s": entry["search_s"],
                         "time_s": entry["search_s"] + row["fit_s"]})
    return {"mode": setup.mode, "lights": {k: {"label": v["label"], "levels": v["W"], "search_s": v["search_s"]}
                                           for k, v in sets.items()},
            "prior": ev.spectral.prior.to_dict(), "rows": rows, "linear_bound": bounds,
            "second_test": None if second is None else {"target": second.name, "linear_bound": bounds2},
            "expected_spectral_rmse": expected}


def second_test(setup: SimulationSetup) -> Target | None:
    """The mode's second test reference (:data:`SECOND_TEST`) on the setup's grid, None where there is none."""
    from dualrgb import resources
    from dualrgb.simulation.datasets import load_target

    if setup.mode not in SECOND_TEST:
        return None
    name, file = SECOND_TEST[setup.mode]
    return load_target(resources.path("targets", file), setup.grid, name)


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
                "metrics": {"rmse": "mean over test patches of the RMSE over the mode's grid where the test "
                                    "reference was measured (factor, 0.01 = 1 %)",
                            "rmse_seen": "the same over the measured wavelengths the system sees (1 % of a channel's "
                                         "peak)",
                            "gfc": "mean goodness-of-fit coefficient where measured",
                            "de00": "mean CIEDE2000 under each light (the whole grid)",
                            "linear_bound": "lowest rmse (the metric above) of any linear map fitted on the test "
                                            "target itself, before clipping",
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
        a1.axhline(bound["bound"], color=_COLOURS[name], ls=":", lw=0.8)
    for ax in (a1, a2):
        ax.axhline(0.03, color="k", ls="--", lw=0.8)
        ax.grid(True, alpha=0.3)
        ax.set_ylabel("test mean spectral RMSE (where the reference was measured)")
    handles = [a1.plot([], [], "o", color=c, label=k)[0] for k, c in _COLOURS.items()]
    handles += [a1.plot([], [], _MARKERS[k], color="0.3", label=k)[0] for k in _MARKERS]
    a1.legend(handles=handles, fontsize=7, loc="best")
    a1.set_xlabel("mean dE00 under D65 (filled) and under the worst of A, D50, FL11, LED (hollow)")
    a1.set_title(f"{m['mode']}: spectra against colour (dotted: linear bound; dashed: 0.03)", fontsize=9)
    a2.set_xscale("log")
    a2.set_xlabel("seconds: light search (spectral- and mixed-chosen) + cross-validated fit")
    a2.set_title(f"{m['mode']}: spectra against time", fontsize=9)


def _nm(pair: list[float] | None) -> str:
    return "-" if not pair else f"{pair[0]:g}-{pair[1]:g} nm"


def summary_lines(modes: list[dict]) -> list[str]:
    """The docs page's tables from the study's ``modes`` (SpectralStudyResult.modes, or its JSON's): method x lights x
    mode with RMSE, GFC and dE00 under every light; each light set's linear bound; and, where the mode has one,
    the figures against the second test reference."""
    lights = list(OTHER_LIGHTS)
    rows = [r for m in modes for r in m["rows"]]
    lines = ["| Mode | Lights | Channels | Method (CV choice) | RMSE mean (where measured) | RMSE seen (over) | GFC | "
             + " | ".join(f"dE00 {k}" for k in lights) + " |", "|---" * (7 + len(lights)) + "|"]
    for r in rows:
        lines.append(f"| {r['mode']} | {r['lights']} | {r['channels']} | {r['chosen']} | {r['rmse']:.4f} | "
                     f"{r['rmse_seen']:.4f} ({_nm(r['wavelengths'].get('seen'))}) | {r['gfc']:.4f} | "
                     + " | ".join(f"{r['de00'][k]:.3f}" for k in lights) + " |")
    lines += ["", "| Mode | Lights | Test reference | RMSE and GFC over | RMSE seen over | linear bound (mean "
              "per-patch RMSE) | that map clipped | least squares |", "|---" * 8 + "|"]
    for m in modes:
        # each light set's own windows: where the system sees depends on its lights (the 3-channel mix sees to
        # 680 nm, the colour-chosen pair to 660 nm; one row's window for all mislabelled the others, issue 40)
        first = {r["lights"]: r for r in reversed(m["rows"])}
        refs = [({k: r["wavelengths"] for k, r in first.items()}, m["linear_bound"], "packaged")]
        if m.get("second_test"):
            second = {k: r["second_test"] for k, r in first.items() if "second_test" in r}
            name = next(iter(second.values()))["target"]
            refs.append(({k: v["wavelengths"] for k, v in second.items()}, m["second_test"]["linear_bound"], name))
        for where, bounds, ref in refs:
            for name, b in bounds.items():
                w = where.get(name, {})
                lines.append(f"| {m['mode']} | {name} | {ref} | {_nm(w.get('measured'))} | {_nm(w.get('seen'))} "
                             f"| {b['bound']:.4f} | {b['bound_clipped']:.4f} | {b['least_squares']:.4f} |")
    return lines + _second_lines(rows)


def _second_lines(rows: list[dict]) -> list[str]:
    """Each method's figures against the packaged test reference and the second one, side by side."""
    rows = [r for r in rows if "second_test" in r]
    if not rows:
        return []
    name = rows[0]["second_test"]["target"]
    lines = ["", f"| Mode | Lights | Method | RMSE packaged reference | RMSE {name} | RMSE seen, packaged | RMSE seen, "
             f"{name} | GFC packaged | GFC {name} |", "|---" * 9 + "|"]
    for r in rows:
        o = r["second_test"]
        lines.append(f"| {r['mode']} | {r['lights']} | {r['chosen']} | {r['rmse']:.4f} | {o['rmse']:.4f} | "
                     f"{r['rmse_seen']:.4f} | {o['rmse_seen']:.4f} | {r['gfc']:.4f} | {o['gfc']:.4f} |")
    return lines


def readme_section(doc: dict, source: Any) -> str:
    """The docs page's generated section (DOC_PAGE) from the study's JSON document
    (:meth:`SpectralStudyResult.to_json`): its tables and where they came from."""
    return "\n".join([f"Made by `dualrgb study spectral --from-json {source} --doc {DOC_PAGE}` from the study's "
                      f"JSON ({doc['setup']['step']:g} nm, {doc['elapsed_s']:.0f} s). Test targets: CC24 (BabelColor, "
                      "measured 380-730 nm) / CC24-on-film; RMSE and GFC over the measured wavelengths of the mode's "
                      "grid; RMSE seen: over those the camera sees too.", "", *summary_lines(doc["modes"])])


def load_study(path: Any) -> dict:
    """A saved ``spectral.json``; ValueError (one line) naming the file when it is not one."""
    import json
    from pathlib import Path

    p = Path(path)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{p}: cannot read a study spectral document ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != "dualrgb-study-spectral/1" or "modes" not in doc:
        raise ValueError(f"{p}: expected a study spectral document (dualrgb-study-spectral/1)")
    return doc


def write_outputs(result: SpectralStudyResult, out: StudyOutput) -> None:
    out.write_json("spectral.json", result.to_json())
    out.save_figure(spectral_chart(result), "spectral.png")
    lines = [f"Setup: {result.spec.label()}; total {result.elapsed_s:.0f} s; applying an estimator costs "
             + ", ".join(f"{v:.3f} us per pixel ({k})" for k, v in result.apply_us_per_pixel.items()) + ".", ""]
    for m in result.modes:
        lines += [f"- {m['mode']}: " + "; ".join(f"{k} {v['label']} (search {v['search_s']:.1f} s, linear bound "
                                                 f"{m['linear_bound'][k]['bound']:.4f})"
                                                 for k, v in m["lights"].items())]
    lines += ["", *summary_lines(result.modes)]
    out.write_summary("Spectral estimation: methods x lights", lines)
