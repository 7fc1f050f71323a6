"""Image-quality metrics of a characterised capture, from data already captured, graded per metric against
FADGI 4-star, ISO 19264-1:2021 level A and Metamorfoze 2.0 Full.

Metrics (the test target with the delivered matrix; ``lab`` = CIELAB relative to the report's white):

* colour: mean / p90 / max CIEDE2000, and per patch the CIELAB 1976 components dL*, dC*ab, dH*ab (captured minus
  reference; dH*ab = 2 sqrt(C1 C2) sin(dh / 2), signed like dh) with their mean and max |.|;
* tone response: dL* of the neutral patches (reference C*ab < ``NEUTRAL_CHROMA``: the CC24's bottom row, an IT8
  grey scale), graded on the largest |dL*| (ISO 19264-1 "dL* <= +-2" applies to every grey patch);
* white balance: the neutral patches' CIEDE2000 without its lightness term (Metamorfoze 2.0's "dE(ab)*":
  captured L* set to the reference L*), graded on the largest;
* noise: L* RMS within each neutral patch of the delivered (superpixel) image, propagated from the patch's
  per-channel standard deviation through the matrix (channels taken as independent) and CIELAB's dL*/dY;
  graded on the largest;
* illuminance non-uniformity (ISO 17957-style shading on block means, FADGI's (max - min) / mean): of the raw
  light field (each light's HDR white: what eq 7.1 divides out; informative) and, graded, the residual of a
  uniform white after flat-fielding: a white merged from half of the flat frames divided by the white merged
  from the other half;
* sensor noise from darks and flats (informative): temporal read noise per CFA channel (difference of two dark
  frames / sqrt 2, robust MAD), the flats' signal, temporal noise, SNR and photon-transfer gain (e-/DN).

Not measured here, so "not assessed" for every standard: SFR / MTF and sampling efficiency, colour channel
misregistration, gain modulation, dynamic range, geometry. A grade is therefore never a full FADGI / ISO /
Metamorfoze grade; ``grade_metrics`` says which criteria were and were not assessed.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from dualrgb.simulation.colorimetry import delta_e_2000

if TYPE_CHECKING:                                   # pragma: no cover
    from dualrgb.app.processing.pipeline import CaptureProcessor, ExposureRef

log = logging.getLogger(__name__)

NEUTRAL_CHROMA = 4.0        # reference C*ab below which a patch counts as neutral (CC24 row 4 has C* < 1.5)
UNIFORMITY_BLOCKS = (9, 12)  # block grid (rows, cols) of the shading maps


# ---------------------------------------------------------------- limits (each with its source)
@dataclass(frozen=True)
class Limit:
    value: float
    strict: bool                  # "<" (FADGI) or "<=" (ISO, Metamorfoze)
    source: str

    def passes(self, v: float) -> bool:
        return bool(v < self.value) if self.strict else bool(v <= self.value)


_SKANDALSKI = ("comparison table of ISO 19264-1:2021 / FADGI 2023 (Bound General Collections) / Metamorfoze 2.0 "
               "(draft 2023), https://skandalski.pl/tabela-fadgi-iso-metamorfoze/")
_FADGI_2016 = ("FADGI Technical Guidelines for Digitizing Cultural Heritage Materials, September 2016, table "
               "'Paintings and other two-dimensional art', 4 star")
_META_2 = "Metamorfoze Preservation Imaging Guidelines 2.0 draft, https://preservationimaging.com/version-2/"

STANDARD_LIMITS: dict[str, dict[str, Limit]] = {
    "FADGI 4-star": {
        "colour_mean_de00": Limit(2.0, True, _SKANDALSKI),
        "colour_p90_de00": Limit(4.0, True, _SKANDALSKI),
        "tone_max_abs_dl": Limit(1.5, True, _SKANDALSKI),
        "white_balance_max_de": Limit(2.0, True, _SKANDALSKI),
        "noise_max_lstar": Limit(1.0, True, _SKANDALSKI),
        "illuminance_nonuniformity_pct": Limit(1.0, True, _FADGI_2016),
    },
    "ISO 19264-1:2021 A": {
        "colour_mean_de00": Limit(4.0, False, _SKANDALSKI),
        "colour_max_de00": Limit(10.0, False, _SKANDALSKI),
        "tone_max_abs_dl": Limit(2.0, False, _SKANDALSKI),
        "white_balance_max_de": Limit(3.0, False, _SKANDALSKI),
        "noise_max_lstar": Limit(1.6, False, _SKANDALSKI),
    },
    "Metamorfoze 2.0 Full": {
        "colour_mean_de00": Limit(3.0, False, _META_2),
        "colour_max_de00": Limit(7.0, False, _META_2),
        "tone_max_abs_dl": Limit(2.0, False, _SKANDALSKI),
        "white_balance_max_de": Limit(3.0, False, _META_2),
        "noise_max_lstar": Limit(1.6, False, _SKANDALSKI),
    },
}
COLOUR_METRICS = ("colour_mean_de00", "colour_p90_de00", "colour_max_de00")
NOT_MEASURED = ("SFR / MTF and sampling efficiency", "colour channel misregistration", "gain modulation",
                "dynamic range", "geometric distortion")


def grade_metrics(measured: dict[str, float | None]) -> dict:
    """Per standard and metric: value, limit, comparison, status (pass / fail / not assessed) and the limit's
    source; ``scope`` says whether only colour was assessed; criteria with no measurement are listed."""
    out = {}
    assessed = {k for k, v in measured.items() if v is not None and np.isfinite(v)}
    for std, limits in STANDARD_LIMITS.items():
        rows = {}
        for metric, lim in limits.items():
            v = measured.get(metric) if metric in assessed else None
            rows[metric] = {"value": None if v is None else round(float(v), 4), "limit": lim.value,
                            "comparison": "<" if lim.strict else "<=", "source": lim.source,
                            "status": "not assessed" if v is None else ("pass" if lim.passes(float(v)) else "fail")}
        statuses = [r["status"] for r in rows.values()]
        colour_only = all(r["status"] == "not assessed" for m, r in rows.items() if m not in COLOUR_METRICS)
        out[std] = {"metrics": rows, "passed": statuses.count("pass"), "failed": statuses.count("fail"),
                    "not_assessed": [m for m, r in rows.items() if r["status"] == "not assessed"]
                                    + list(NOT_MEASURED),
                    "scope": "colour accuracy only" if colour_only else "measured criteria only (not a full grade)",
                    "verdict": "fail" if "fail" in statuses else "pass (measured criteria)"}
    return out


# ---------------------------------------------------------------- colour metrics
def lab_differences(lab_ref: np.ndarray, lab_cap: np.ndarray) -> dict[str, np.ndarray]:
    """CIELAB 1976 dL*, dC*ab, dH*ab (captured minus reference) per patch."""
    lab_ref = np.asarray(lab_ref, dtype=float)
    lab_cap = np.asarray(lab_cap, dtype=float)
    c1 = np.hypot(lab_ref[:, 1], lab_ref[:, 2])
    c2 = np.hypot(lab_cap[:, 1], lab_cap[:, 2])
    da = lab_cap[:, 1] - lab_ref[:, 1]
    db = lab_cap[:, 2] - lab_ref[:, 2]
    dc = c2 - c1
    cross = lab_ref[:, 1] * lab_cap[:, 2] - lab_ref[:, 2] * lab_cap[:, 1]
    dh = np.sqrt(np.maximum(da * da + db * db - dc * dc, 0.0)) * np.where(cross < 0, -1.0, 1.0)
    return {"dL": lab_cap[:, 0] - lab_ref[:, 0], "dC": dc, "dH": dh}


def summary(values: np.ndarray) -> dict[str, float]:
    v = np.asarray(values, dtype=float)
    return {"mean": float(v.mean()), "mean_abs": float(np.abs(v).mean()), "max_abs": float(np.abs(v).max())}


def neutral_patches(lab_ref: np.ndarray, max_chroma: float = NEUTRAL_CHROMA) -> np.ndarray:
    """Indices of the neutral patches, lightest first."""
    lab_ref = np.asarray(lab_ref, dtype=float)
    idx = np.flatnonzero(np.hypot(lab_ref[:, 1], lab_ref[:, 2]) < max_chroma)
    return idx[np.argsort(-lab_ref[idx, 0])]


def tone_and_white_balance(lab_ref: np.ndarray, lab_cap: np.ndarray, idx: np.ndarray) -> dict:
    """Tone response (dL*) and white balance error (CIEDE2000 without lightness) of the neutral patches."""
    ref, cap = np.asarray(lab_ref, float)[idx], np.asarray(lab_cap, float)[idx]
    same_l = cap.copy()
    same_l[:, 0] = ref[:, 0]
    wb = delta_e_2000(ref, same_l)
    dl = cap[:, 0] - ref[:, 0]
    return {"patches": [int(i) for i in idx], "reference_L": ref[:, 0].tolist(), "captured_L": cap[:, 0].tolist(),
            "dL": dl.tolist(), "max_abs_dL": float(np.abs(dl).max()) if len(idx) else None,
            "white_balance_de00_ab": wb.tolist(), "max_white_balance": float(wb.max()) if len(idx) else None,
            "da": (cap[:, 1] - ref[:, 1]).tolist(), "db": (cap[:, 2] - ref[:, 2]).tolist()}


def lightness_noise(values: np.ndarray, std: np.ndarray, matrix: np.ndarray, white: np.ndarray,
                    idx: np.ndarray) -> list[float]:
    """L* RMS noise of each patch in ``idx``: per-channel standard deviations ``std`` (n, C) through the Y row
    of ``matrix`` (C, 3), or of each patch's own (n, C, 3) (a non-linear model's Jacobian at the patch),
    (independent channels) and dL*/dY at the patch's Y (values through that map: exactly the model's Y, every
    delivered model being homogeneous of degree 1, Euler's theorem)."""
    A = np.asarray(matrix, dtype=float)
    A = A[idx] if A.ndim == 3 else np.broadcast_to(A, (len(idx),) + A.shape)
    y = np.einsum("nc,nc->n", np.asarray(values, float)[idx], A[:, :, 1])
    sy = np.sqrt((np.asarray(std, float)[idx] ** 2 * A[:, :, 1] ** 2).sum(axis=1))
    t = np.maximum(y / white[1], 1e-12)
    d = 6.0 / 29.0
    slope = np.where(t > d ** 3, (116.0 / 3.0) * np.cbrt(t) ** -2, 116.0 / (3 * d * d))    # dL*/d(Y/Yn)
    return (slope * sy / white[1]).tolist()


# ---------------------------------------------------------------- uniformity and sensor noise
def block_means(mosaic: np.ndarray, cfa_index: np.ndarray, blocks: tuple[int, int] = UNIFORMITY_BLOCKS
                ) -> dict[int, np.ndarray]:
    """Per CFA colour (0 R, 1 G, 2 B): the mean of each block of a (rows, cols) grid over the frame."""
    out: dict[int, list] = {}
    m = np.asarray(mosaic, dtype=np.float64)
    for di in range(2):
        for dj in range(2):
            plane = m[di::2, dj::2]
            rows = np.array_split(np.arange(plane.shape[0]), blocks[0])
            cols = np.array_split(np.arange(plane.shape[1]), blocks[1])
            grid = np.array([[np.nanmean(plane[r[0]:r[-1] + 1, c[0]:c[-1] + 1]) for c in cols] for r in rows])
            out.setdefault(int(cfa_index[di, dj]), []).append(grid)
    return {ch: np.mean(g, axis=0) for ch, g in out.items()}


def shading(mosaic: np.ndarray, cfa_index: np.ndarray, blocks: tuple[int, int] = UNIFORMITY_BLOCKS) -> dict:
    """Percent deviation of each block from the channel's mean, (max - min) / mean and max |deviation| (%)."""
    res = {}
    for ch, grid in block_means(mosaic, cfa_index, blocks).items():
        mean = float(np.nanmean(grid))
        dev = 100.0 * (grid / mean - 1.0)
        res["RGB"[ch]] = {"deviation_pct": np.round(dev, 3).tolist(),
                          "range_pct": float(100.0 * (np.nanmax(grid) - np.nanmin(grid)) / mean),
                          "max_abs_pct": float(np.nanmax(np.abs(dev)))}
    return res


def _robust_sd(x: np.ndarray, k: float = 5.0) -> float:
    """Standard deviation after rejecting outliers (hot pixels, spikes) beyond ``k`` robust sigmas of the median.
    (A plain MAD is quantised on integer raw differences: 2 DN of MAD always reads as 2.10 DN.)"""
    x = np.asarray(x, dtype=np.float64).ravel()
    med = np.median(x)
    s0 = 1.4826 * np.median(np.abs(x - med))
    keep = np.abs(x - med) <= k * max(s0, 1.0)
    return float(x[keep].std())


def temporal_noise(frame_a: np.ndarray, frame_b: np.ndarray, cfa_index: np.ndarray) -> dict[str, float]:
    """Per CFA colour: temporal noise (DN) of one frame from two frames of the same scene, sd(a - b) / sqrt 2."""
    d = np.asarray(frame_a, np.float64) - np.asarray(frame_b, np.float64)
    out: dict[str, list] = {}
    for di in range(2):
        for dj in range(2):
            out.setdefault("RGB"[int(cfa_index[di, dj])], []).append(_robust_sd(d[di::2, dj::2]) / np.sqrt(2.0))
    return {k: float(np.mean(v)) for k, v in out.items()}


def channel_means(frame: np.ndarray, dark: np.ndarray | float, cfa_index: np.ndarray, central: float = 0.5
                  ) -> dict[str, float]:
    """Per CFA colour: mean dark-subtracted signal over the central part of the frame."""
    m = np.asarray(frame, np.float64) - np.asarray(dark, np.float64)
    h, w = m.shape
    r0, c0 = int(h * (1 - central) / 4) * 2, int(w * (1 - central) / 4) * 2
    out: dict[str, list] = {}
    for di in range(2):
        for dj in range(2):
            out.setdefault("RGB"[int(cfa_index[di, dj])], []).append(
                float(m[r0 + di:h - r0:2, c0 + dj:w - c0:2].mean()))
    return {k: float(np.mean(v)) for k, v in out.items()}


# ---------------------------------------------------------------- calibration frames -> metrics
@dataclass
class CalibrationFrames:
    """What the report needs from a session's calibration: its processor (master darks, HDR whites) and the
    dark and flat frames (flats per light), so the report can measure noise and uniformity."""

    processor: CaptureProcessor
    darks: list[ExposureRef] = field(default_factory=list)
    flats: dict[str, list[ExposureRef]] = field(default_factory=dict)


def _pairs_by_exposure(refs: Sequence[ExposureRef]) -> dict[float, list[ExposureRef]]:
    groups: dict[float, list] = {}
    for r in refs:
        groups.setdefault(round(float(r.exposure_s), 9), []).append(r)
    return {t: g for t, g in groups.items() if len(g) >= 2}


def _mosaics(refs: Sequence[ExposureRef]) -> list[np.ndarray]:
    from dualrgb.app.processing.mosaic import iter_open_raw, mosaic_of

    return [np.array(mosaic_of(f), dtype=np.float32) for f in iter_open_raw([r.source for r in refs])]


def sensor_noise(cal: CalibrationFrames, cfa_index: np.ndarray) -> dict:
    """Read noise from the longest dark pair; per light, at the longest flat exposure within the linear range,
    the flats' signal, temporal noise, SNR and photon-transfer gain (signal / (noise^2 - read noise^2))."""
    out: dict = {}
    darks = _pairs_by_exposure(cal.darks)
    read = None
    if darks:
        t = max(darks)
        a, b = _mosaics(darks[t][:2])
        read = temporal_noise(a, b, cfa_index)
        out["read_noise_dn"] = {"exposure_s": t, **read}
    limit = float(cal.processor.linear_limit or np.inf)
    for light, refs in cal.flats.items():
        pairs = _pairs_by_exposure(refs)
        for t in sorted(pairs, reverse=True):            # the longest exposure whose flat is within the linear range
            a, b = _mosaics(pairs[t][:2])
            h, w = a.shape
            if float(np.median(a[h // 4: 3 * h // 4, w // 4: 3 * w // 4])) <= 0.95 * limit:
                break
        else:
            continue
        dark = cal.processor.master_dark(t)
        s = channel_means(a, dark if dark is not None else float(cal.processor.black_level or 0.0), cfa_index)
        n = temporal_noise(a, b, cfa_index)
        row: dict[str, Any] = {"exposure_s": t}
        for ch in s:
            shot = n[ch] ** 2 - (read[ch] ** 2 if read else 0.0)
            row[ch] = {"signal_dn": s[ch], "noise_dn": n[ch], "snr": s[ch] / n[ch] if n[ch] > 0 else None,
                       "gain_e_per_dn": s[ch] / shot if shot > 0 else None}
        out.setdefault("flats", {})[light] = row
    return out


def uniformity(cal: CalibrationFrames, cfa_index: np.ndarray) -> dict:
    """Per light: shading of the raw light field (its HDR white) and the residual shading of a flat-fielded
    uniform white (half of the flat frames merged, divided by the other half merged)."""
    out: dict = {}
    proc = cal.processor
    for light, refs in cal.flats.items():
        if not proc.has_white(light):
            continue
        row = {"light_field": shading(proc.white(light).white, cfa_index)}
        groups = sorted(_pairs_by_exposure(refs).items())
        if groups and len(groups) == len({round(float(r.exposure_s), 9) for r in refs}):
            half_a = [g[i] for _, g in groups for i in range(0, len(g), 2)]
            half_b = [g[i] for _, g in groups for i in range(1, len(g), 2)]
            a, b = proc.hdr(half_a).radiance, proc.hdr(half_b).radiance
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(b > 0, a / b, np.nan)
            row["after_flat_field"] = shading(ratio, cfa_index)
        out[light] = row
    return out


def worst_residual_pct(uni: dict) -> float | None:
    vals = [ch["range_pct"] for row in uni.values() for ch in row.get("after_flat_field", {}).values()]
    return float(max(vals)) if vals else None


# ---------------------------------------------------------------- everything for the report
def assess(lab_ref: np.ndarray, lab_cap: np.ndarray, names: Sequence[str], errors: np.ndarray, *,
           values: np.ndarray | None = None, std: np.ndarray | None = None,
           matrix: np.ndarray | None = None, white: np.ndarray | None = None,
           calibration: CalibrationFrames | None = None) -> dict:
    """All metrics of one target (normally the test target) and their grading."""
    from dualrgb.app.processing.mosaic import cfa_channel_index
    from dualrgb.simulation.objective import ErrorStats

    comp = lab_differences(lab_ref, lab_cap)
    idx = neutral_patches(lab_ref)
    tone = tone_and_white_balance(lab_ref, lab_cap, idx)
    tone["names"] = [names[i] for i in idx]
    stats = ErrorStats.of(errors)
    measured: dict[str, float | None] = {"colour_mean_de00": stats.mean, "colour_p90_de00": stats.p90,
                                            "colour_max_de00": stats.max, "tone_max_abs_dl": tone["max_abs_dL"],
                                            "white_balance_max_de": tone["max_white_balance"]}
    out = {"lab_differences": {"per_patch": {k: np.round(v, 4).tolist() for k, v in comp.items()},
                               "summary": {k: summary(v) for k, v in comp.items()}},
           "neutral_patches": tone}
    if values is not None and std is not None and matrix is not None and white is not None and len(idx):
        noise = lightness_noise(values, std, matrix, np.asarray(white, float), idx)
        out["lightness_noise"] = {"names": tone["names"], "lstar_rms": noise}
        measured["noise_max_lstar"] = float(max(noise))
    if calibration is not None:
        cfa = cfa_channel_index(calibration.processor.cfa or "RGGB")
        out["sensor_noise"] = sensor_noise(calibration, cfa)
        out["uniformity"] = uniformity(calibration, cfa)
        measured["illuminance_nonuniformity_pct"] = worst_residual_pct(out["uniformity"])
    out["measured"] = {k: (None if v is None else round(float(v), 4)) for k, v in measured.items()}
    out["grading"] = grade_metrics(measured)
    return out


def quality_summary(quality: dict) -> dict:
    """The measured values and each standard's verdict and scope (for the demo's top-level report)."""
    return {"measured": quality["measured"],
            "grading": {std: {"verdict": g["verdict"], "scope": g["scope"], "passed": g["passed"],
                              "failed": g["failed"], "not_assessed": g["not_assessed"]}
                        for std, g in quality["grading"].items()}}


def grading_summary(quality: dict) -> dict:
    """What the calibration profile and each original's sidecar keep of the grading: the measured values, and
    per standard its verdict, scope, counts and each criterion's status (the limits and sources stay in the
    report)."""
    return {"measured": dict(quality.get("measured") or {}),
            "grading": {std: {"verdict": g["verdict"], "scope": g["scope"], "passed": g["passed"],
                              "failed": g["failed"],
                              "metrics": {m: r["status"] for m, r in g["metrics"].items()}}
                        for std, g in (quality.get("grading") or {}).items()}}


def grading_lines(summary: dict | None) -> list[str]:
    """One line per standard: ``FADGI 4-star: pass (measured criteria; colour accuracy only): colour_mean_de00
    pass, ...`` (none without a grading: a calibration made before it was recorded)."""
    if not summary or not summary.get("grading"):
        return ["grading: not recorded in this calibration (calibrate again)"]
    out = []
    for std, g in summary["grading"].items():
        crit = ", ".join(f"{m} {s}" for m, s in g["metrics"].items() if s != "not assessed")
        out.append(f"{std}: {g['verdict']} ({g['scope']}; {g['passed']} passed, {g['failed']} failed): {crit}")
    return out
