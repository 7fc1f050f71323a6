"""Noise-free, expected-captured, robust and per-pixel objectives compared (``dualrgb study objectives``; the
stability study's predicted-vs-captured part).

For each mode, each colour objective (:data:`simulation.choices.COLOUR_OBJECTIVES`) and each method (exhaustive at full
intensity, the default successive halving over PSO, and the thesis PSO except on the 8x dearer robust
objective and the per-pixel one), the optimum's wall and CPU time and its figures under every objective:
noise-free, expected captured (float64, patch means), robust (mean over the plausible worlds) and per pixel (the
matrix fitted on the patch means applied to one pixel: simulation.expected_error.ExpectedErrorModel.pixel_errors,
mean and test p90). Then each distinct optimum is *captured* at the levels the sphere holds (simulation.sphere: a
noise-free optimum's trace level below the minimum stable level is 0 there) through the virtual lab and
app.processing when a ``capture`` is given (patch means and per pixel), else the pixel-level capture simulation of
simulation.studies.noise (patch means), and the captured training error is set against the predictions.

Conditioning (``conditioning``, per mode): the condition number of each of the 630 binned pairs at full level
(simulation.colour_models.condition_number, on the training reflectances) beside its expected per-pixel test error,
the evidence for the limits the calibration refuses and warns at (app.workflow.stand.preflight.CONDITION_LIMIT / _WARN).

The worked example is the transmissive full-intensity pair (2, 5, 9) + (2, 6, 9): the best noise-free choice
(0.45 dE00) shares LEDs 2 and 9 between its lights, so its six channels are nearly collinear, the fitted matrix
amplifies the camera noise, and it is captured at ~1.9 dE00 (worse than 3-channel); the expected-captured
objective predicts that and picks (1, 6, 8) + (3, 5, 9) instead.

Outputs: ``objectives.json``, ``objectives.png`` (the speed-accuracy plane per mode: patch means above, per pixel
below), ``predicted_vs_captured.png`` and ``SUMMARY.md``.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.capture_model import CameraNoise, CaptureModel
from dualrgb.simulation.choices import COLOUR_OBJECTIVES
from dualrgb.simulation.datasets import MODES, SimulationSetup
from dualrgb.simulation.halving import HalvingSettings, successive_halving
from dualrgb.simulation.pso import PsoSettings, pso
from dualrgb.simulation.robust import RobustEvaluator, RobustSettings
from dualrgb.simulation.runner import make_evaluator
from dualrgb.simulation.search import exhaustive, light_pairs, refine_top
from dualrgb.simulation.studies.common import SetupSpec, StudyOutput, new_figure
from dualrgb.simulation.studies.noise import NoiseModel

log = logging.getLogger(__name__)

Capture = Callable[[SimulationSetup, np.ndarray, np.ndarray], dict]
WORKED_EXAMPLE = ("transmissive", ((2, 5, 9), (2, 6, 9)))


@dataclass(frozen=True)
class ObjectivesConfig:
    modes: tuple[str, ...] = MODES
    objectives: tuple[str, ...] = COLOUR_OBJECTIVES
    methods: tuple[str, ...] = ("exhaustive", "halving", "pso")
    light_sets: int | None = None                 # None: all 630
    halving: HalvingSettings = HalvingSettings()
    pso: PsoSettings = PsoSettings()
    robust: RobustSettings = RobustSettings()
    capture_repeats: int = 2
    seed: int = 0

    @classmethod
    def tiny(cls) -> ObjectivesConfig:
        return cls(light_sets=8, halving=HalvingSettings(particles=6, min_sets=2, polish_sets=1, polish_iterations=3),
                   pso=PsoSettings(particles=8, iterations=2), robust=RobustSettings(worlds=2), capture_repeats=1)


def study_capture_model(setup: SimulationSetup) -> CaptureModel:
    """The expected-captured model of the pixel-level capture simulation (simulation.studies.noise): 64 pixels per
    patch and channel, one white frame, plain means."""
    return CaptureModel(camera=CameraNoise(), test_pixels_per_patch=None, green_pixels=1, trim_efficiency=1.0)


def _groups(cfg: ObjectivesConfig, mode: str) -> list:
    groups = light_pairs()
    if cfg.light_sets:
        groups = groups[:cfg.light_sets]
        if mode == WORKED_EXAMPLE[0] and WORKED_EXAMPLE[1] not in groups:
            groups.append(WORKED_EXAMPLE[1])
    return groups


def optima(setup: SimulationSetup, cfg: ObjectivesConfig, capture_model: CaptureModel,
           cancel: CancelToken | None = None) -> list[dict]:
    """Every (objective, method) optimum with its wall time and its figures under all three objectives."""
    groups = _groups(cfg, setup.mode)
    judge = RobustEvaluator(setup, capture_model, cfg.robust)       # expected (nominal world) and robust figures
    rows = []
    for objective in cfg.objectives:
        ev = judge if objective == "robust" else make_evaluator(setup, objective, capture_model)
        for method in cfg.methods:
            if method == "pso" and objective in ("robust", "expected-per-pixel"):
                continue                                             # 8 worlds x 1.39 M evaluations; CPU budget
            check(cancel)
            t0, c0 = time.perf_counter(), time.process_time()
            if method == "exhaustive":
                out = exhaustive(ev, groups)
            elif method == "halving":
                out = successive_halving(ev, groups, cfg.halving, cfg.seed, cancel=cancel)
            else:
                out = pso(ev, groups, cfg.pso, cfg.seed, cancel=cancel)
            seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
            best = refine_top(ev, out, 1, judge).best
            W = judge.realise(best.weights(judge.n_leds))        # what the sphere holds: captured and judged
            px = judge.pixel_stats(W)
            rows.append({"mode": setup.mode, "objective": objective, "method": method, "seconds": seconds,
                         "cpu_seconds": cpu, "evaluations": out.evaluations,
                         "pair": [list(s.leds) for s in best.sources],
                         "levels": [[float(W[li, k - 1]) for k in s.leds] for li, s in enumerate(best.sources)],
                         "requested_levels": [list(s.levels) for s in best.sources],
                         "noise_free_train": best.train_errors.mean, "noise_free_test": best.test_errors.mean,
                         "expected_train": best.expected_train_errors.mean,
                         "expected_test": best.expected_test_errors.mean,
                         "robust_train": float(judge.world_costs(W).mean()),
                         "per_pixel_train": px["train"]["mean"], "per_pixel_test": px["test"]["mean"],
                         "per_pixel_test_p90": px["test"]["p90"]})
    return rows


def conditioning_evidence(setup: SimulationSetup, capture_model: CaptureModel) -> dict:
    """Every binned pair at full level: its condition number and expected per-pixel test dE00, against the
    3-channel camera's (the mode's packaged one-light preset). Summarised at the preflight's limits."""
    from dualrgb.simulation.camera_model import led_responses, with_flare
    from dualrgb.simulation.colour_models import condition_number
    from dualrgb.simulation.expected_error import ExpectedErrorModel
    from dualrgb.simulation.presets import load_preset, packaged_presets

    model = ExpectedErrorModel(setup, capture_model)
    R = with_flare(led_responses(setup.leds, setup.train.spectra, setup.camera), setup.flare)
    groups = light_pairs()
    W = np.zeros((len(groups), 2, model.n_leds))
    for i, g in enumerate(groups):
        for li, leds in enumerate(g):
            W[i, li, np.asarray(leds) - 1] = 1.0
    cond = np.array([condition_number(np.einsum("lk,knc->nlc", w, R).reshape(R.shape[1], -1)) for w in W])
    px = np.concatenate([model.test_errors(model.emitted(W[lo:lo + 64]), pixel=True).mean
                         for lo in range(0, len(W), 64)])
    one = next(load_preset(p) for p in packaged_presets() if p.stem == "three_channel_d65")
    W3 = model.emitted(np.stack([s.weights(model.n_leds) for s in one.sources])[None])
    base = float(model.test_errors(W3, pixel=True).mean[0])
    out: dict[str, Any] = {"pairs": len(groups), "three_channel_per_pixel_test": base,
                           "condition_min": float(cond.min()), "condition_max": float(cond.max())}
    for name, limit in (("above_1e3", 1e3), ("above_1e4", 1e4)):
        sel = cond > limit
        out[name] = {"pairs": int(sel.sum()), "best_per_pixel_test": float(px[sel].min()) if sel.any() else None,
                     "worse_than_three_channel": float(np.mean(px[sel] > base)) if sel.any() else None}
    out["below_1e3"] = {"pairs": int((cond <= 1e3).sum()), "best_per_pixel_test": float(px[cond <= 1e3].min())}
    out["per_pair"] = {"condition": np.round(cond, 2).tolist(), "per_pixel_test": np.round(px, 4).tolist()}
    return out


def captured(setup: SimulationSetup, rows: list[dict], capture: Capture | None, repeats: int) -> None:
    """Capture each distinct optimum once (virtual lab or pixel-level simulation) and add its captured errors."""
    model = NoiseModel(setup)
    done: dict[str, dict] = {}
    for row in rows:
        W = np.zeros((2, model.n_leds))
        for li, (leds, levels) in enumerate(zip(row["pair"], row["levels"], strict=True)):
            W[li, np.asarray(leds) - 1] = levels
        key = repr(W.round(6).tolist())
        if key not in done:
            done[key] = (capture(setup, W, model.exposures(W)) if capture is not None
                         else model.captured_errors(W, repeats))
        row.update(captured_train=done[key]["train"], captured_test=done[key]["test"],
                   **{f"captured_{k}": done[key][k] for k in ("per_pixel_train", "per_pixel_test", "per_pixel_test_p90")
                      if k in done[key]})


@dataclass
class ObjectivesResult:
    config: ObjectivesConfig
    rows: list[dict]
    capture: str
    elapsed_s: float = 0.0
    summary: dict = field(default_factory=dict)
    conditioning: dict = field(default_factory=dict)        # mode -> conditioning_evidence
    cpu_s: float = 0.0

    def to_json(self) -> dict:
        return {"elapsed_s": round(self.elapsed_s, 2), "cpu_s": round(self.cpu_s, 2), "capture": self.capture,
                "rows": self.rows, "summary": self.summary, "robust": self.config.robust.to_dict(),
                "conditioning": self.conditioning}


def _summary(rows: list[dict]) -> dict:
    """Mean |predicted - captured| / captured of each prediction, and the worked example's rows."""
    out: dict[str, Any] = {}
    for key, got in (("noise_free_train", "captured_train"), ("expected_train", "captured_train"),
                     ("per_pixel_train", "captured_per_pixel_train"), ("per_pixel_test", "captured_per_pixel_test")):
        rel = [abs(r[key] - r[got]) / r[got] for r in rows if got in r]
        out[f"{key}_relative_error"] = float(np.mean(rel)) if rel else None
        out[f"{key}_max_relative_error"] = float(np.max(rel)) if rel else None
    out["worked_example"] = [r for r in rows if r["mode"] == WORKED_EXAMPLE[0] and r["method"] == "exhaustive"]
    return out


def objectives_study(spec: SetupSpec = SetupSpec(), cfg: ObjectivesConfig = ObjectivesConfig(), *,
                     capture: Capture | None = None,
                     capture_model: Callable[[SimulationSetup], CaptureModel] = study_capture_model,
                     progress: ProgressCallback | None = None,
                     cancel: CancelToken | None = None) -> ObjectivesResult:
    """All modes of ``cfg`` (``spec`` gives the grid and any user CSVs). ``capture(setup, W, exposures)`` is the
    capture chain to check against (the CLI passes the virtual lab's) and ``capture_model(setup)`` its model."""
    t0, c0 = time.perf_counter(), time.process_time()
    rows = []
    conditioning = {}
    for i, mode in enumerate(cfg.modes):
        setup = replace(spec, mode=mode).build()
        report(progress, i / len(cfg.modes), f"objectives: {mode} optima")
        mode_rows = optima(setup, cfg, capture_model(setup), cancel)
        report(progress, (i + 0.6) / len(cfg.modes), f"objectives: {mode} captures")
        captured(setup, mode_rows, capture, cfg.capture_repeats)
        conditioning[mode] = conditioning_evidence(setup, capture_model(setup))
        rows += mode_rows
    report(progress, 1.0, "objectives: done")
    return ObjectivesResult(cfg, rows, "virtual lab" if capture is not None else "pixel-level simulation",
                            time.perf_counter() - t0, _summary(rows), conditioning, time.process_time() - c0)


# ---------------------------------------------------------------------------------------------------------
_COLOURS = {"exhaustive": "black", "halving": "tab:green", "pso": "tab:blue"}
_MARKERS = {"noise-free": "o", "expected-captured": "s", "robust": "D", "expected-per-pixel": "^"}


def speed_accuracy_chart(result: ObjectivesResult):
    """Per mode (columns): CPU seconds against the optimum's expected captured training error (top: patch means,
    hollow the robust figure) and its per-pixel error (bottom: hollow the captured per-pixel figure)."""
    modes = list(dict.fromkeys(r["mode"] for r in result.rows))
    fig, axes = new_figure(5.5 * len(modes), 8.4, ncols=len(modes), nrows=2)
    axes = np.asarray(axes).reshape(2, len(modes))
    for col, mode in enumerate(modes):
        top, bottom = axes[0, col], axes[1, col]
        for r in (r for r in result.rows if r["mode"] == mode):
            kw = dict(color=_COLOURS[r["method"]], marker=_MARKERS[r["objective"]], ms=8, ls="none")
            top.plot(r["cpu_seconds"], r["expected_train"], **kw)
            top.plot(r["cpu_seconds"], r["robust_train"], mfc="none", **kw)
            bottom.plot(r["cpu_seconds"], r["per_pixel_train"], **kw)
            if "captured_per_pixel_train" in r:
                bottom.plot(r["cpu_seconds"], r["captured_per_pixel_train"], mfc="none", **kw)
        for method, c in _COLOURS.items():
            top.plot([], [], color=c, marker="o", ls="none", label=method)
        for objective, m in _MARKERS.items():
            top.plot([], [], color="grey", marker=m, ls="none", label=f"optimised: {objective}")
        top.plot([], [], color="grey", marker="o", mfc="none", ls="none", label="hollow: robust figure")
        bottom.plot([], [], color="grey", marker="o", mfc="none", ls="none", label="hollow: captured per pixel")
        for ax, what in ((top, "expected captured training mean dE00 (patch means)"),
                         (bottom, "per-pixel training mean dE00 (expected)")):
            ax.set_xscale("log")
            ax.set_xlabel("CPU seconds of the search")
            ax.set_ylabel(what)
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=7)
        top.set_title(f"{mode}: optima judged as patch means")
        bottom.set_title(f"{mode}: the same optima, per pixel")
    return fig


def predicted_vs_captured_chart(result: ObjectivesResult):
    modes = list(dict.fromkeys(r["mode"] for r in result.rows))
    fig, axes = new_figure(5.5 * len(modes), 4.6, ncols=len(modes))
    for ax, mode in zip(np.atleast_1d(axes), modes, strict=True):
        rows = [r for r in result.rows if r["mode"] == mode and "captured_train" in r]
        cap = [r["captured_train"] for r in rows]
        ax.plot([r["noise_free_train"] for r in rows], cap, "o", mfc="none", color="tab:blue",
                label="noise-free prediction")
        ax.plot([r["expected_train"] for r in rows], cap, "s", color="tab:red", label="expected captured prediction")
        for r in rows:
            if mode == WORKED_EXAMPLE[0] and [tuple(p) for p in r["pair"]] == list(WORKED_EXAMPLE[1]):
                ax.annotate("(2,5,9)+(2,6,9): noise-free pick", (r["noise_free_train"], r["captured_train"]),
                            textcoords="offset points", xytext=(8, -12), fontsize=7)
        hi = max(cap + [r["expected_train"] for r in rows]) * 1.1
        ax.plot([0, hi], [0, hi], "k--", lw=0.8)
        ax.set_xlabel("predicted training mean dE00")
        ax.set_ylabel(f"captured ({result.capture}) training mean dE00")
        ax.set_title(f"{mode}: predicted vs captured")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    return fig


def summary_lines(result: ObjectivesResult) -> list[str]:
    nan = float("nan")
    lines = ["| mode | objective | method | CPU s | pair @ levels | noise-free train | expected train | robust | "
             "per-pixel train / test (p90) | captured train | captured test | captured per-pixel train / test |",
             "|---|---|---|---:|---|---:|---:|---:|---|---:|---:|---|"]
    for r in result.rows:
        levels = " + ".join(f"{tuple(p)}@{tuple(round(v, 4) for v in lv)}"
                            for p, lv in zip(r["pair"], r["levels"], strict=True))
        lines.append(f"| {r['mode']} | {r['objective']} | {r['method']} | {r['cpu_seconds']:.2f} | {levels} | "
                     f"{r['noise_free_train']:.3f} | {r['expected_train']:.3f} | {r['robust_train']:.3f} | "
                     f"{r['per_pixel_train']:.3f} / {r['per_pixel_test']:.3f} ({r['per_pixel_test_p90']:.3f}) | "
                     f"{r.get('captured_train', nan):.3f} | {r.get('captured_test', nan):.3f} | "
                     f"{r.get('captured_per_pixel_train', nan):.3f} / {r.get('captured_per_pixel_test', nan):.3f} |")
    s = result.summary

    def pct(key: str) -> str:
        v, m = s.get(f"{key}_relative_error"), s.get(f"{key}_max_relative_error")
        return "n/a" if v is None or m is None else f"{100 * v:.0f} % (max {100 * m:.0f} %)"
    lines += ["", f"Mean |predicted - captured| / captured ({result.capture}): training, noise-free "
                  f"{pct('noise_free_train')}, expected captured {pct('expected_train')}; per pixel, training "
                  f"{pct('per_pixel_train')}, test {pct('per_pixel_test')}."]
    for mode, c in result.conditioning.items():
        above = c["above_1e4"]
        lines.append(f"Conditioning, {mode}: of {c['pairs']} pairs, {above['pairs']} above 1e4 (best per-pixel test "
                     f"{above['best_per_pixel_test'] or nan:.2f}), {c['above_1e3']['pairs']} above 1e3; 3-channel "
                     f"per pixel {c['three_channel_per_pixel_test']:.2f}.")
    return lines


def write_outputs(result: ObjectivesResult, out: StudyOutput) -> None:
    out.write_json("objectives.json", result.to_json())
    out.save_figure(speed_accuracy_chart(result), "objectives.png")
    out.save_figure(predicted_vs_captured_chart(result), "predicted_vs_captured.png")
    out.write_summary("Noise-free, expected-captured and robust objectives",
                      [f"{len(result.rows)} optima, {result.elapsed_s:.0f} s; captures: {result.capture}.", ""]
                      + summary_lines(result))
