"""The camera's relative spectral sensitivity from a CSRF session (thesis 4.2, eq 4.1) and its camera CSV.

Per wavelength ``lambda`` and channel ``c`` (the mean of a central ``region`` of each CFA plane; G = both green
planes)::

    rate_c(lambda)  = (mean_c(frames at t) - mean_c(darks at t)) / t          DN/s, t the wavelength's exposure
    CSRF_c(lambda)  = rate_c(lambda) / L(lambda)                              eq 4.1, per unit exposure time
    normalised      = CSRF_c / max_lambda CSRF_green                          (the green maximum is 1)

``L`` is the radiance reference at the set wavelength (simulation.radiance_reference). The thesis used one
exposure for every wavelength; here each wavelength has its own (metered, in the linear range), so the signal is
divided by its exposure time.

Standard uncertainty (k = 1) per wavelength and channel, propagated to the normalised value:

* signal: the larger of the pixel noise of the mean (pixel standard deviation / sqrt(pixels x frames)) and the
  frame repeatability (standard deviation of the frame means / sqrt(frames)), combined in quadrature with the
  dark's (standard deviation of the dark frames' means / sqrt(darks));
* radiance: the reference's relative uncertainty (from its file; 0 when it gives none);
* the normaliser's own uncertainty is not propagated (it scales every value alike).
"""
from __future__ import annotations

import logging
import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.core.protocols import Session
from dualrgb.core.vocabulary import Role, exposure_key, format_exposure
from dualrgb.drivers.raw import RawFrame, load_raw
from dualrgb.simulation.datasets import CAMERA_UNCERTAINTY_COLUMNS
from dualrgb.simulation.radiance_reference import RadianceReference
from dualrgb.simulation.spectral_io import write_spectral_csv
from dualrgb.simulation.versions import dualrgb_version

log = logging.getLogger(__name__)

CHANNELS = ("red", "green", "blue")
NORMALISATION = "green maximum = 1"
LOW_SIGNAL_DN = 20.0               # a channel below this (mean above dark) is flagged: in the noise


@dataclass(frozen=True)
class FrameStats:
    """Per channel (R, G, B) over the central region, black subtracted: mean, pixel standard deviation, pixels."""

    mean: np.ndarray
    sd: np.ndarray
    pixels: np.ndarray


def frame_stats(frame: RawFrame, region: float = 0.3) -> FrameStats:
    """The central ``region`` (fraction of each side) of every CFA plane, greens pooled."""
    h, w = frame.mosaic.shape
    r0, r1 = int(h * (1 - region) / 2) // 2 * 2, int(h * (1 + region) / 2) // 2 * 2
    c0, c1 = int(w * (1 - region) / 2) // 2 * 2, int(w * (1 + region) / 2) // 2 * 2
    planes: dict[str, list[np.ndarray]] = defaultdict(list)
    for name, (r, c), idx in frame.channels():
        plane = frame.mosaic[r0 + r:r1:2, c0 + c:c1:2].astype(np.float64) - frame.black_levels[idx]
        planes[name[0]].append(plane.ravel())
    values = [np.concatenate(planes[k]) for k in "RGB"]
    if any(v.size < 2 for v in values):
        raise ValueError(f"{frame.path}: the central region {region:g} of a {w}x{h} frame holds too few pixels")
    return FrameStats(np.array([v.mean() for v in values]), np.array([v.std(ddof=1) for v in values]),
                      np.array([float(v.size) for v in values]))


@dataclass(frozen=True)
class WavelengthSignal:
    """The dark-subtracted signal rate at one set wavelength (per channel R, G, B)."""

    wavelength_nm: float
    exposure_s: float
    level_dn: np.ndarray          # mean above the dark, DN
    rate: np.ndarray              # DN/s
    u_rate: np.ndarray            # standard uncertainty, DN/s
    frames: int
    dark_frames: int


def _mean_and_u(stats: list[FrameStats]) -> tuple[np.ndarray, np.ndarray]:
    """Mean over frames and its standard uncertainty: max(pixel noise, frame repeatability)."""
    means = np.array([s.mean for s in stats])
    n = len(stats)
    pixel = np.mean([s.sd for s in stats], axis=0) / np.sqrt(np.sum([s.pixels for s in stats], axis=0))
    repeat = means.std(axis=0, ddof=1) / math.sqrt(n) if n > 1 else np.zeros(3)
    return means.mean(axis=0), np.maximum(pixel, repeat)


def _stats(session: Session, entries: list, region: float) -> list[FrameStats]:
    return [frame_stats(load_raw(session.file_path(e)), region) for e in entries]


def session_signals(session: Session, region: float = 0.3) -> list[WavelengthSignal]:
    """Every wavelength's signal rate in a CSRF session, in wavelength order (frames checked intact first)."""
    frames = session.entries(Role.CSRF.value)
    darks = session.entries(Role.DARK.value)
    if not frames:
        raise ValueError(f"{session.path}: no monochromatic frames (role {Role.CSRF.value!r}): not a CSRF session, "
                         "or the sweep has not started")
    session.require_intact(frames + darks)
    by_exposure: dict[str, list] = defaultdict(list)
    for e in darks:
        by_exposure[exposure_key(e.exposure())].append(e)
    by_wavelength: dict[float, list] = defaultdict(list)
    for e in frames:
        by_wavelength[float(e.meta["wavelength_nm"])].append(e)
    dark_cache: dict[str, tuple[np.ndarray, np.ndarray, int]] = {}
    out = []
    for nm in sorted(by_wavelength):
        entries = by_wavelength[nm]
        t = float(entries[0].exposure_s)
        key = exposure_key(t)
        if key not in dark_cache:
            if not by_exposure.get(key):
                raise ValueError(f"{session.path}: no dark frames at {format_exposure(t)} (used at {nm:g} nm): "
                                 "resume the measurement to take them")
            dark_mean, dark_u = _mean_and_u(_stats(session, by_exposure[key], region))
            dark_cache[key] = (dark_mean, dark_u, len(by_exposure[key]))
        dark_mean, dark_u, n_dark = dark_cache[key]
        mean, u = _mean_and_u(_stats(session, entries, region))
        level = mean - dark_mean
        out.append(WavelengthSignal(nm, t, level, level / t, np.hypot(u, dark_u) / t, len(entries), n_dark))
    return out


@dataclass
class CsrfResult:
    """The measured relative spectral sensitivity (normalised: :data:`NORMALISATION`) with its uncertainty."""

    wavelengths: np.ndarray                  # (n,) nm
    values: np.ndarray                       # (n, 3) R, G, B
    uncertainty: np.ndarray                  # (n, 3) standard uncertainty, same scale
    exposures: np.ndarray                    # (n,) s
    low_signal: np.ndarray                   # (n, 3) bool: below LOW_SIGNAL_DN above the dark
    normaliser: float                        # DN/s per radiance unit of the green maximum
    radiance: dict[str, str] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"wavelength_nm": self.wavelengths.tolist(), "normalisation": NORMALISATION,
                **{c: self.values[:, i].tolist() for i, c in enumerate(CHANNELS)},
                **{u: self.uncertainty[:, i].tolist() for i, u in enumerate(CAMERA_UNCERTAINTY_COLUMNS)},
                "exposure_s": self.exposures.tolist(),
                "low_signal": {c: [float(w) for w in self.wavelengths[self.low_signal[:, i]]]
                               for i, c in enumerate(CHANNELS)},
                **self.radiance}


def compute_csrf(signals: list[WavelengthSignal], radiance: RadianceReference) -> CsrfResult:
    """Eq 4.1 per wavelength and channel, normalised so the green maximum is 1 (module docstring).

    Parameters
    ----------
    signals
        The dark-subtracted signal rates per set wavelength (:func:`session_signals`).
    radiance
        The monochromator's radiance at those wavelengths (its relative uncertainty is propagated).

    Returns
    -------
    CsrfResult
        Relative sensitivities (n, 3), their standard uncertainties, exposures and low-signal flags.

    References
    ----------
    Thesis *High Dynamic Range Imaging for Dual-RGB System for Cultural Heritage*, 4.2, eq 4.1.
    """
    wl = np.array([s.wavelength_nm for s in signals])
    ref = [radiance.at(nm) for nm in wl]
    L = np.array([v for v, _ in ref])[:, None]
    u_L = np.array([u for _, u in ref])[:, None]
    rate = np.array([s.rate for s in signals])
    u_rate = np.array([s.u_rate for s in signals])
    raw = rate / L
    u_raw = np.hypot(u_rate / L, raw * u_L)
    norm = float(raw[:, 1].max())
    if not norm > 0:
        raise ValueError("the green channel never rose above its dark: no light reached the camera (shutter, "
                         "lens cap, monochromator lamp?)")
    low = np.array([s.level_dn for s in signals]) < LOW_SIGNAL_DN
    return CsrfResult(wl, raw / norm, u_raw / norm, np.array([s.exposure_s for s in signals]), low, norm,
                      radiance.describe())


def write_camera_csv(result: CsrfResult, path: str | Path, provenance: dict[str, str]) -> Path:
    """The project's camera CSV (simulation/spectral_io.py): ``# key: value`` provenance, then
    ``wavelength_nm,red,green,blue,u_red,u_green,u_blue``; readable by ``simulate --camera-csv``. Estimates below
    zero (noise where the camera does not respond) are written as 0; their uncertainty is kept."""
    wl = result.wavelengths
    meta = {"title": "camera relative spectral sensitivity, measured with a monochromator",
            "units": f"relative spectral sensitivity ({NORMALISATION}); u_*: standard uncertainty (k = 1)",
            "method": "thesis 4.2 eq 4.1: dark-subtracted mean of the central region / exposure time / radiance",
            **provenance,
            "range": f"{wl[0]:g}-{wl[-1]:g} nm, step {(wl[1] - wl[0]) if len(wl) > 1 else 0:g} nm",
            "exposures": f"{format_exposure(float(result.exposures.min()))} to "
                         f"{format_exposure(float(result.exposures.max()))} (metered per wavelength)",
            **result.radiance,
            "low_signal": "; ".join(f"{c}: {_ranges(wl[result.low_signal[:, i]])}"
                                    for i, c in enumerate(CHANNELS) if result.low_signal[:, i].any()) or "none",
            "dualrgb": dualrgb_version(),
            "generated_by": "dualrgb measure csrf (app/processing/csrf.py)"}
    values = np.column_stack([np.maximum(result.values, 0.0), result.uncertainty])
    write_spectral_csv(path, wl, values, [*CHANNELS, *CAMERA_UNCERTAINTY_COLUMNS], meta)
    log.info("camera CSV written: %s", path)
    return Path(path)


def _ranges(wavelengths: np.ndarray) -> str:
    return ", ".join(f"{w:g}" for w in wavelengths[:12]) + (" ..." if len(wavelengths) > 12 else "") + " nm"


def rms_error_percent(result: CsrfResult, wavelengths: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """RMS error per channel in % of that channel's peak, against ``truth`` (n, 3) at ``wavelengths`` normalised
    the same way (green maximum = 1), over the truth's wavelengths inside the measured range (the virtual lab's
    check: the curves the camera renders with)."""
    t = np.asarray(truth, dtype=float) / float(np.max(truth[:, 1]))
    inside = (wavelengths >= result.wavelengths[0] - 1e-6) & (wavelengths <= result.wavelengths[-1] + 1e-6)
    out = {}
    for i, c in enumerate(CHANNELS):
        measured = np.interp(wavelengths[inside], result.wavelengths, result.values[:, i])
        err = measured - t[inside, i]
        out[c] = float(100 * np.sqrt(np.mean(err ** 2)) / t[inside, i].max())
    return out
