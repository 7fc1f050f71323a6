"""The simplest choices that cost no accuracy (``dualrgb study parsimony``).

Three questions, each answered automatically with a tolerance (default 0.05 mean dE00):

1. Spectral step (1 / 5 / 10 / 20 nm): at each step the full-intensity exhaustive search and a PSO pick their
   optimum; both optima are re-evaluated on the 1 nm reference model. A step is acceptable when the optimum
   it picks is within the tolerance of the 1 nm optimum *on the 1 nm model*, and its own error estimate is
   within the tolerance of the 1 nm re-evaluation. The coarsest acceptable step is chosen.
2. Characterisation model (linear 6x3, dE-optimised 6x3, root-polynomial degree 2 with 21 terms): fitted on
   simulated captures (noise model of :mod:`.noise`) of the training target for the optimum light sets, judged
   on the captured *test* target. The simplest model within the tolerance of the most accurate one is chosen.
3. HDR exposures per light (1-4, geometric from the open-gate exposure to 100x, i.e. an ND 2.0 filter over
   half the patches as thesis 8.3): test error of simulated captures, merged with the HDR estimator that
   ``dualrgb study hdr`` chose (key ``hdr_merge``, kept). The fewest exposures within the tolerance of the most
   accurate bracket are chosen.

The choices go to ``parsimony.json`` (format ``dualrgb-parsimony/1``); :mod:`simulation.defaults` reads the
user's copy (``--write-defaults`` puts it in the per-user data folder, ``resources.user_path``) when there is
one, else the packaged ``resources/parsimony.json`` from the reference run.
"""
from __future__ import annotations

import datetime as _dt
import logging
import time
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from common.progress import CancelToken, ProgressCallback, check, report
from simulation.defaults import FORMAT, save_defaults
from simulation.hdr_estimators import default_method
from simulation.pso import PsoSettings, pso
from simulation.search import exhaustive, light_pairs, refine_top
from simulation.studies.common import SetupSpec, StudyOutput, evaluator_for, new_figure
from simulation.studies.models import MODEL_TERMS, MODELS
from simulation.studies.noise import CameraNoise, NoiseModel
from simulation.versions import output_header

log = logging.getLogger(__name__)

@dataclass(frozen=True)
class ParsimonyConfig:
    steps: tuple[float, ...] = (1.0, 5.0, 10.0, 20.0)
    tolerance: float = 0.05
    pso: PsoSettings = PsoSettings(particles=100, iterations=10)
    light_sets: int | None = None
    exposures: tuple[int, ...] = (1, 2, 3, 4)
    exposure_span: float = 100.0                 # ND 2.0
    nd_transmittance: float = 0.01
    repeats: int = 6
    camera: CameraNoise = CameraNoise()

    @classmethod
    def tiny(cls) -> ParsimonyConfig:
        return cls(steps=(10.0, 20.0), pso=PsoSettings(particles=8, iterations=2), light_sets=8,
                   exposures=(1, 2), repeats=1)


def _choose(options: list, errors: list[float], tolerance: float) -> tuple[int, float]:
    """Index of the first (simplest) option within ``tolerance`` of the best error, and that best error."""
    best = float(min(errors))
    for i, e in enumerate(errors):
        if e <= best + tolerance:
            return i, best
    return int(np.argmin(errors)), best          # pragma: no cover (the best always qualifies)


def _at_step(spec: SetupSpec, step: float) -> SetupSpec:
    """The spec on a ``step`` grid (SpectralGrid stops at the last whole step: 410-780 nm at 20 nm ends at 770)."""
    return replace(spec, step=step)


def spectral_steps(spec: SetupSpec, cfg: ParsimonyConfig, cancel=None, progress=None) -> dict:
    ref_step = min(cfg.steps)
    ref_ev = evaluator_for(_at_step(spec, ref_step))
    groups = light_pairs()[:cfg.light_sets] if cfg.light_sets else light_pairs()
    rows = []
    ref_full = None
    for i, step in enumerate(sorted(cfg.steps)):
        check(cancel)
        ev = evaluator_for(_at_step(spec, step))
        t0 = time.perf_counter()
        ex = exhaustive(ev, groups)
        p = refine_top(ev, pso(ev, groups, cfg.pso, seed=0), 1)
        seconds = time.perf_counter() - t0
        row: dict[str, Any] = {"step_nm": step, "grid": ev.setup.grid.label(), "wavelengths": len(ev.setup.grid),
               "seconds": seconds}
        for key, cand in (("exhaustive", ex.best), ("pso", p.best)):
            W = cand.weights(ev.n_leds)
            own = ev.stats(W)
            on_ref = ref_ev.stats(W)
            row[key] = {"pair": [list(s.leds) for s in cand.sources],
                        "levels": [[round(v, 4) for v in s.levels] for s in cand.sources],
                        "own_train": own[0].mean, "own_test": own[1].mean,
                        "ref_train": on_ref[0].mean, "ref_test": on_ref[1].mean}
        costs = np.asarray([c.train_cost for c in sorted(ex.candidates, key=lambda c: tuple(
            tuple(s.leds) for s in c.sources))])
        if ref_full is None:
            ref_full = costs
        ra, rb = np.argsort(np.argsort(costs)), np.argsort(np.argsort(ref_full))
        row["full_intensity_vs_ref"] = {"max_abs_diff": float(np.abs(costs - ref_full).max()),
                                        "rank_correlation": float(np.corrcoef(ra, rb)[0, 1])}
        rows.append(row)
        report(progress, 0.3 * (i + 1) / len(cfg.steps), f"parsimony: {step:g} nm")
    ref = rows[0]
    for row in rows:
        dev = []
        for key in ("exhaustive", "pso"):
            dev.append(abs(row[key]["ref_train"] - ref[key]["ref_train"]))    # the choice, judged at 1 nm
            dev.append(abs(row[key]["own_train"] - row[key]["ref_train"]))    # the step's own estimate
        row["deviation"] = float(max(dev))
        row["acceptable"] = bool(row["deviation"] <= cfg.tolerance)
    ok = [r for r in rows if r["acceptable"]]
    chosen = max(ok, key=lambda r: r["step_nm"])["step_nm"] if ok else ref_step
    return {"reference_step_nm": ref_step, "rows": rows, "chosen_nm": chosen,
            "default_10nm_justified": any(r["step_nm"] == 10.0 and r["acceptable"] for r in rows)}


def _nd(n: int, transmittance: float) -> np.ndarray:
    """ND filter over the first half of the patches (thesis 8.3 covers half the chart)."""
    t = np.ones(n)
    t[: n // 2] = transmittance
    return t


def models_and_exposures(spec: SetupSpec, cfg: ParsimonyConfig, cancel=None, progress=None) -> tuple[dict, dict]:
    ev = evaluator_for(spec)
    groups = light_pairs()[:cfg.light_sets] if cfg.light_sets else light_pairs()
    ex = exhaustive(ev, groups)
    p = pso(ev, groups, cfg.pso, seed=0)
    lights = {"exhaustive": ex.best.weights(ev.n_leds), "pso": p.best.weights(ev.n_leds)}
    model = NoiseModel(ev.setup, cfg.camera)
    # --- models: single exposure, no ND
    mrows = {}
    for name, W in lights.items():
        check(cancel)
        cap = model.captured_errors(W, cfg.repeats, models=MODELS)
        mrows[name] = {"captured": cap["models"], "noise_free": _noise_free_models(ev, W)}
    report(progress, 0.6, "parsimony: characterisation models")
    worst = {m: max(mrows[n]["captured"][m]["test"] for n in lights) for m in MODELS}
    idx, best = _choose(list(MODELS), [worst[m] for m in MODELS], cfg.tolerance)
    models = {"light_sets": {k: [list(np.nonzero(w)[0] + 1) for w in W] for k, W in lights.items()},
              "terms": {m: MODEL_TERMS[m](6) for m in MODELS}, "results": mrows,
              "criterion": "captured test mean dE00 (worst over the light sets)", "scores": worst,
              "best": best, "chosen": MODELS[idx]}
    # --- exposures: ND 2.0 over half the patches, brackets of 1..4 exposures
    nd = {key: _nd(len(t), cfg.nd_transmittance) for key, t in (("train", ev.setup.train), ("test", ev.setup.test))}
    erows = []
    for k, n_exp in enumerate(cfg.exposures):
        check(cancel)
        factors = tuple(np.geomspace(1.0, cfg.exposure_span, n_exp)) if n_exp > 1 else (1.0,)
        row: dict[str, Any] = {"exposures": n_exp, "factors": [round(f, 3) for f in factors]}
        for name, W in lights.items():
            with_nd = model.captured_errors(W, cfg.repeats, factors=factors, nd=nd)
            without = model.captured_errors(W, max(1, cfg.repeats // 2), factors=factors)
            row[name] = {"nd_train": with_nd["train"], "nd_test": with_nd["test"], "nd_test_sd": with_nd["test_sd"],
                         "plain_train": without["train"], "plain_test": without["test"],
                         "exposure_s": (model.exposures(W) * max(factors)).tolist()}
        erows.append(row)
        report(progress, 0.6 + 0.4 * (k + 1) / len(cfg.exposures), f"parsimony: {n_exp} exposure(s)")
    scores = [max(r[n]["nd_test"] for n in lights) for r in erows]
    idx, best = _choose(erows, scores, cfg.tolerance)
    exposures = {"rows": erows, "scores": scores, "best": best, "chosen": erows[idx]["exposures"],
                 "hdr_merge": default_method(),      # the estimator the brackets were merged with (study hdr)
                 "criterion": "captured test mean dE00 with ND 2.0 over half the patches (worst over light sets)",
                 "nd_transmittance": cfg.nd_transmittance, "span": cfg.exposure_span}
    return models, exposures


def _noise_free_models(ev, W: np.ndarray) -> dict:
    from simulation.studies.models import fit_model, model_errors

    tr = ev.train.camera_values(W)
    te = ev.test.camera_values(W)
    out = {}
    for m in MODELS:
        fm = fit_model(m, tr, ev.train.xyz, ev.train.white)
        out[m] = {"train": float(model_errors(fm, tr, ev.train.xyz, ev.train.white).mean()),
                  "test": float(model_errors(fm, te, ev.test.xyz, ev.test.white).mean())}
    return out


@dataclass
class ParsimonyResult:
    spec: SetupSpec
    config: ParsimonyConfig
    steps: dict
    models: dict
    exposures: dict
    elapsed_s: float

    def defaults(self) -> dict:
        return {**output_header(FORMAT), "spectral_step_nm": self.steps["chosen_nm"],
                "characterisation_model": self.models["chosen"], "hdr_exposures": self.exposures["chosen"],
                "hdr_merge": self.exposures["hdr_merge"], "tolerance_de00": self.config.tolerance,
                "default_10nm_justified": self.steps["default_10nm_justified"],
                "evidence": {
                    "step_deviation": {f"{r['step_nm']:g}": round(r["deviation"], 4) for r in self.steps["rows"]},
                    "model_test_de00": {k: round(v, 4) for k, v in self.models["scores"].items()},
                    "exposures_test_de00": {str(r["exposures"]): round(s, 4) for r, s in
                                            zip(self.exposures["rows"], self.exposures["scores"], strict=True)}},
                "setup": self.spec.to_dict(), "camera": self.config.camera.to_dict(),
                "generated_by": "dualrgb study parsimony",
                "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}

    def to_json(self) -> dict:
        return {"setup": self.spec.to_dict(), "config": asdict(self.config), "elapsed_s": round(self.elapsed_s, 2),
                "spectral_step": self.steps, "characterisation_model": self.models, "hdr_exposures": self.exposures,
                "defaults": self.defaults()}


def parsimony(spec: SetupSpec = SetupSpec(), cfg: ParsimonyConfig = ParsimonyConfig(), *,
              progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> ParsimonyResult:
    if cfg.tolerance <= 0:
        raise ValueError(f"tolerance {cfg.tolerance}: expected a positive dE00")
    t0 = time.perf_counter()
    steps = spectral_steps(spec, cfg, cancel, progress)
    models, exposures = models_and_exposures(spec, cfg, cancel, progress)
    return ParsimonyResult(spec, cfg, steps, models, exposures, time.perf_counter() - t0)


# ---------------------------------------------------------------------------------------------------------
def parsimony_chart(result: ParsimonyResult):
    fig, (a1, a2, a3) = new_figure(14.0, 4.4, ncols=3)
    tol = result.config.tolerance
    rows = result.steps["rows"]
    steps = [r["step_nm"] for r in rows]
    for key, mk in (("exhaustive", "s"), ("pso", "o")):
        a1.plot(steps, [r[key]["ref_train"] for r in rows], mk + "-", label=f"{key} optimum, on 1 nm model")
        a1.plot(steps, [r[key]["own_train"] for r in rows], mk + ":", mfc="none", label=f"{key}, step's own estimate")
        ref = rows[0][key]["ref_train"]
        a1.axhspan(ref - tol, ref + tol, alpha=0.08, color="grey")
    a1.axvline(result.steps["chosen_nm"], color="tab:green", ls="--", label=f"chosen {result.steps['chosen_nm']:g} nm")
    a1.set_xlabel("spectral step, nm")
    a1.set_ylabel("training mean dE00")
    a1.set_title(f"(a) spectral step (band: ±{tol} of 1 nm)")
    a1.legend(fontsize=6)
    a1.grid(True, alpha=0.3)
    m = result.models
    x = np.arange(len(MODELS))
    for j, name in enumerate(m["results"]):
        r = m["results"][name]
        a2.bar(x + (j - 0.5) * 0.4, [r["captured"][k]["test"] for k in MODELS], 0.38, label=f"{name}: captured test")
        a2.plot(x + (j - 0.5) * 0.4, [r["noise_free"][k]["test"] for k in MODELS], "k_", ms=14,
                label="noise-free test" if j == 0 else None)
    a2.axhline(m["best"] + tol, color="grey", ls="--", label=f"best + {tol}")
    a2.set_xticks(x, [f"{k}\n({m['terms'][k]} terms)" for k in MODELS], fontsize=7)
    a2.set_ylabel("test mean dE00")
    a2.set_title(f"(b) characterisation model: chosen {m['chosen']}")
    a2.legend(fontsize=6)
    a2.grid(True, axis="y", alpha=0.3)
    e = result.exposures
    n = [r["exposures"] for r in e["rows"]]
    for name in ("exhaustive", "pso"):
        a3.plot(n, [r[name]["nd_test"] for r in e["rows"]], "o-", label=f"{name}: ND 2.0 on half")
        a3.plot(n, [r[name]["plain_test"] for r in e["rows"]], "o:", mfc="none", label=f"{name}: no ND")
    a3.axhline(e["best"] + tol, color="grey", ls="--", label=f"best + {tol}")
    a3.axvline(e["chosen"], color="tab:green", ls="--", label=f"chosen {e['chosen']}")
    a3.set_xticks(n)
    a3.set_xlabel("exposures per light (1x .. 100x)")
    a3.set_ylabel("captured test mean dE00")
    a3.set_title("(c) HDR exposures")
    a3.legend(fontsize=6)
    a3.grid(True, alpha=0.3)
    return fig


def write_outputs(result: ParsimonyResult, out: StudyOutput, defaults_path: str | None = None) -> None:
    out.write_json("parsimony_study.json", result.to_json())
    out.write_json("parsimony.json", result.defaults())
    if defaults_path:
        save_defaults(defaults_path, result.defaults())
    out.save_figure(parsimony_chart(result), "parsimony.png")
    s = result.steps
    lines = [f"Setup: {result.spec.label()}; tolerance {result.config.tolerance} mean dE00; total "
             f"{result.elapsed_s:.0f} s.", "", "## Spectral step", "",
             "| step nm | exhaustive pair | on 1 nm (train) | own estimate | PSO on 1 nm | own estimate | "
             "full-intensity max diff vs 1 nm | deviation | acceptable |",
             "|---:|---|---:|---:|---:|---:|---:|---:|---|"]
    for r in s["rows"]:
        lines.append(f"| {r['step_nm']:g} | {r['exhaustive']['pair']} | {r['exhaustive']['ref_train']:.4f} | "
                     f"{r['exhaustive']['own_train']:.4f} | {r['pso']['ref_train']:.4f} | "
                     f"{r['pso']['own_train']:.4f} | "
                     f"{r['full_intensity_vs_ref']['max_abs_diff']:.4f} | {r['deviation']:.4f} | {r['acceptable']} |")
    lines += ["", f"Chosen step: **{s['chosen_nm']:g} nm**; the 10 nm default is "
              f"{'justified' if s['default_10nm_justified'] else 'NOT justified'} at this tolerance.", "",
              "## Characterisation model (captured test mean dE00, worst over the light sets)", ""]
    m = result.models
    lines += [f"- {k} ({m['terms'][k]} terms): {m['scores'][k]:.4f}" for k in MODELS]
    lines += ["", f"Chosen: **{m['chosen']}**.", "", "## HDR exposures (ND 2.0 over half the patches)", ""]
    e = result.exposures
    lines += [f"- {r['exposures']} exposure(s) x{', '.join(f'{f:.3g}' for f in r['factors'])}: {sc:.4f}"
              for r, sc in zip(e["rows"], e["scores"], strict=True)]
    lines += ["", f"Chosen: **{e['chosen']}** exposure(s) per light.", "",
              "Defaults written to parsimony.json (`dualrgb study parsimony --write-defaults` makes them the "
              "app's defaults)."]
    out.write_summary("Parsimony", lines)
