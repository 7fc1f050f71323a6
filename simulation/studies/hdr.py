"""Which HDR merge estimator (``dualrgb study hdr``): bias against signal level, and dE00 on dark originals,
per target mode.

Two experiments, each with every estimator of ``simulation.hdr_estimators.HDR_MERGE_METHODS`` (eq 8.9 of the
thesis and the variance-optimal weights of Granados et al. 2010), on the noise model of :mod:`.noise` (the
virtual lab's D610: Poisson electrons, read noise, 14-bit integers, master darks, linear limit):

1. Bias (mode-independent: pixels, no spectra): pixels of known radiance from 0 to 10^5 DN/s, bracket
   ``bracket_s`` (default 0.01 s and 1 s: the parsimony study's two exposures spanning 100x, the longest 1 s so
   that DN/s = DN in the longest frame); mean relative error of the merge per level and per decade, each with its
   standard error (Monte Carlo over ``pixels`` pixels per level: a bias smaller than about twice its standard
   error is not resolved), and the mean merged value at zero radiance.
2. dE00 on dark originals, per mode, both bracketed 1x and 100x, under the mode's light sets (:mod:`.lights`:
   the packaged exhaustive and PSO presets):
   (a) a uniformly dark original whose darkest patch reaches only ``shadow_dn`` DN (brightest channel) in the
   longest exposure, judged after exposure normalisation; (b) the ND 2.0 chart (an ND 2.0 filter over half the
   patches, thesis 8.3). The characterisation (thesis 7) is fitted on the captured training target; the score is
   its 5-fold cross-validated mean CIEDE2000 on the captured *training* target (simulation.cross_validation);
   the test target is reported beside it, never used to choose.

Each mode's default is the estimator with the lower score (training CV averaged over the two originals, worst
light set); it goes to that mode's entry of ``parsimony.json`` as ``hdr_merge`` (``--write-defaults``), which
HdrMerge reads for the mode it processes.
"""
from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb import resources
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.hdr_estimators import HDR_MERGE_METHODS, HDR_THESIS, HdrNoise, merge_exposures
from dualrgb.simulation.pso import PsoSettings
from dualrgb.simulation.studies.common import SetupSpec, StudyOutput, evaluator_for, new_figure
from dualrgb.simulation.studies.lights import study_lights
from dualrgb.simulation.studies.noise import CameraNoise, NoiseModel, capture_bracket

log = logging.getLogger(__name__)

DECADES = ((10.0, 100.0), (100.0, 1e3), (1e3, 1e4), (1e4, 1e5))


@dataclass(frozen=True)
class HdrStudyConfig:
    bracket_s: tuple[float, ...] = (0.01, 1.0)
    levels_per_decade: int = 8
    pixels: int = 1_000_000                  # per radiance level: standard error of the bias ~0.03 % at 10 DN/s
    shadow_dn: float = 10.0                  # the dark original's darkest patch in the longest exposure
    nd_transmittance: float = 0.01
    repeats: int = 6
    folds: int = 5
    pso: PsoSettings = PsoSettings(particles=100, iterations=10)
    light_sets: int | None = None
    camera: CameraNoise = CameraNoise()
    seed: int = 2012

    @classmethod
    def tiny(cls) -> HdrStudyConfig:
        return cls(levels_per_decade=2, pixels=4000, repeats=2, pso=PsoSettings(particles=8, iterations=2),
                   light_sets=8)

    @property
    def factors(self) -> tuple[float, ...]:
        t = np.asarray(self.bracket_s, dtype=float)
        return tuple(t / t.min())


def levels(cfg: HdrStudyConfig) -> np.ndarray:
    """Radiance levels (DN/s): 0 and log-spaced from 1 to 10^5."""
    return np.r_[0.0, np.logspace(0, 5, 5 * cfg.levels_per_decade + 1)]


def _bias_sums(cfg: HdrStudyConfig, L: np.ndarray, cancel: CancelToken | None) -> dict[str, np.ndarray]:
    """Per estimator: (sum, sum of squares, count) of the merged radiance per level, over ``cfg.pixels``."""
    cam = cfg.camera
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
    return sums


def bias_by_level(cfg: HdrStudyConfig, cancel: CancelToken | None = None) -> dict:
    """Per estimator: mean merged radiance, relative bias with its standard error and relative noise per level;
    bias per decade (mean over its levels, standard error of that mean)."""
    L = levels(cfg)
    out: dict[str, Any] = {"levels_dn_s": L.tolist(), "bracket_s": list(cfg.bracket_s),
                           "pixels_per_level": cfg.pixels, "methods": list(HDR_MERGE_METHODS)}
    for m, (s1, s2, count) in _bias_sums(cfg, L, cancel).items():
        mean = s1 / count
        sd = np.sqrt(np.maximum(s2 / count - mean * mean, 0.0) * count / np.maximum(count - 1, 1))
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(L > 0, mean / L - 1.0, np.nan)
            rel_sd = np.where(L > 0, sd / L, np.nan)
        rel_se = rel_sd / np.sqrt(count)
        per_decade = {}
        for a, b in DECADES:
            inside = (L >= a) & (L < b)
            if np.any(inside):
                per_decade[f"{a:g}-{b:g}"] = {"mean": float(np.mean(rel[inside])),
                                              "se": float(np.sqrt(np.sum(rel_se[inside] ** 2)) / inside.sum())}
        from10 = L >= 10
        out[m] = {"mean_dn_s": mean.tolist(), "relative_bias": rel.tolist(), "relative_bias_se": rel_se.tolist(),
                  "relative_noise": rel_sd.tolist(), "bias_per_decade": per_decade,
                  "zero_radiance_mean_dn_s": float(mean[0]), "zero_radiance_se_dn_s": float(sd[0] / np.sqrt(count[0])),
                  "max_abs_bias_from_10": float(np.nanmax(np.abs(rel[from10]))),
                  "max_abs_z_from_10": float(np.nanmax(np.abs(rel[from10] / rel_se[from10])))}
    return out


def dark_original_scale(model: NoiseModel, W: np.ndarray, cfg: HdrStudyConfig) -> float:
    """Transmittance that puts the darkest patch's brightest channel at ``shadow_dn`` in the longest exposure."""
    S = np.concatenate([model.signals(W[None], which)[0][0] for which in ("train", "test")])    # (n, L, 3)
    darkest = float(S.max(axis=2).min())
    return cfg.shadow_dn / (max(cfg.factors) * darkest)


def dark_originals(spec: SetupSpec, cfg: HdrStudyConfig, cancel=None, progress=None) -> dict:
    """Captured training CV (criterion), training and test (reported) mean dE00 per estimator, original and
    light set, for ``spec.mode``."""
    ev = evaluator_for(spec)
    lights, origin = study_lights(spec, cfg.pso, cfg.light_sets)
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
                                     nd_in_truth=False, folds=cfg.folds)
        nd = model.captured_errors(W, cfg.repeats, factors=cfg.factors, nd=half, hdr_method=m, folds=cfg.folds)
        rows.setdefault(m, {})[name] = {"dark_original": dark, "nd_chart": nd, "dark_transmittance": k}
        report(progress, 0.5 + 0.5 * (i + 1) / steps, f"HDR study ({spec.mode}): {m}, {name}")
    scenes = ("dark_original", "nd_chart")

    def score(m: str, key: str) -> float:
        return float(np.mean([max(rows[m][n][scene][key] for n in lights) for scene in scenes]))

    scores = {m: score(m, "train_cv") for m in rows}
    return {"mode": spec.mode, "light_sets_from": origin,
            "light_sets": {k: [[int(i) + 1 for i in np.nonzero(w)[0]] for w in W] for k, W in lights.items()},
            "results": rows, "scores": scores, "test_reported": {m: score(m, "test") for m in rows},
            "chosen": min(scores, key=scores.__getitem__),
            "criterion": f"captured training mean dE00, {cfg.folds}-fold cross-validation, mean over the dark "
                         "original and the ND 2.0 chart, worst light set; the test target is reported only"}


@dataclass
class HdrStudyResult:
    specs: list[SetupSpec]
    config: HdrStudyConfig
    bias: dict
    originals: dict                          # mode -> dark_originals(...)
    elapsed_s: float
    extra: dict = field(default_factory=dict)

    def chosen(self, mode: str) -> str:
        return self.originals[mode]["chosen"]

    def to_json(self) -> dict:
        return {"setups": [s.to_dict() for s in self.specs], "config": asdict(self.config),
                "elapsed_s": round(self.elapsed_s, 2), "bias": self.bias, "dark_originals": self.originals,
                "chosen": {mode: o["chosen"] for mode, o in self.originals.items()}}


def hdr_study(specs: SetupSpec | list[SetupSpec] = SetupSpec(), cfg: HdrStudyConfig = HdrStudyConfig(), *,
              progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> HdrStudyResult:
    """The bias experiment once, the dark originals (and the choice) for each spec's mode."""
    specs = [specs] if isinstance(specs, SetupSpec) else list(specs)
    t0 = time.perf_counter()
    bias = bias_by_level(cfg, cancel)
    report(progress, 0.5, "HDR study: bias against signal level")
    originals = {spec.mode: dark_originals(spec, cfg, cancel, progress) for spec in specs}
    return HdrStudyResult(specs, cfg, bias, originals, time.perf_counter() - t0)


def write_defaults(result: HdrStudyResult, path: str | None = None) -> Path:
    """Set each studied mode's ``hdr_merge`` (with its criterion and evidence) in the defaults file, keeping the
    parsimony study's keys and the other mode."""
    from dualrgb.simulation.defaults import save_defaults

    target = path or str(resources.path("parsimony.json"))
    for mode, o in result.originals.items():
        save_defaults(target, mode, {
            "hdr_merge": o["chosen"], "criteria": {"hdr_merge": o["criterion"]},
            "evidence": {"hdr_merge_cv_de00": {k: round(v, 4) for k, v in o["scores"].items()},
                         "hdr_merge_test_de00_reported": {k: round(v, 4) for k, v in o["test_reported"].items()}}})
    return Path(target)


# ---------------------------------------------------------------------------------------------------------
_LABELS = {HDR_THESIS: "eq 8.9 (thesis)", "variance": "variance-optimal (Granados 2010)"}


def _bias_panels(a1, a2, b: dict) -> None:
    L = np.asarray(b["levels_dn_s"])
    pos = L > 0
    for m in HDR_MERGE_METHODS:
        a1.plot(L[pos], 100 * np.asarray(b[m]["relative_bias"])[pos], "o-", ms=3, label=_LABELS.get(m, m))
    a1.axhspan(-0.3, 0.3, color="tab:green", alpha=0.15, label="±0.3 %")
    a1.set_xscale("log")
    a1.set_yscale("symlog", linthresh=0.3)
    a1.set_xlabel("radiance, DN/s (= DN in the longest exposure)")
    a1.set_ylabel("mean relative bias of the merge, %")
    a1.set_title(f"(a) bias, bracket {' + '.join(f'{t:g} s' for t in b['bracket_s'])}", fontsize=9)
    a1.legend(fontsize=7)
    a1.grid(True, which="both", alpha=0.3)
    for m in HDR_MERGE_METHODS:
        rel, se = (100 * np.asarray(b[m][k])[pos] for k in ("relative_bias", "relative_bias_se"))
        if np.nanmax(np.abs(rel[L[pos] >= 10])) < 1.0:             # the unbiased estimators, zoomed
            a2.errorbar(L[pos], rel, yerr=2 * se, fmt="o", ms=3, capsize=2, label=f"{_LABELS.get(m, m)} ± 2 SE")
    a2.axhline(0.0, color="k", lw=0.8)
    a2.set_xscale("log")
    a2.set_ylim(-0.5, 0.5)
    a2.set_xlabel("radiance, DN/s")
    a2.set_ylabel("relative bias, %")
    a2.set_title(f"(b) zoom: bias ± 2 standard errors ({b['pixels_per_level']:.0e} pixels per level)", fontsize=9)
    a2.legend(fontsize=7)
    a2.grid(True, which="both", alpha=0.3)


def _originals_panel(ax, o: dict, shadow_dn: float) -> None:
    names = list(o["light_sets"])
    scenes = (("dark_original", f"dark original\n({shadow_dn:g} DN shadows)"), ("nd_chart", "ND 2.0 over\nhalf"))
    x = np.arange(len(scenes) * len(names))
    width = 0.8 / len(HDR_MERGE_METHODS)
    for j, m in enumerate(HDR_MERGE_METHODS):
        off = (j - (len(HDR_MERGE_METHODS) - 1) / 2) * width
        cells = [o["results"][m][n][s] for s, _ in scenes for n in names]
        ax.bar(x + off, [c["train_cv"] for c in cells], width * 0.95, yerr=[c["train_cv_se"] for c in cells],
               capsize=2, label=f"{_LABELS.get(m, m)}: training CV (criterion)")
        ax.plot(x + off, [c["test"] for c in cells], "kx", label="test (reported only)" if j == 0 else None)
    ax.set_xticks(x, [f"{lab}\n{n} lights" for _, lab in scenes for n in names], fontsize=6)
    ax.set_ylabel("captured mean dE00")
    ax.set_title(f"({o['mode']}) dark originals: chosen {_LABELS.get(o['chosen'], o['chosen'])}", fontsize=9)
    ax.legend(fontsize=6)
    ax.grid(True, axis="y", alpha=0.3)


def hdr_chart(result: HdrStudyResult):
    axes = new_figure(6.0 * (2 + len(result.originals)), 4.4, ncols=2 + len(result.originals))[1]
    _bias_panels(axes[0], axes[1], result.bias)
    for ax, o in zip(axes[2:], result.originals.values(), strict=True):
        _originals_panel(ax, o, result.config.shadow_dn)
    return axes[0].figure


def pm(mean: float, se: float, unit: str = "") -> str:
    """'mean ± se' with the digits the standard error supports (two significant digits of it, at least 3
    decimals), e.g. '+0.013 ± 0.0060 %'."""
    decimals = 3 if not se > 0 else max(3, int(-np.floor(np.log10(se))) + 1)
    return f"{mean:+.{decimals}f} ± {se:.{decimals}f}{unit}"


def _bias_lines(b: dict) -> list[str]:
    decades = list(b[HDR_THESIS]["bias_per_decade"])
    lines = ["| estimator | " + " | ".join(f"{d} DN/s" for d in decades) + " | zero radiance (DN/s) |",
             "|---|" + "---:|" * (len(decades) + 1)]
    for m in HDR_MERGE_METHODS:
        r = b[m]
        lines.append(f"| {m} | " + " | ".join(pm(100 * v["mean"], 100 * v["se"], " %")
                                              for v in r["bias_per_decade"].values())
                     + f" | {pm(r['zero_radiance_mean_dn_s'], r['zero_radiance_se_dn_s'])} |")
    L = np.asarray(b["levels_dn_s"])
    lines += ["", "Per level (relative bias ± standard error, %):", "", "| DN/s | "
              + " | ".join(HDR_MERGE_METHODS) + " |", "|---:|" + "---:|" * len(HDR_MERGE_METHODS)]
    for i in np.flatnonzero(L >= 10):
        lines.append(f"| {L[i]:.4g} | " + " | ".join(pm(100 * b[m]["relative_bias"][i],
                                                        100 * b[m]["relative_bias_se"][i])
                                                     for m in HDR_MERGE_METHODS) + " |")
    return lines


def write_outputs(result: HdrStudyResult, out: StudyOutput) -> None:
    out.write_json("hdr_study.json", result.to_json())
    out.save_figure(hdr_chart(result), "hdr.png")
    b = result.bias
    lines = [f"Setups: {', '.join(s.label() for s in result.specs)}; bracket {b['bracket_s']} s; "
             f"{b['pixels_per_level']} pixels per level; total {result.elapsed_s:.0f} s.", "",
             "## Bias against signal (mean relative error ± standard error of the Monte Carlo)", "",
             *_bias_lines(b)]
    for mode, o in result.originals.items():
        lines += ["", f"## Dark originals, {mode} (captured mean dE00: training 5-fold CV = criterion; test reported)",
                  "", "| estimator | light set | dark original CV | test | ND 2.0 chart CV | test |",
                  "|---|---|---:|---:|---:|---:|"]
        for m, r in o["results"].items():
            for n, v in r.items():
                d, c = v["dark_original"], v["nd_chart"]
                lines.append(f"| {m} | {n} | {d['train_cv']:.4f} ± {d['train_cv_se']:.4f} | {d['test']:.4f} | "
                             f"{c['train_cv']:.4f} ± {c['train_cv_se']:.4f} | {c['test']:.4f} |")
        lines += ["", f"Scores ({o['criterion']}): " + ", ".join(f"{k} {v:.4f}" for k, v in o["scores"].items()),
                  "", f"Chosen default for {mode}: **{o['chosen']}**."]
    out.write_summary("HDR merge estimator", lines)
