"""The sphere's LEDs from spectroradiometer readings (thesis 4.3): shape, level linearity, warm-up drift.

* :func:`led_shape`: peak wavelength, FWHM and integrated radiance of one LED's spectrum. The samples are
  interpolated with a cubic spline to 0.05 nm (a 5 nm instrument resolves a 23 nm-wide LED's peak to ~0.01 nm
  that way, linear interpolation of the half-maximum crossings alone is ~2 % off), the peak is the vertex of a
  least-squares parabola through the spline above 80 % of its maximum and the FWHM is the distance between the
  half-maximum crossings.
* :func:`band_output`: an LED's output in one reading, integrated over the band where its full-level spectrum
  exceeds 1 % of its peak (outside it a reading is instrument noise only).
* :func:`fit_low_level`: the level -> output curve near the bottom as a
  :class:`simulation.sphere.LowLevelResponse` (dead band, curve exponent, knee) by least squares on the relative
  error, and the *minimum stable level*: the lowest measured level from which every measured level is within
  ``tolerance`` of proportional output (what :class:`simulation.sphere.SphereProperties` needs).
* :func:`fit_drift`: the peak shift against continuous on-time as ``A (1 - exp(-(t - t0) / tau))`` for
  ``t > t0`` (none before): the form of thesis Fig 4.10's curves, rising towards a maximum within the hour.

References
----------
Thesis 4.3 (LED spectra, Fig 4.9; peak drift with on-time, Fig 4.10 and 4.3.2).
"""
from __future__ import annotations

import logging
from dataclasses import asdict, dataclass

import numpy as np
from scipy.integrate import trapezoid
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares

from dualrgb.common.strict_json import finite_or_none
from dualrgb.simulation.sphere import LowLevelResponse

log = logging.getLogger(__name__)

FINE_STEP_NM = 0.05
PEAK_FRACTION = 0.8
BAND_FRACTION = 0.01
STABLE_TOLERANCE = 0.05


@dataclass(frozen=True)
class LedShape:
    """One LED spectrum's peak wavelength and FWHM (nm), its peak value and its integral (value x nm)."""

    peak_nm: float
    fwhm_nm: float
    peak_value: float
    integral: float

    def to_dict(self) -> dict[str, float | None]:
        """As JSON: an unknown FWHM (a broadband reading that never falls to half its peak in range) is null."""
        return {k: finite_or_none(v) for k, v in asdict(self).items()}


def _fine(wavelengths: np.ndarray, spectrum: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    wl = np.asarray(wavelengths, dtype=float)
    fine = np.arange(wl[0], wl[-1] + FINE_STEP_NM / 2, FINE_STEP_NM)
    return fine, CubicSpline(wl, np.asarray(spectrum, dtype=float))(fine)


def _vertex(wl: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Peak wavelength and value: a parabola through the points above PEAK_FRACTION of the maximum."""
    i = int(np.argmax(y))
    lo = hi = i
    while lo > 0 and y[lo - 1] >= PEAK_FRACTION * y[i]:
        lo -= 1
    while hi < len(y) - 1 and y[hi + 1] >= PEAK_FRACTION * y[i]:
        hi += 1
    lo, hi = min(lo, max(i - 1, 0)), max(hi, min(i + 1, len(y) - 1))
    if hi - lo < 2:                                   # the maximum at the edge of the range
        return float(wl[i]), float(y[i])
    c = np.polyfit(wl[lo:hi + 1] - wl[i], y[lo:hi + 1], 2)
    if c[0] >= 0:
        return float(wl[i]), float(y[i])
    v = float(np.clip(-c[1] / (2 * c[0]), wl[lo] - wl[i], wl[hi] - wl[i]))
    return float(wl[i] + v), float(np.polyval(c, v))


def _crossing(wl: np.ndarray, y: np.ndarray, level: float, start: int, step: int) -> float:
    """Where ``y`` falls to ``level`` walking from index ``start`` by ``step`` (NaN if it never does)."""
    j = start
    while 0 <= j + step < len(y) and y[j + step] > level:
        j += step
    k = j + step
    if not 0 <= k < len(y):
        return float("nan")
    return float(np.interp(level, [y[k], y[j]], [wl[k], wl[j]]))


def led_shape(wavelengths: np.ndarray, spectrum: np.ndarray) -> LedShape:
    """Peak, FWHM, peak value and integral of one LED's spectrum (module docstring).

    Parameters
    ----------
    wavelengths : (n,) nm, increasing (any regular or irregular sampling).
    spectrum : (n,) spectral radiance (or relative) at ``wavelengths``.

    Returns
    -------
    LedShape; ``fwhm_nm`` is NaN when the spectrum does not fall to half its peak on both sides in range.
    """
    fine, y = _fine(wavelengths, spectrum)
    peak, top = _vertex(fine, y)
    i = int(np.argmax(y))
    fwhm = _crossing(fine, y, top / 2, i, +1) - _crossing(fine, y, top / 2, i, -1)
    return LedShape(peak, fwhm, top, float(trapezoid(np.asarray(spectrum, float), wavelengths)))


def led_band(spectrum_full: np.ndarray, fraction: float = BAND_FRACTION) -> np.ndarray:
    """Boolean mask of the samples where an LED's full-level spectrum exceeds ``fraction`` of its peak."""
    s = np.asarray(spectrum_full, dtype=float)
    return s > fraction * s.max()


def band_output(wavelengths: np.ndarray, spectrum: np.ndarray, band: np.ndarray) -> float:
    """An LED's output in one reading: the spectrum integrated (trapezoid) over ``band`` (led_band)."""
    wl = np.asarray(wavelengths, dtype=float)
    return float(trapezoid(np.where(band, np.asarray(spectrum, dtype=float), 0.0), wl))


# ---- level linearity ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LevelFit:
    """The fitted low-level response, its rms relative residual, and the minimum stable level (measured points
    and fitted curve) for ``tolerance`` (relative departure from proportional output)."""

    response: LowLevelResponse
    rms_relative: float
    min_stable_level: float
    min_stable_level_fit: float
    tolerance: float

    def to_dict(self) -> dict:
        return {**self.response.to_dict(), "rms_relative": self.rms_relative,
                "min_stable_level": self.min_stable_level, "min_stable_level_fit": self.min_stable_level_fit,
                "tolerance": self.tolerance}


def min_stable_level(levels: np.ndarray, outputs: np.ndarray, tolerance: float = STABLE_TOLERANCE) -> float:
    """The lowest non-zero level from which every level at or above it gives ``outputs`` within ``tolerance``
    of proportional (output / level within 1 +- tolerance); 1.0 when even full level is off."""
    lv, y = np.asarray(levels, dtype=float), np.asarray(outputs, dtype=float)
    keep = lv > 0
    order = np.argsort(lv[keep])
    lv, y = lv[keep][order], y[keep][order]
    good = np.abs(y / lv - 1.0) <= tolerance
    best = 1.0
    for i in range(len(lv) - 1, -1, -1):
        if not good[i]:
            break
        best = float(lv[i])
    return best


def _residuals(x: np.ndarray, lv: np.ndarray, y: np.ndarray) -> np.ndarray:
    d, e, p = x
    model = LowLevelResponse(d, d + e, p).output(lv)
    return (np.asarray(model) - y) / (lv + 0.002)          # relative error; 0.002 keeps the dead band finite


def fit_low_level(levels: np.ndarray, outputs: np.ndarray, tolerance: float = STABLE_TOLERANCE,
                  max_level: float = 0.3) -> LevelFit:
    """Fit :class:`LowLevelResponse` to relative outputs (output at level / output at full level).

    Parameters
    ----------
    levels, outputs : (n,) PWM levels 0..1 and the measured relative outputs; levels above ``max_level`` are
        left out of the fit (but count for the minimum stable level).
    tolerance : relative departure from proportional output that still counts as stable.

    Returns
    -------
    LevelFit
    """
    lv, y = np.asarray(levels, dtype=float), np.asarray(outputs, dtype=float)
    sel = lv <= max_level
    if sel.sum() < 4:
        raise ValueError(f"level linearity: {int(sel.sum())} readings at or below level {max_level:g}; "
                         "expected at least 4 (measure the low end finely, e.g. 0.2 %..5 %)")
    best = None
    for d0 in (0.0, 0.005, 0.01):
        for e0, p0 in ((0.02, 1.0), (0.04, 1.5), (0.08, 2.5)):
            r = least_squares(_residuals, [d0, e0, p0], bounds=([0.0, 0.0, 0.2], [0.2, 0.5, 5.0]),
                              args=(lv[sel], y[sel]), x_scale=[0.01, 0.01, 1.0])
            if best is None or r.cost < best.cost:
                best = r
    assert best is not None
    d, e, p = (float(v) for v in best.x)
    response = LowLevelResponse(d, d + e if e > 1e-6 else d, p)
    fine = np.arange(1, int(round(max_level * 1e4)) + 1) / 1e4
    fit_stable = min_stable_level(fine, np.asarray(response.output(fine)), tolerance)
    rms = float(np.sqrt(np.mean(_residuals(best.x, lv[sel], y[sel]) ** 2)))
    return LevelFit(response, rms, min_stable_level(lv, y, tolerance), fit_stable, tolerance)


# ---- warm-up drift -----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DriftFit:
    """Peak shift against continuous on-time: ``max_shift_nm * (1 - exp(-(t - onset_s) / tau_s))`` after
    ``onset_s`` (none before); ``rms_nm``: the residual of the measured shifts."""

    max_shift_nm: float
    tau_s: float
    onset_s: float
    rms_nm: float

    def shift(self, t_s: np.ndarray | float) -> np.ndarray:
        t = np.maximum(np.asarray(t_s, dtype=float) - self.onset_s, 0.0)
        return self.max_shift_nm * -np.expm1(-t / self.tau_s)

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


def fit_drift(times_s: np.ndarray, shifts_nm: np.ndarray, max_onset_s: float = 120.0) -> DriftFit:
    """Fit :class:`DriftFit` to measured peak shifts (nm, against the first reading) at on-times ``times_s``.

    Parameters
    ----------
    times_s, shifts_nm : (n,) seconds continuously on and the measured peak shift.
    max_onset_s : the latest onset considered.

    Returns
    -------
    DriftFit; an LED that does not drift gets ``max_shift_nm`` ~0 (its ``tau_s`` then means nothing).
    """
    t, s = np.asarray(times_s, dtype=float), np.asarray(shifts_nm, dtype=float)
    if len(t) < 4:
        raise ValueError(f"warm-up: {len(t)} readings; expected at least 4 (spectra every N s for M minutes)")
    span = float(t.max() - t.min()) or 1.0

    def resid(x: np.ndarray) -> np.ndarray:
        return DriftFit(x[0], x[1], x[2], 0.0).shift(t) - s

    a0 = float(s[np.argmax(np.abs(s))])
    best = None
    for tau0 in (span / 8, span / 3, span):
        r = least_squares(resid, [a0 or 0.1, tau0, 5.0], bounds=([-30.0, 1.0, 0.0], [30.0, 100 * span, max_onset_s]),
                          x_scale=[1.0, span / 4, 10.0])
        if best is None or r.cost < best.cost:
            best = r
    assert best is not None
    a, tau, t0 = (float(v) for v in best.x)
    return DriftFit(a, tau, t0, float(np.sqrt(np.mean(resid(best.x) ** 2))))
