"""The stand model fitted to a calibration's captures (simulation/stand_fit.py), as the processing and the
calibration profile use it.

:func:`fit_session_stand` is called by ``process_session`` (app/workflow/calibration/session_processing.py) when the
training
target's spectra and the lights' levels are known: it reduces the processed captures to
:class:`simulation.stand_fit.StandObservations` - each light's open gate at the frame's centre (the HDR white's
median over the central quarter, per CFA colour, DN per second above black), the training and test patch means
(flat-fielded values times that level: DN per second at the centre, vignetting out), their standard errors and the
frames' means (the flare's base) - fits the model from ``start`` (nominal, or with measurements), and predicts the
captured test CIEDE2000 with the starting and the fitted model (the expected-captured model of
simulation/expected_error.py for this calibration's patch sizes and frame counts; least-squares matrix, as the
objective). :func:`report_section` adds the thesis Fig 7.4 check for the fitted model (the report's own
``dn_validation`` shows the starting one) and a figure of both; the profile stores :meth:`StandResult.summary` and,
in its .npz, the observations (:func:`observation_arrays`), so the model can be refitted later from other
measurements without the session (app/workflow/calibration/stand_reoptimise.py).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.app.processing.characterise import LEAST_SQUARES, Characterisation
from dualrgb.app.processing.figure_files import FigureJob
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.defaults import default_grid
from dualrgb.simulation.grid import DEFAULT_GRID, SpectralGrid
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.stand_fit import StandFit, StandObservations, expected_de00, fit_stand
from dualrgb.simulation.stand_model import StandModel

log = logging.getLogger(__name__)

FIGURE = "dn_validation_fitted.png"
REFERENCE_ISO, REFERENCE_APERTURE = 50, 8.0      # the virtual lab's and the expected model's reference settings
_ARRAYS = ("levels", "white", "train", "train_spectra", "train_frame", "train_sd", "test", "test_spectra",
           "test_frame")


@dataclass
class StandResult:
    """A calibration's stand fit: the fit, what it was fitted to, the lights, and the predicted and captured
    mean CIEDE2000 (``de00``)."""

    fit: StandFit
    observations: StandObservations
    lights: list[str]
    mode: str
    capture: CaptureModel
    de00: dict = field(default_factory=dict)

    def values(self, which: str = "start") -> np.ndarray:
        """(n, 3 L) the training patches as ``which`` model ('start' or 'fitted') predicts them, DN per second,
        channels R1, G1, B1, R2, ... (the processing's order)."""
        pred = self.fit.start_prediction if which == "start" else self.fit.fitted
        return pred.train.reshape(len(pred.train), -1)

    def captured(self, which: str = "train") -> np.ndarray:
        values = self.observations.train if which == "train" else self.observations.test
        if values is None:
            raise ValueError(f"the stand fit has no {which} target")
        return np.asarray(values).reshape(len(values), -1)

    def summary(self) -> dict[str, Any]:
        """The profile's ``stand_model`` section: the fitted model, parameters, warnings, R^2, CIEDE2000."""
        return {**self.fit.to_dict(), "lights": list(self.lights), "mode": self.mode,
                "dn_scale": self.observations.dn_scale, "de00": self.de00,
                "capture": {"train_pixels": self.capture.camera.pixels_per_patch,
                            "test_pixels": self.capture.pixels("test"), "dark_frames": self.capture.camera.dark_frames,
                            "flat_frames": self.capture.camera.flat_frames}}


# ---- the captures, reduced --------------------------------------------------------------------------------
def centre_level(white: np.ndarray, cfa: str = "RGGB", fraction: float = 0.25) -> np.ndarray:
    """(3,) an HDR white mosaic's median per CFA colour (R, G, B) over its central ``fraction`` of each side
    (the crop starts on an even row and column, so the CFA phase is the frame's)."""
    h, w = white.shape
    r0, c0 = int(h * (1 - fraction) / 4) * 2, int(w * (1 - fraction) / 4) * 2
    crop = np.asarray(white[r0:r0 + max(2, int(h * fraction) // 2 * 2), c0:c0 + max(2, int(w * fraction) // 2 * 2)])
    planes: dict[str, list[np.ndarray]] = {"R": [], "G": [], "B": []}
    for pos, colour in enumerate(cfa.upper()):
        planes[colour].append(crop[pos // 2::2, pos % 2::2].ravel())
    return np.array([float(np.nanmedian(np.concatenate(planes[c]))) for c in "RGB"])


def frame_mean(stack_data: np.ndarray, max_samples: int = 250_000) -> np.ndarray:
    """(C,) the flat-fielded frame's mean per channel over its usable superpixels, on a regular subsample of at most
    about ``max_samples`` of them (a 24 MP frame's stack is not copied whole for one mean)."""
    h, w = stack_data.shape[:2]
    step = max(1, int(np.ceil(np.sqrt(h * w / max_samples))))
    sample = stack_data[::step, ::step].reshape(-1, stack_data.shape[-1])
    return np.asarray(np.nanmean(sample, axis=0, dtype=np.float64))


def patch_counts(grid: Any, shape: tuple[int, ...], n: int) -> np.ndarray | None:
    """(n,) superpixels each patch's mean averages (None without a grid)."""
    if grid is None:
        return None
    return np.asarray(grid.sample(np.zeros((shape[0], shape[1], 1), np.float32)).count[:n], dtype=float)


def dn_scale(iso: float | None, aperture: float | None) -> float:
    """Exposure per second against the reference settings (ISO 50, f/8): (ISO / 50) (8 / N)^2."""
    if not iso or not aperture:
        return 1.0
    return float(iso) / REFERENCE_ISO * (REFERENCE_APERTURE / float(aperture)) ** 2


@dataclass
class Captured:
    """One target's processed captures: patch means (n, C), their per-pixel sd (n, C), pixel counts (n,) or None,
    the frame's mean (C,), its spectra (n, n_wl)."""

    values: np.ndarray
    sd: np.ndarray | None
    counts: np.ndarray | None
    frame: np.ndarray
    spectra: np.ndarray


def observations(levels: np.ndarray, white: np.ndarray, train: Captured, test: Captured | None,
                 scale: float = 1.0, grid: SpectralGrid = DEFAULT_GRID) -> StandObservations:
    """:class:`StandObservations` from the processed captures: ``white`` (L, 3) the open gates' centre levels,
    the targets' spectra on ``grid`` (the mode's, simulation.defaults.default_grid)."""
    L = len(levels)

    def dn(values: np.ndarray) -> np.ndarray:
        return np.asarray(values, dtype=float).reshape(len(values), L, 3) * white[None]
    sd = None
    if train.sd is not None and train.counts is not None:
        sd = dn(train.sd / np.sqrt(np.maximum(train.counts, 1.0))[:, None])
    return StandObservations(
        np.asarray(levels, dtype=float), np.asarray(white, dtype=float), dn(train.values), train.spectra,
        train.frame.reshape(L, 3) * white, sd,
        test=dn(test.values) if test is not None else None, test_spectra=test.spectra if test is not None else None,
        test_frame=test.frame.reshape(L, 3) * white if test is not None else None, grid=grid, dn_scale=scale)


def calibration_capture(mode: str, train_px: np.ndarray | None, test_px: np.ndarray | None, dark_frames: int,
                        flat_frames: int) -> CaptureModel:
    """The expected-captured model of this calibration: the virtual lab's sensor, its patch sizes and frame
    counts (median pixels per patch)."""
    cap = CaptureModel.virtual_lab(mode)
    cam = replace(cap.camera, dark_frames=max(1, dark_frames), flat_frames=max(1, flat_frames),
                  pixels_per_patch=int(np.median(train_px)) if train_px is not None else cap.camera.pixels_per_patch)
    return replace(cap, camera=cam, test_pixels_per_patch=int(np.median(test_px)) if test_px is not None
                   else cap.test_pixels_per_patch)


# ---- the fit and what it predicts -------------------------------------------------------------------------
def predicted_de00(fit: StandFit, mode: str, lights: list[LightSource], capture: CaptureModel,
                   characterisation: Characterisation) -> dict[str, Any]:
    """Captured mean CIEDE2000 (least-squares matrix and the delivered one) beside what the starting and the fitted
    model predict for these lights under this calibration's capture, and each prediction's relative miss."""
    W = np.stack([light.weights() for light in lights])
    ls = characterisation.results.get(LEAST_SQUARES) or characterisation.results[characterisation.best]
    test = ls.test
    captured = {"train": ls.train.mean, "test": test.mean if test is not None else None}
    out: dict[str, Any] = {"matrix": LEAST_SQUARES if LEAST_SQUARES in characterisation.results
                           else characterisation.best, "captured": captured, "predicted": {}, "miss": {}}
    for name, model in (("start", fit.start), ("fitted", fit.model)):
        pred = expected_de00(model, mode, W, capture)
        out["predicted"][name] = pred
        out["miss"][name] = {k: (pred[k] / v - 1.0) if v else None for k, v in captured.items()}
    return out


def fit_calibration(mode: str, lights: list[LightSource], names: list[str], obs: StandObservations,
                    capture: CaptureModel, characterisation: Characterisation,
                    start: StandModel | None = None) -> StandResult:
    """Fit the stand model to ``obs`` (from ``start``: nominal, or with measurements) and predict the captured
    CIEDE2000 with both models."""
    fit = fit_stand(obs, start)
    de00 = predicted_de00(fit, mode, lights, capture, characterisation)
    log.info("stand model: train R^2 %.5f -> %.5f; test dE00 captured %s, predicted start %.3f / fitted %.3f",
             fit.min_r2("start"), fit.min_r2("fitted"), de00["captured"]["test"],
             de00["predicted"]["start"]["test"], de00["predicted"]["fitted"]["test"])
    return StandResult(fit, obs, list(names), mode, capture, de00)


def _frame_counts(frames: Any, subject: Any, names: list[str]) -> tuple[int, int]:
    """(dark frames, flat frames) at the lights' base (shortest) exposures, the fewest of any light."""
    def near(t: float, refs: Any) -> int:
        return sum(abs(r.exposure_s - t) <= 0.02 * t for r in refs)
    base = {n: min(r.exposure_s for r in frames.subject(subject)[n]) for n in names}
    return (min((near(t, frames.darks) for t in base.values()), default=1),
            min((near(t, frames.flats.get(n, [])) for n, t in base.items()), default=1))


def fit_processed(proc: Any, frames: Any, names: list[str], lights: list[LightSource], train: tuple, test: tuple,
                  characterisation: Characterisation, start: StandModel | None,
                  settings: tuple[float | None, float | None] = (None, None)) -> StandResult | None:
    """The stand fit of a processed session (``process_session``): ``proc`` its CaptureProcessor (the whites),
    ``frames`` its SessionFrames, ``train`` (spec, means, per-pixel sd, stack), ``test`` (spec or None, means,
    stack), ``settings`` the camera's (ISO, aperture). None (logged) when the fit cannot be made."""
    spec, vt, st, stack = train
    tspec, vs, stack_t = test
    white = np.stack([centre_level(proc.white(n).white, proc.cfa or "RGGB") for n in names])
    counts = patch_counts(spec.grid, stack.data.shape, len(vt))
    tr = Captured(vt, st, counts, frame_mean(stack.data), spec.spectra)
    te = None
    if tspec is not None and tspec.spectra is not None and vs is not None and stack_t is not None:
        te = Captured(vs, None, patch_counts(tspec.grid, stack_t.data.shape, len(vs)), frame_mean(stack_t.data),
                      tspec.spectra)
    darks, flats = _frame_counts(frames, spec.subject, names)
    capture = calibration_capture(spec.mode, counts, te.counts if te is not None else None, darks, flats)
    try:
        obs = observations(np.stack([light.weights() for light in lights]), white, tr, te, dn_scale(*settings),
                           default_grid(spec.mode))
        return fit_calibration(spec.mode, lights, names, obs, capture, characterisation, start)
    except (ValueError, np.linalg.LinAlgError) as exc:      # the fit is a check: its failure never stops processing
        log.warning("stand model not fitted: %s", exc)
        return None


# ---- the report ---------------------------------------------------------------------------------------------
def report_section(result: StandResult, out_dir: Path, channels: list[str], patch_names: list[str]
                   ) -> tuple[dict, FigureJob]:
    """The report's ``stand_model`` section: the fitted model's Fig 7.4 check (line R^2 and outliers, as the
    report's ``dn_validation`` of the starting model), both models' R^2 against the captures, the parameters and
    CIEDE2000, and a figure of captured against predicted DN for both (named in the section; the job draws it:
    the report draws it with its own, app.processing.report.build_report's ``more_figures``)."""
    from dualrgb.app.processing.report import dn_validation

    fits = dn_validation(result.values("fitted"), result.captured("train"), channels)
    union = sorted({i for f in fits for i in f.outliers})
    section = {**result.summary(),
               "dn_validation": {"channels": [f.to_dict(patch_names) for f in fits], "outlier_patches": union,
                                 "outlier_names": [patch_names[i] for i in union],
                                 "min_r2": min(f.r2 for f in fits),
                                 "min_r2_without_outliers": min(f.r2_clean for f in fits)},
               "figures": [FIGURE]}
    job = FigureJob("stand model: captured against predicted values",
                    lambda: stand_figure(Path(out_dir) / FIGURE, result, channels))
    return section, job


def stand_figure(path: Path, result: StandResult, channels: list[str]) -> Path:
    """Captured against predicted training DN per channel: the starting model (grey) and the fitted one (black),
    R^2 of each."""
    from dualrgb.app.processing.figure_files import new_figure, save_tight

    captured = result.captured("train")
    cols = min(len(channels), 3)
    rows = int(np.ceil(len(channels) / cols))
    fig = new_figure(3.3 * cols, 3.0 * rows)
    r2 = result.fit.r2
    for j, ch in enumerate(channels):
        ax = fig.add_subplot(rows, cols, j + 1)
        ax.scatter(result.values("start")[:, j], captured[:, j], s=8, color="0.65",
                   label=_start_label(result.fit.start))
        ax.scatter(result.values("fitted")[:, j], captured[:, j], s=8, color="black", label="fitted")
        top = float(np.nanmax(captured[:, j]))
        ax.plot([0, top], [0, top], "r-", lw=0.8)
        ax.set_title(f"{ch}: R² {r2['start']['train'][j]:.4f} -> {r2['fitted']['train'][j]:.5f}", fontsize=9)
        ax.set_xlabel("predicted DN/s")
        ax.set_ylabel("captured DN/s")
        if j == 0:
            ax.legend(fontsize=7)
    return save_tight(fig, path)


# ---- the observations in the profile's .npz -------------------------------------------------------------------
def observation_arrays(obs: StandObservations) -> dict[str, np.ndarray]:
    """The observations as named arrays (``stand_<field>``) for the profile's .npz; absent parts left out."""
    return {f"stand_{k}": np.asarray(getattr(obs, k), dtype=np.float64) for k in _ARRAYS
            if getattr(obs, k) is not None}


def observations_from_arrays(arrays: Any, scale: float = 1.0, grid: SpectralGrid = DEFAULT_GRID
                             ) -> StandObservations | None:
    """The observations back from the profile's .npz (None when it has none: a profile made before); the
    spectra are on ``grid``, the profile's mode's."""
    if "stand_levels" not in getattr(arrays, "files", arrays):
        return None
    got = {k: np.asarray(arrays[f"stand_{k}"]) for k in _ARRAYS if f"stand_{k}" in getattr(arrays, "files", arrays)}
    return StandObservations(**got, grid=grid, dn_scale=scale)


# ---- for people (``dualrgb calibration show``) ------------------------------------------------------------------
def _percent(v: float | None) -> str:
    return "?" if v is None else f"{100 * v:+.1f} %"


def _start_label(start: StandModel) -> str:
    """How the starting model is named for people: nominal, or by its measured curves."""
    measured = [w for w, f in (("camera", start.camera_csv), ("LEDs", start.leds_csv)) if f]
    return f"measured {' and '.join(measured)}" if measured else "nominal"


def describe_stand(section: dict[str, Any]) -> list[str]:
    """Lines on a profile's stand model: what it started from, R^2 before and after, the captured test CIEDE2000
    beside both predictions, the parameters with their standard uncertainties, what determines them
    (identifiability: posterior / prior sd, correlations, the combinations left to the priors), warnings."""
    if not section:
        return ["stand model: not fitted (calibration made before the stand fit, or without the targets' spectra)"]
    start = section.get("start") or {}
    camera = f"measured camera {Path(start['camera_csv']).name}" if start.get("camera_csv") else "nominal camera"
    r2, de = section.get("r2") or {}, section.get("de00") or {}
    label = _start_label(StandModel.from_dict(start)) if start else "nominal"
    lines = [f"stand model: fitted to the training target and flats from the {camera}"
             + (f" and measured LEDs {Path(start['leds_csv']).name}" if start.get("leds_csv") else "")
             + (" with their measured level curves" if start.get("level_curves") else "")]
    for target in ("train", "test"):
        if target in r2.get("fitted", {}):
            lines.append(f"  R² {target} (worst channel): {label} {min(r2['start'][target]):.4f} -> fitted "
                         f"{min(r2['fitted'][target]):.5f}")
    cap, pred, miss = de.get("captured") or {}, de.get("predicted") or {}, de.get("miss") or {}
    if cap.get("test") is not None and pred:
        lines.append(f"  test mean dE00 ({de.get('matrix', '?')}): captured {cap['test']:.3f}, predicted {label} "
                     f"{pred['start']['test']:.3f} ({_percent(miss['start']['test'])}), fitted "
                     f"{pred['fitted']['test']:.3f} ({_percent(miss['fitted']['test'])})")
    params = section.get("parameters", [])
    lines += [f"  {g}: {', '.join(items)}" for g, items in _grouped(params, lambda p: f"{p['value']:#.3g} ± "
                                                                   f"{p['sd']:.2g}" + (" (at bound)" if
                                                                                        p.get("at_bound") else ""))]
    lines += describe_identifiability(section)
    lines += [f"  warning: {w}" for w in section.get("warnings", [])]
    return lines


def _grouped(params: list[dict[str, Any]], text: Any) -> list[tuple[str, list[str]]]:
    """Parameters grouped by kind ("LED 3 peak shift (nm)" -> group "LED peak shift (nm)", member "3"), each
    member as ``text(parameter)``."""
    groups: dict[str, list[str]] = {}
    for p in params:
        words = p["label"].split(" ", 2)          # "LED 3 peak shift (nm)", "gain R", "camera G width", "flare"
        group = f"{words[0]} {words[2]}" if len(words) == 3 else words[0]
        who = words[1] if len(words) > 1 else ""
        groups.setdefault(group, []).append(f"{who} {text(p)}".strip())
    return list(groups.items())


SHOWN_PAIRS = 5


def describe_identifiability(section: dict[str, Any]) -> list[str]:
    """The stand fit's identifiability for people (simulation.stand_fit): posterior / prior sd per parameter,
    the strongest correlations, the combinations left to the priors. Nothing for a profile fitted before."""
    params = [p for p in section.get("parameters", []) if "sd_ratio" in p]
    limits = section.get("identifiability") or {}
    if not params or not limits:
        return []
    lines = [f"  determined by (posterior sd / prior sd; below {limits['determined_ratio']:.2g} the captures, from "
             f"{limits['prior_ratio']:.2g} mainly the prior):"]
    lines += [f"    {g}: {', '.join(items)}" for g, items in _grouped(params, lambda p: f"{p['sd_ratio']:.2f}" + (
        " (prior)" if p["determined_by"] == "prior" else ""))]
    pairs = section.get("correlations") or []
    if pairs:
        shown = ", ".join(f"{c['a']} ~ {c['b']} {c['r']:+.3f}" for c in pairs[:SHOWN_PAIRS])
        more = f" (and {len(pairs) - SHOWN_PAIRS} more pairs)" if len(pairs) > SHOWN_PAIRS else ""
        lines.append(f"  correlated (|r| >= {limits['correlation_limit']:g}): {shown}{more}")
    for d in section.get("weak_directions") or []:
        combo = " ".join(f"{w:+.2f} {name}" for name, w in d["combination"])
        lines.append(f"  left to the priors (posterior sd {d['sd_ratio']:.2f} of the prior's along): {combo}")
    return lines
