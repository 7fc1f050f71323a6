"""Accuracy report of a characterised capture: JSON + PNG figures (matplotlib, Agg canvas, no pyplot state).

Contents (thesis Table 7.2, Figs 7.4-7.11):
  * mean / median / p90 / max CIEDE2000 on the training and test targets for every fitted matrix
    (``simulation.objective.ErrorStats``), which one is delivered (chosen by cross-validation on the training
    target, never by the test target) and the delivered one's test error;
  * per-patch dE00 heatmap in the target's layout; a*b* and L*C* scatter coloured by error; ground truth vs
    prediction patch mosaic (sRGB, left half ground truth, right half prediction);
  * simulated vs captured digital numbers per channel (Fig 7.4): a least-squares line per channel, R^2 with
    and without outliers (Fig 7.5); outliers are points whose standardized residual from the line fitted to
    the remaining points exceeds 4 (noise scale allowed to grow with the signal; see fit_line_with_outliers);
  * pass/fail against published colour-accuracy levels of FADGI, ISO 19264-1 and Metamorfoze (test target),
    labelled "colour accuracy only";
  * the quality metrics of app.processing.quality (dL*/dC*/dH*, tone response, white balance, noise,
    illuminance non-uniformity, sensor noise) graded per metric against FADGI 4-star / ISO 19264-1 A /
    Metamorfoze Full, "not assessed" where a criterion is not measured (SFR...), with their figures;
  * when the targets' spectra are known, the spectral estimate (app.processing.spectral): the method chosen by
    cross-validation on the training target, spectral RMSE, GFC and CIEDE2000 under D65, A, D50, FL11 and a
    warm-white LED on both targets, and estimated against reference spectra of a few test patches.

Published limits used (colour accuracy, CIEDE2000 of a reference target):
  FADGI 2023 (Technical Guidelines for Digitizing Cultural Heritage Materials, 3rd ed.), per star level:
      mean dE00 < 2 / 3.5 / 5 / 6.5 and 90th percentile < 4 / 7 / 10 / 13 for 4 / 3 / 2 / 1 stars.
  ISO 19264-1:2021, levels A / B / C: mean dE00 <= 4 / 5 / 5, max dE00 <= 10 / 15 / 15.
  Metamorfoze Preservation Imaging Guidelines 2.0 (draft 2023): Full mean <= 3, max <= 7; Light mean <= 4,
      max <= 14 (Extra Light sets no colour-accuracy limit).
  Sources: comparison table of the three guidelines, https://skandalski.pl/tabela-fadgi-iso-metamorfoze/
  (ISO 19264-1:2021 / FADGI 2023 / Metamorfoze 2.0 draft columns); Metamorfoze 2.0 tolerances as announced at
  https://preservationimaging.com/version-2/ . Caveats: the guidelines evaluate a full imaging chain on their
  own targets (ColorChecker SG, ISO 19264 target) under D50, and Metamorfoze 2.0 uses CIEDE2000 with S_L = 1;
  here the thesis metric (standard CIEDE2000, D65) on the characterisation's test target is graded, so the
  verdict is indicative. (An older FADGI edition, 2016, allowed mean dE00 <= 4 at 3 stars; 2023 is used.)
"""
from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dualrgb.app.processing.characterise import Characterisation
from dualrgb.app.processing.figure_files import (
    FigureJob,
    FigureProgress,
    draw_figures,
    new_figure,
    save_figure,
    save_tight,
)
from dualrgb.common.atomic_files import atomic_write
from dualrgb.common.progress import CancelToken
from dualrgb.common.strict_json import dumps as strict_dumps
from dualrgb.common.strict_json import finite_or_none
from dualrgb.simulation.colorimetry import xyz_to_lab
from dualrgb.simulation.objective import ErrorStats
from dualrgb.simulation.versions import output_header

if TYPE_CHECKING:                                   # pragma: no cover
    from dualrgb.app.processing.patches import PatchGrid
    from dualrgb.app.processing.quality import CalibrationFrames
    from dualrgb.app.processing.spectral import SpectralCharacterisation

log = logging.getLogger(__name__)

REPORT_FORMAT = "dualrgb-report/1"
TARGET_WORDS = {"train": "training target", "test": "test target"}     # the figures' progress lines


# ---------------------------------------------------------------- standards
@dataclass(frozen=True)
class Level:
    name: str
    mean: float
    p90: float | None = None
    max: float | None = None
    strict: bool = False            # FADGI writes "<", ISO and Metamorfoze "<="

    def passes(self, s: ErrorStats) -> dict:
        def ok(value: float, limit: float | None) -> bool | None:
            if limit is None:
                return None
            return bool(value < limit) if self.strict else bool(value <= limit)
        checks = {"mean": ok(s.mean, self.mean), "p90": ok(s.p90, self.p90), "max": ok(s.max, self.max)}
        checks = {k: v for k, v in checks.items() if v is not None}
        limits = {k: getattr(self, k) for k in checks}
        return {"pass": all(checks.values()), "checks": checks, "limits": limits,
                "comparison": "<" if self.strict else "<="}


STANDARDS: dict[str, list[Level]] = {
    # best level first
    "FADGI 2023": [Level("4-star", 2.0, p90=4.0, strict=True), Level("3-star", 3.5, p90=7.0, strict=True),
                   Level("2-star", 5.0, p90=10.0, strict=True), Level("1-star", 6.5, p90=13.0, strict=True)],
    "ISO 19264-1:2021": [Level("A", 4.0, max=10.0), Level("B", 5.0, max=15.0), Level("C", 5.0, max=15.0)],
    "Metamorfoze 2.0": [Level("Full", 3.0, max=7.0), Level("Light", 4.0, max=14.0)],
}


def grade(stats: ErrorStats) -> dict:
    """{standard: {"level": best level passed or None, "levels": {name: {...pass, checks, limits}}}}."""
    out = {}
    for std, levels in STANDARDS.items():
        res = {lv.name: lv.passes(stats) for lv in levels}
        best = next((lv.name for lv in levels if res[lv.name]["pass"]), None)
        out[std] = {"level": best, "levels": res}
    return out


# ---------------------------------------------------------------- Fig 7.4 validation
@dataclass
class ChannelFit:
    channel: str
    slope: float
    intercept: float
    r2: float                       # all points
    r2_clean: float                 # outliers removed (Fig 7.5)
    outliers: list[int] = field(default_factory=list)
    z: list[float] = field(default_factory=list)

    def to_dict(self, names: Sequence[str] = ()) -> dict:
        d = {"channel": self.channel, "slope": self.slope, "intercept": self.intercept,
             "r2": finite_or_none(self.r2), "r2_without_outliers": finite_or_none(self.r2_clean),
             "outliers": self.outliers}           # R² of a constant channel is undefined: null
        if names:
            d["outlier_patches"] = [names[i] for i in self.outliers]
        return d


def _r2(x: np.ndarray, y: np.ndarray, slope: float, intercept: float) -> float:
    ss_res = float(np.sum((y - (slope * x + intercept)) ** 2))
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    return 1.0 - ss_res / ss_tot if ss_tot > 0 else float("nan")


def fit_line_with_outliers(x: np.ndarray, y: np.ndarray, z_threshold: float = 4.0, max_iter: int = 10
                           ) -> tuple[float, float, np.ndarray, np.ndarray]:
    """Least-squares line y = a x + b fitted to the inliers; outliers = points whose standardized residual
    exceeds ``z_threshold`` (iterated until the set is stable). Returns (a, b, outlier mask, z).

    The residual scale may grow with the signal: capture errors have a constant part (read noise) and a
    proportional part (gain, spectral-measurement error). It is modelled as sigma_i = 1.2533 (alpha + beta
    fit_i), alpha and beta >= 0 fitted by least squares to the inliers' |residuals| (1.2533 = sqrt(pi / 2) turns
    a mean absolute deviation into a standard deviation). A single residual / RMS would flag the brightest
    good patches under proportional errors, or miss bad dark ones under constant noise.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    out = np.zeros(len(x), dtype=bool)
    a = b = 0.0
    z = np.zeros(len(x))
    for _ in range(max_iter):
        keep = ~out
        if keep.sum() < 4:
            break
        a, b = np.polyfit(x[keep], y[keep], 1)
        fit = a * x + b
        r = y - fit
        G = np.c_[np.ones(int(keep.sum())), np.abs(fit[keep])]
        coef, *_ = np.linalg.lstsq(G, np.abs(r[keep]), rcond=None)
        alpha, beta = (max(float(v), 0.0) for v in coef)
        if alpha == 0.0 and beta == 0.0:
            alpha = float(np.mean(np.abs(r[keep])))
        scale = 1.2533 * (alpha + beta * np.abs(fit))
        scale = np.maximum(scale, 1e-9 * (float(np.max(np.abs(fit))) or 1.0))
        z = r / scale
        new = np.abs(z) > z_threshold
        if np.array_equal(new, out):
            break
        out = new
    return float(a), float(b), out, z


def dn_validation(simulated: np.ndarray, captured: np.ndarray, channels: Sequence[str],
                  z_threshold: float = 4.0) -> list[ChannelFit]:
    """Thesis Fig 7.4: per channel, captured vs simulated patch values, line fit, R^2, outliers."""
    simulated = np.asarray(simulated, dtype=float)
    captured = np.asarray(captured, dtype=float)
    if simulated.shape != captured.shape:
        raise ValueError(f"simulated {simulated.shape} and captured {captured.shape} patch values differ in shape")
    fits = []
    for j, ch in enumerate(channels):
        x, y = simulated[:, j], captured[:, j]
        ok = np.isfinite(x) & np.isfinite(y)
        a, b, out, z = fit_line_with_outliers(x[ok], y[ok], z_threshold)
        idx = np.flatnonzero(ok)
        a_all, b_all = np.polyfit(x[ok], y[ok], 1)
        fits.append(ChannelFit(ch, a, b, _r2(x[ok], y[ok], a_all, b_all), _r2(x[ok][~out], y[ok][~out], a, b),
                               [int(i) for i in idx[out]], [float(v) for v in z]))
    return fits


# ---------------------------------------------------------------- figures
def layout_for(n: int, layout: tuple[int, int] | None = None) -> tuple[int, int]:
    if layout and layout[0] * layout[1] >= n:
        return int(layout[0]), int(layout[1])
    cols = int(math.ceil(math.sqrt(n * 1.5)))
    return int(math.ceil(n / cols)), cols


def xyz_to_srgb8(xyz: np.ndarray, white: np.ndarray) -> np.ndarray:
    import colour

    from dualrgb.app.processing.outputs import xyz_to_rgb_matrix

    M = xyz_to_rgb_matrix("sRGB", white) / float(white[1])
    lin = np.clip(np.asarray(xyz, float) @ M.T, 0, 1)
    return np.asarray(colour.RGB_COLOURSPACES["sRGB"].cctf_encoding(lin))


def heatmap_figure(path: Path, errors: np.ndarray, layout: tuple[int, int], title: str) -> Path:
    rows, cols = layout
    grid = np.full(rows * cols, np.nan)
    grid[: len(errors)] = errors
    fig = new_figure(max(4.0, cols * 0.55 + 1.5), max(2.5, rows * 0.5 + 1.0))
    ax = fig.add_subplot(111)
    im = ax.imshow(grid.reshape(rows, cols), cmap="viridis", vmin=0)
    if len(errors) <= 60:
        for k, e in enumerate(errors):
            r, c = divmod(k, cols)
            ax.text(c, r, f"{e:.1f}", ha="center", va="center", fontsize=7,
                    color="white" if e < 0.6 * np.nanmax(errors) else "black")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title)
    fig.colorbar(im, ax=ax, label="ΔE00")
    return save_tight(fig, path)


def lab_scatter_figure(path: Path, xyz_ref: np.ndarray, errors: np.ndarray, white: np.ndarray, title: str) -> Path:
    lab = xyz_to_lab(xyz_ref, white)
    chroma = np.hypot(lab[:, 1], lab[:, 2])
    fig = new_figure(9, 4)
    ax1, ax2 = fig.add_subplot(121), fig.add_subplot(122)
    sc = ax1.scatter(lab[:, 1], lab[:, 2], c=errors, cmap="plasma", s=22, vmin=0)
    ax1.axhline(0, color="0.8", lw=0.5)
    ax1.axvline(0, color="0.8", lw=0.5)
    ax1.set_xlabel("a*")
    ax1.set_ylabel("b*")
    ax1.set_title(f"{title}: a* vs b*")
    ax2.scatter(chroma, lab[:, 0], c=errors, cmap="plasma", s=22, vmin=0)
    ax2.set_xlabel("C*")
    ax2.set_ylabel("L*")
    ax2.set_title(f"{title}: L* vs C*")
    fig.colorbar(sc, ax=[ax1, ax2], label="ΔE00")
    return save_figure(fig, path)


def patch_mosaic_figure(path: Path, xyz_ref: np.ndarray, xyz_pred: np.ndarray, white: np.ndarray,
                        layout: tuple[int, int], title: str) -> Path:
    rows, cols = layout
    gt = xyz_to_srgb8(xyz_ref, white)
    pr = xyz_to_srgb8(xyz_pred, white)
    cell = 20
    img = np.ones((rows * cell, cols * cell, 3))
    for k in range(len(gt)):
        r, c = divmod(k, cols)
        y, x = r * cell, c * cell
        img[y + 1: y + cell - 1, x + 1: x + cell // 2] = gt[k]
        img[y + 1: y + cell - 1, x + cell // 2: x + cell - 1] = pr[k]
    fig = new_figure(max(4.0, cols * 0.5 + 1), max(2.5, rows * 0.5 + 0.8))
    ax = fig.add_subplot(111)
    ax.imshow(img, interpolation="nearest")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(f"{title}: left ground truth, right prediction (sRGB)")
    return save_tight(fig, path)


def dn_validation_figure(path: Path, simulated: np.ndarray, captured: np.ndarray, fits: Sequence[ChannelFit]
                         ) -> Path:
    n = len(fits)
    cols = min(n, 3)
    rows = int(math.ceil(n / cols))
    fig = new_figure(3.3 * cols, 3.0 * rows)
    for j, f in enumerate(fits):
        ax = fig.add_subplot(rows, cols, j + 1)
        x, y = simulated[:, j], captured[:, j]
        mask = np.zeros(len(x), bool)
        mask[f.outliers] = True
        ax.scatter(x[~mask], y[~mask], s=10, color="0.3")
        ax.scatter(x[mask], y[mask], s=18, color="red", label="outlier")
        xs = np.linspace(np.nanmin(x), np.nanmax(x), 2)
        ax.plot(xs, f.slope * xs + f.intercept, "k-", lw=1)
        ax.set_title(f"{f.channel}: R²={f.r2:.4f} (clean {f.r2_clean:.4f})", fontsize=9)
        ax.set_xlabel("simulated")
        ax.set_ylabel("captured")
    return save_tight(fig, path)


# ---------------------------------------------------------------- the report
@dataclass
class TargetData:
    """Patch data of one target for the report: names, reference XYZ, camera values, layout (rows, cols), and
    where the values came from (``placement``: the grid over the frame, drawn in the report)."""

    names: list[str]
    xyz: np.ndarray
    values: np.ndarray
    layout: tuple[int, int] | None = None
    label: str = ""
    std: np.ndarray | None = None          # (n, C) per-patch standard deviation of the camera values
    placement: Placed | None = None


@dataclass
class Placed:
    """A target's patch grid over its frame (H, W, 3: the first light's RGB), the placement checks' record
    (app.processing.placement.Placement.to_dict) and the grid cells the patches are in."""

    grid: PatchGrid
    frame: np.ndarray
    record: dict
    cells: list[int]


def quality_section(out_dir: Path, c: Characterisation, data: TargetData, errors: np.ndarray, label: str,
                    calibration: CalibrationFrames | None) -> tuple[dict, list[FigureJob]]:
    """The quality metrics of one target (app.processing.quality) and their figures (to draw)."""
    from dualrgb.app.processing.quality import STANDARD_LIMITS, assess
    from dualrgb.app.processing.quality_figures import lab_components_figure, tone_figure, uniformity_figure

    m = c.results[c.best].matrix
    lab_ref = xyz_to_lab(data.xyz, c.white)
    lab_cap = xyz_to_lab(m.apply(data.values), c.white)
    q = assess(lab_ref, lab_cap, data.names, errors, values=data.values, std=data.std,
               matrix=m.matrix if m.degree == 1 else m.jacobian(data.values), white=c.white, calibration=calibration)
    name, short = data.label or label, TARGET_WORDS.get(label, label)
    comp = q["lab_differences"]["per_patch"]
    jobs = [FigureJob(f"{short}: ΔL*, ΔC*, ΔH* per patch", lambda: lab_components_figure(
        out_dir / f"lab_components_{label}.png", data.names, comp, name))]
    if q["neutral_patches"]["patches"]:
        limit = STANDARD_LIMITS["ISO 19264-1:2021 A"]["tone_max_abs_dl"].value
        neutral = q["neutral_patches"]
        jobs.append(FigureJob(f"{short}: tone response",
                              lambda: tone_figure(out_dir / f"tone_{label}.png", neutral, limit, name)))
    if q.get("uniformity"):
        uniformity = q["uniformity"]
        jobs.append(FigureJob("illuminance non-uniformity",
                              lambda: uniformity_figure(out_dir / "uniformity.png", uniformity)))
    q["target"] = label
    return q, jobs


def _target_figures(out_dir: Path, c: Characterisation, label: str, data: TargetData) -> list[FigureJob]:
    """The chosen matrix on one target: dE00 heat map, Lab scatter and the patch mosaic (to draw)."""
    best, white = c.best, c.white
    res = c.results[best]
    errors = res.errors(label)
    layout = layout_for(len(data.names), data.layout)
    name, short = data.label or label, TARGET_WORDS.get(label, label)
    pred = res.matrix.apply(data.values)
    heat = f"{name}: ΔE00 per patch ({best})"
    jobs = [FigureJob(f"{short}: ΔE00 per patch",
                      lambda: heatmap_figure(out_dir / f"heatmap_{label}.png", errors, layout, heat)),
            FigureJob(f"{short}: a*b* and L*C* scatter",
                      lambda: lab_scatter_figure(out_dir / f"lab_scatter_{label}.png", data.xyz, errors, white, name)),
            FigureJob(f"{short}: patches, ground truth and prediction",
                      lambda: patch_mosaic_figure(out_dir / f"patches_{label}.png", data.xyz, pred, white, layout,
                                                  name))]
    p = data.placement
    if p is not None:
        from dualrgb.app.processing.placement import placement_figure

        title = f"{name} ({p.record.get('method', 'given')})"
        jobs.append(FigureJob(f"{short}: patch grid over the frame", lambda: placement_figure(
            out_dir / f"placement_{label}.png", p.frame, p.grid, title, p.cells)))
    return jobs


def _targets_section(out_dir: Path, c: Characterisation, targets: list[tuple[str, TargetData]]
                     ) -> tuple[list[FigureJob], dict]:
    """Per target ('train', 'test'): its figures (to draw), and every fitted matrix's dE00 per patch (names
    alongside)."""
    jobs: list[FigureJob] = []
    per_patch: dict = {}
    for label, data in targets:
        jobs += _target_figures(out_dir, c, label, data)
        per_patch[label] = {"names": list(data.names),
                            "de00": {m: [round(float(v), 4) for v in r.errors(label)] for m, r in c.results.items()}}
    return jobs, per_patch


def _dn_validation(out_dir: Path, c: Characterisation, simulated_train: np.ndarray, train: TargetData
                   ) -> tuple[dict, FigureJob]:
    """Simulated against captured training values per channel (thesis Fig 7.4): the section and its figure."""
    fits = dn_validation(simulated_train, train.values, c.channels)
    job = FigureJob("simulated against captured values (Fig 7.4)", lambda: dn_validation_figure(
        out_dir / "dn_validation.png", simulated_train, train.values, fits))
    union = sorted({i for f in fits for i in f.outliers})
    return ({"channels": [f.to_dict(train.names) for f in fits], "outlier_patches": union,
             "outlier_names": [train.names[i] for i in union],
             "min_r2": finite_or_none(min(f.r2 for f in fits)),
             "min_r2_without_outliers": finite_or_none(min(f.r2_clean for f in fits))}, job)


def _model_sections(out_dir: Path, c: Characterisation, train: TargetData, test: TargetData | None,
                    simulated_train: np.ndarray | None, spectral: SpectralCharacterisation | None
                    ) -> tuple[dict, list[FigureJob]]:
    """The simulated-vs-captured check (Fig 7.4) and the spectral estimate, when there are data for them."""
    sections: dict = {"dn_validation": None, "spectral": None}
    jobs: list[FigureJob] = []
    if simulated_train is not None:
        sections["dn_validation"], job = _dn_validation(out_dir, c, np.asarray(simulated_train), train)
        jobs.append(job)
    if spectral is not None:
        from dualrgb.app.processing.spectral import spectral_section

        names = {"train": train.names, "test": test.names if test is not None else []}
        sections["spectral"], more = spectral_section(out_dir, spectral, names)
        jobs += more
    return sections, jobs


def build_report(out_dir: Path, characterisation: Characterisation, train: TargetData,
                 test: TargetData | None = None, *, simulated_train: np.ndarray | None = None,
                 title: str = "dual-RGB capture", extra: dict | None = None,
                 calibration: CalibrationFrames | None = None,
                 spectral: SpectralCharacterisation | None = None, more_figures: Sequence[FigureJob] = (),
                 progress: FigureProgress | None = None, cancel: CancelToken | None = None) -> dict:
    """Write report.json and the PNG figures into ``out_dir``; returns the JSON dict. ``calibration`` (the
    session's processor, darks and flats) adds sensor noise and illuminance non-uniformity to the quality
    metrics (app.processing.quality); ``spectral`` (app.processing.spectral) a spectra figure and its section.
    ``more_figures``: figures of ``extra``'s sections (drawn last, named there). Every figure is listed before
    the first is drawn; ``progress(k, n, what)`` after each (figure_files.draw_figures); a cancel between them."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    c, best = characterisation, characterisation.best
    targets = [("train", train)] + ([("test", test)] if test is not None else [])
    jobs, per_patch = _targets_section(out_dir, c, targets)
    sections, more = _model_sections(out_dir, c, train, test, simulated_train, spectral)
    graded_set = "test" if test is not None else "train"
    graded, graded_errors = c.results[best].stats(graded_set), c.results[best].errors(graded_set)
    quality, qjobs = quality_section(out_dir, c, test if test is not None else train, graded_errors, graded_set,
                                     calibration)
    jobs += more + qjobs
    figures = draw_figures([*jobs, *more_figures], progress, cancel)[:len(jobs)]
    report = {
        **output_header(REPORT_FORMAT),
        "title": title,
        "created_at": datetime.now(UTC).isoformat(timespec="seconds"),
        "channels": c.channels,
        "white_xyz": [float(v) for v in c.white],
        "best_method": best,
        "best_reason": c.selection.reason if c.selection else "the only matrix fitted",
        "model_selection": c.selection.to_dict() if c.selection else None,
        "train": c.results[best].train.to_dict(),
        "test": c.results[best].stats("test").to_dict() if test is not None else None,
        "methods": {m: r.to_dict() for m, r in c.results.items()},
        **{k: v for k, v in c.to_dict().items() if k in ("models", "per_pixel_de00", "noise_gain", "condition_number")},
        "standards": {"evaluated_on": graded_set, "method": best, "stats": graded.to_dict(),
                      "scope": "colour accuracy only (dE00 of the target); the other criteria: see 'quality'",
                      "results": grade(graded)},
        "quality": quality,
        **sections,
        "per_patch": per_patch,
        "placement": {label: data.placement.record for label, data in targets if data.placement is not None},
        "figures": figures,
        **(extra or {}),
    }
    atomic_write(out_dir / "report.json", strict_dumps(report, indent=2))
    log.info("report written to %s (%d figures); best %s: test mean dE00 %s", out_dir, len(figures), best,
             f"{report['test']['mean']:.3f}" if report["test"] else "n/a")
    return report
