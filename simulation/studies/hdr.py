"""Which HDR merge estimator (``dualrgb study hdr``): bias against signal level, and dE00 on dark originals.

Two experiments, each with every estimator of ``simulation.hdr_estimators.HDR_MERGE_METHODS`` (eq 8.9 of the
thesis and the variance-optimal weights of Granados et al. 2010), on the noise model of :mod:`.noise` (the
virtual lab's D610: Poisson electrons, read noise, 14-bit integers, master darks, linear limit):

1. Bias: pixels of known radiance from 0 to 10^5 DN/s, bracket ``bracket_s`` (default 0.01 s and 1 s: the
   parsimony study's two exposures spanning 100x, the longest 1 s so that DN/s = DN in the longest frame);
   mean relative error of the merge per level and per decade, and the mean merged value at zero radiance.
2. dE00 on dark originals, both bracketed 1x and 100x, fitted on the captured training target and judged on the
   captured test target (the characterisation of thesis 7, mean CIEDE2000), for the exhaustive and PSO optimum
   light sets: (a) a uniformly dark original whose darkest patch reaches only ``shadow_dn`` DN (brightest
   channel) in the longest exposure, judged after exposure normalisation; (b) the ND 2.0 chart (an ND 2.0
   filter over half the patches, thesis 8.3).

The default estimator is the one with the lower score (test dE00 averaged over the two originals, worst light
set); it goes to ``parsimony.json`` as ``hdr_merge`` (``--write-defaults``), which HdrMerge reads.
"""
from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import resources
from common.progress import CancelToken, ProgressCallback, check, report
from simulation.hdr_estimators import HDR_MERGE_METHODS, HDR_THESIS, HdrNoise, merge_exposures
from simulation.pso import PsoSettings, pso
from simulation.search import exhaustive, light_pairs
from simulation.studies.common import SetupSpec, StudyOutput, evaluator_for, new_figure
from simulation.studies.noise import CameraNoise, NoiseModel, capture_bracket

log = logging.getLogger(__name__)

DECADES = ((10.0, 100.0), (100.0, 1e3), (1e3, 1e4), (1e4, 1e5))


@dataclass(frozen=True)
class HdrStudyConfig:
    bracket_s: tuple[float, ...] = (0.01, 1.0)
    levels_per_decade: int = 8
    pixels: int = 100_000                    # per radiance level
    shadow_dn: float = 10.0                  # the dark original's darkest patch in the longest exposure
    nd_transmittance: float = 0.01
    repeats: int = 6
    pso: PsoSettings = PsoSettings(particles=100, iterations=10)
    light_sets: int | None = None
    camera: CameraNoise = CameraNoise()
    seed: int = 2012

    @classmethod
    def tiny(cls) -> HdrStudyConfig:
        return cls(levels_per_decade=2, pixels=4000, repeats=1, pso=PsoSettings(particles=8, iterations=2),
                   light_sets=8)

    @property
    def factors(self) -> tuple[float, ...]:
        t = np.asarray(self.bracket_s, dtype=float)
        return tuple(t / t.min())


def levels(cfg: HdrStudyConfig) -> np.ndarray:
    """Radiance levels (DN/s): 0 and log-spaced from 1 to 10^5."""
    return np.r_[0.0, np.logspace(0, 5, 5 * cfg.levels_per_decade + 1)]


def bias_by_level(cfg: HdrStudyConfig, cancel: CancelToken | None = None) -> dict:
    """Per estimator: mean merged radiance, relative bias and relative noise per level; bias per decade."""
    cam = cfg.camera
    L = levels(cfg)
    times = np.asarray(cfg.bracket_s, dtype=float)
    rng = np.random.default_rng(cfg.seed)
    noise = HdrNoise(cam.read_noise, cam.electrons_per_dn)
    sums = {m: np.zeros((3, len(L))) for m in HDR_MERGE_METHODS}
    chunk = max(1, min(cfg.pixels, 200_000 // len(L)))
    for lo in range(0, cfg.pixels, chunk):
        check(cancel)
        n = min(chunk, cfg.pixels - lo)
        x, usable = capture_bracket(cam, L[:, None], tuple(times), rng, (len(L), n))
        for m in HDR_MERGE_METHODS:
            e = merge_exposures(x, usable, times, m, span=cam.max_code - cam.black_level, noise=noise)[0]
            sums[m] += [e.sum(axis=1), (e * e).sum(axis=1), np.full(len(L), n)]
    out: dict[str, Any] = {"levels_dn_s": L.tolist(), "bracket_s": list(cfg.bracket_s), "pixels_per_level": cfg.pixels}
    for m, (s1, s2, count) in sums.items():
        mean = s1 / count
        sd = np.sqrt(np.maximum(s2 / count - mean * mean, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(L > 0, mean / L - 1.0, np.nan)
            rel_sd = np.where(L > 0, sd / L, np.nan)
        per_decade = {f"{a:g}-{b:g}": float(np.mean(rel[(L >= a) & (L < b)])) for a, b in DECADES
                      if np.any((L >= a) & (L < b))}
        out[m] = {"mean_dn_s": mean.tolist(), "relative_bias": rel.tolist(), "relative_noise": rel_sd.tolist(),
                  "bias_per_decade": per_decade, "zero_radiance_mean_dn_s": float(mean[0]),
                  "max_abs_bias_from_10": float(np.nanmax(np.abs(rel[L >= 10])))}
    return out


def dark_original_scale(model: NoiseModel, W: np.ndarray, cfg: HdrStudyConfig) -> float:
    """Transmittance that puts the darkest patch's brightest channel at ``shadow_dn`` in the longest exposure."""
    S = np.concatenate([model.signals(W[None], which)[0][0] for which in ("train", "test")])    # (n, L, 3)
    darkest = float(S.max(axis=2).min())
    return cfg.shadow_dn / (max(cfg.factors) * darkest)


def dark_originals(spec: SetupSpec, cfg: HdrStudyConfig, cancel=None, progress=None) -> dict:
    """Captured test (and train) mean dE00 per estimator, original and light set."""
    ev = evaluator_for(spec)
    groups = light_pairs()[:cfg.light_sets] if cfg.light_sets else light_pairs()
    lights = {"exhaustive": exhaustive(ev, groups).best.weights(ev.n_leds),
              "pso": pso(ev, groups, cfg.pso, seed=0).best.weights(ev.n_leds)}
    model = NoiseModel(ev.setup, cfg.camera)
    n_tr, n_te = len(ev.setup.train), len(ev.setup.test)
    half = {key: np.where(np.arange(n) < n // 2, cfg.nd_transmittance, 1.0) for key, n in (("train", n_tr),
                                                                                         ("test", n_te))}
    rows: dict = {}
    steps = len(HDR_MERGE_METHODS) * len(lights)
    for i, (m, (name, W)) in enumerate((m, item) for m in HDR_MERGE_METHODS for item in lights.items()):
        check(cancel)
        k = dark_original_scale(model, W, cfg)
        uniform = {"train": np.full(n_tr, k), "test": np.full(n_te, k)}
        dark = model.captured_errors(W, cfg.repeats, factors=cfg.factors, nd=uniform, hdr_method=m,
                                     nd_in_truth=False)
        nd = model.captured_errors(W, cfg.repeats, factors=cfg.factors, nd=half, hdr_method=m)
        rows.setdefault(m, {})[name] = {"dark_original": dark, "nd_chart": nd, "dark_transmittance": k}
        report(progress, 0.5 + 0.5 * (i + 1) / steps, f"HDR study: {m}, {name}")
    scores = {m: float(np.mean([max(r[n][scene]["test"] for n in lights) for scene in ("dark_original", "nd_chart")]))
              for m, r in rows.items()}
    chosen = min(scores, key=scores.__getitem__)
    return {"light_sets": {k: [list(np.nonzero(w)[0] + 1) for w in W] for k, W in lights.items()},
            "results": rows, "scores": scores, "chosen": chosen,
            "criterion": "captured test mean dE00, mean over the dark original and the ND 2.0 chart, worst light set"}


@dataclass
class HdrStudyResult:
    spec: SetupSpec
    config: HdrStudyConfig
    bias: dict
    originals: dict
    elapsed_s: float
    extra: dict = field(default_factory=dict)

    @property
    def chosen(self) -> str:
        return self.originals["chosen"]

    def to_json(self) -> dict:
        return {"setup": self.spec.to_dict(), "config": asdict(self.config), "elapsed_s": round(self.elapsed_s, 2),
                "bias": self.bias, "dark_originals": self.originals, "chosen": self.chosen}


def hdr_study(spec: SetupSpec = SetupSpec(), cfg: HdrStudyConfig = HdrStudyConfig(), *,
              progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> HdrStudyResult:
    t0 = time.perf_counter()
    bias = bias_by_level(cfg, cancel)
    report(progress, 0.5, "HDR study: bias against signal level")
    originals = dark_originals(spec, cfg, cancel, progress)
    return HdrStudyResult(spec, cfg, bias, originals, time.perf_counter() - t0)


def write_defaults(result: HdrStudyResult, path: str | None = None) -> Path:
    """Set ``hdr_merge`` (and its evidence) in the defaults file, keeping the parsimony study's keys."""
    from simulation.defaults import save_defaults

    return save_defaults(path or str(resources.path("parsimony.json")), {
        "hdr_merge": result.chosen,
        "evidence": {"hdr_merge_test_de00": {k: round(v, 4) for k, v in result.originals["scores"].items()}}})


# ---------------------------------------------------------------------------------------------------------
_LABELS = {HDR_THESIS: "eq 8.9 (thesis)", "variance": "variance-optimal (Granados 2010)"}


def hdr_chart(result: HdrStudyResult):
    fig, (a1, a2) = new_figure(12.0, 4.4, ncols=2)
    b = result.bias
    L = np.asarray(b["levels_dn_s"])
    pos = L > 0
    for m in HDR_MERGE_METHODS:
        a1.plot(L[pos], 100 * np.asarray(b[m]["relative_bias"])[pos], "o-", ms=3, label=_LABELS.get(m, m))
    a1.axhspan(-0.3, 0.3, color="tab:green", alpha=0.15, label="±0.3 %")
    a1.set_xscale("log")
    a1.set_yscale("symlog", linthresh=0.3)
    a1.set_xlabel("radiance, DN/s (= DN in the longest exposure)")
    a1.set_ylabel("mean relative bias of the merge, %")
    a1.set_title(f"(a) bias, bracket {' + '.join(f'{t:g} s' for t in b['bracket_s'])}")
    a1.legend(fontsize=7)
    a1.grid(True, which="both", alpha=0.3)
    o = result.originals
    names = list(o["light_sets"])
    scenes = (("dark_original", f"dark original\n({result.config.shadow_dn:g} DN shadows)"),
              ("nd_chart", "ND 2.0 over\nhalf the chart"))
    x = np.arange(len(scenes) * len(names))
    width = 0.8 / len(HDR_MERGE_METHODS)
    for j, m in enumerate(HDR_MERGE_METHODS):
        vals = [o["results"][m][n][s]["test"] for s, _ in scenes for n in names]
        a2.bar(x + (j - (len(HDR_MERGE_METHODS) - 1) / 2) * width, vals, width * 0.95, label=_LABELS.get(m, m))
    a2.set_xticks(x, [f"{lab}\n{n} lights" for _, lab in scenes for n in names], fontsize=7)
    a2.set_ylabel("captured test mean dE00")
    a2.set_title(f"(b) dark originals: chosen {_LABELS.get(o['chosen'], o['chosen'])}")
    a2.legend(fontsize=7)
    a2.grid(True, axis="y", alpha=0.3)
    return fig


def write_outputs(result: HdrStudyResult, out: StudyOutput) -> None:
    out.write_json("hdr_study.json", result.to_json())
    out.save_figure(hdr_chart(result), "hdr.png")
    b = result.bias
    lines = [f"Setup: {result.spec.label()}; bracket {b['bracket_s']} s; {b['pixels_per_level']} pixels per "
             f"level; total {result.elapsed_s:.0f} s.", "", "## Bias against signal (mean relative error)", "",
             "| estimator | " + " | ".join(f"{d} DN/s" for d in b[HDR_THESIS]["bias_per_decade"])
             + " | zero radiance (DN/s) |", "|---|" + "---:|" * (len(b[HDR_THESIS]["bias_per_decade"]) + 1)]
    for m in HDR_MERGE_METHODS:
        r = b[m]
        lines.append(f"| {m} | " + " | ".join(f"{100 * v:+.3f} %" for v in r["bias_per_decade"].values())
                     + f" | {r['zero_radiance_mean_dn_s']:+.2f} |")
    o = result.originals
    lines += ["", "## Dark originals (captured test mean dE00)", "", "| estimator | light set | dark original | "
              "ND 2.0 chart |", "|---|---|---:|---:|"]
    for m, r in o["results"].items():
        for n, v in r.items():
            lines.append(f"| {m} | {n} | {v['dark_original']['test']:.4f} | {v['nd_chart']['test']:.4f} |")
    lines += ["", f"Scores ({o['criterion']}): " + ", ".join(f"{k} {v:.4f}" for k, v in o["scores"].items()),
              "", f"Chosen default: **{o['chosen']}**."]
    out.write_summary("HDR merge estimator", lines)
