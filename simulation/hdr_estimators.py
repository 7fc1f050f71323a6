"""HDR merge estimators: how exposures of one scene combine into one radiance (DN/s), numpy reference.

Every estimator sees, per pixel and exposure e, the dark-subtracted signal x_e (DN), the exposure time t_e (s)
and whether the raw value was usable (at most the sensor's linear limit and below the white level). Methods
(``HDR_MERGE_METHODS``, dispatched by name as colour-science's ``*_METHODS``):

``"thesis"``  eq 8.9 of the thesis (Dual-RGB HDR thesis, chapter 8.2.2): w_e = triangle(x_e / span), the
    weight of the measured signal, E = sum w_e x_e / t_e / sum w_e. The weight grows with the measured signal and
    ignores the exposure time, so it is biased upwards at low signal: a short exposure's positive read-noise
    excursions get weight *and* a large per-second value (bias chart: ``dualrgb study hdr``).
``"variance"``  variance-optimal weights, Granados et al. (2010): w_e = t_e^2 / var(x_e), with
    var(x_e) = max(E0, 0) t_e / g + sigma^2 (shot noise at g electrons per DN, read noise sigma DN) evaluated at
    the pooled estimate E0 = sum x_e / sum t_e (the maximum-likelihood radiance under photon noise) instead of
    each exposure's own measurement, so the weights do not follow the noise they average: unbiased. Where shot
    noise dominates the weights are ~t (E = E0); in read-noise-limited shadows ~t^2, so the long exposure
    dominates and the short one adds little of its read noise.

Shared rules, both methods: frames of one exposure time are averaged first (over their usable frames), as the
thesis merges one image per exposure time (for the variance weights this is exact, for eq 8.9 it weights the mean
frame by the number of frames); a pixel no usable exposure reaches (above the linear limit or clipped in every
exposure) takes the shortest exposure's value and is counted as clipped; a pixel whose usable exposures all
have zero weight (eq 8.9 at signal <= 0: dark pixels) takes the longest usable exposure's value and is *not*
clipped. One exposure gives exactly x / t.

The fused numba kernels of the processing pipeline (app/processing/kernels.py) implement the same rules and are
tested against this module. References: Granados, M., Ajdin, B., Wand, M., Theobalt, C., Seidel, H.-P.,
Lensch, H. P. A. (2010), "Optimal HDR reconstruction with linear digital cameras", CVPR 2010, 215-222;
Robertson, Borman, Stevenson (2003), "Estimation-theoretic approach to dynamic range enhancement using
multiple exposures", J. Electronic Imaging 12(2) (weights t^2 / variance).
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

log = logging.getLogger(__name__)

HDR_THESIS = "thesis"
HDR_VARIANCE = "variance"
HDR_METHOD_CODES = {HDR_THESIS: 0, HDR_VARIANCE: 1}       # the kernels' integer codes


@dataclass(frozen=True)
class HdrNoise:
    """Sensor noise for the variance-optimal weights (defaults: the D610-like sensor of the virtual lab at ISO 50,
    drivers/virtual/camera.py). Any positive values leave the estimate unbiased; they only set where the weights
    turn from t (shot-noise limited) to t^2 (read-noise limited): at g sigma^2 = 50 DN of signal here."""

    read_noise_dn: float = 2.5
    electrons_per_dn: float = 8.0

    def __post_init__(self) -> None:
        if not (self.read_noise_dn > 0 and self.electrons_per_dn > 0):
            raise ValueError(f"HDR noise model: read noise {self.read_noise_dn} DN and gain "
                             f"{self.electrons_per_dn} e-/DN must both be positive")

    @property
    def read_variance(self) -> float:
        """DN^2 of one dark-subtracted frame: read noise plus quantisation (1/12 DN^2)."""
        return self.read_noise_dn ** 2 + 1.0 / 12.0


def triangle_weight(signal: np.ndarray, full_scale: float, out: np.ndarray | None = None) -> np.ndarray:
    """Eq 8.9 on a 0..1 scale: u = signal / full_scale, w = min(u, 1 - u) clipped at 0; float32."""
    if out is None:
        out = np.empty(np.shape(signal), dtype=np.float32)
    np.multiply(signal, np.float32(1.0 / full_scale), out=out, casting="unsafe")
    np.minimum(out, np.float32(1.0) - out, out=out)
    np.maximum(out, np.float32(0.0), out=out)
    return out


def _thesis_weights(xbar: np.ndarray, n: np.ndarray, t: np.ndarray, span: float, noise: HdrNoise) -> np.ndarray:
    """Eq 8.9 on each exposure time's mean frame, with the weight of its n usable frames."""
    return n * triangle_weight(xbar, span)


def _variance_weights(xbar: np.ndarray, n: np.ndarray, t: np.ndarray, span: float, noise: HdrNoise
                      ) -> np.ndarray:
    """n t^2 / var at the pooled estimate E0 = sum of usable signal / sum of usable exposure time."""
    tt = t.reshape((-1,) + (1,) * (xbar.ndim - 1))
    st = np.sum(n * tt, axis=0)
    e0 = np.sum(n * xbar, axis=0) / np.where(st > 0, st, 1.0)
    var = np.maximum(e0, 0.0)[None] * tt / noise.electrons_per_dn + noise.read_variance
    return n * tt * tt / var


HDR_MERGE_METHODS: dict[str, Callable[..., np.ndarray]] = {
    HDR_THESIS: _thesis_weights,
    HDR_VARIANCE: _variance_weights,
}


def check_method(method: str) -> str:
    if method not in HDR_MERGE_METHODS:
        raise ValueError(f"HDR merge method {method!r}: expected one of {', '.join(HDR_MERGE_METHODS)}")
    return method


def _by_exposure_time(x: np.ndarray, usable: np.ndarray, t: np.ndarray):
    """Frames grouped by exposure time (equal within 0.1 %), shortest first: per group the mean of the usable
    frames, their number, and the mean of all frames (the fallback where none is usable)."""
    order = np.argsort(t, kind="stable")
    groups: list[list[int]] = []
    for k in order:
        if groups and t[k] <= t[groups[-1][0]] * (1 + 1e-3):
            groups[-1].append(int(k))
        else:
            groups.append([int(k)])
    n = np.stack([usable[g].sum(axis=0) for g in groups]).astype(float)
    s = np.stack([(x[g] * usable[g]).sum(axis=0) for g in groups])
    xbar = s / np.maximum(n, 1.0)
    every = np.stack([x[g].mean(axis=0) for g in groups])
    return xbar, n, every, np.array([t[g[0]] for g in groups])


def merge_exposures(x: np.ndarray, usable: np.ndarray, exposures, method: str = HDR_THESIS, *, span: float,
                    noise: HdrNoise = HdrNoise()) -> tuple[np.ndarray, np.ndarray]:
    """Merge K frames: ``x`` (K, ...) dark-subtracted DN, ``usable`` (K, ...) bool, ``exposures`` (K,) s;
    ``span`` the usable raw range (white - black level, eq 8.9's full scale). Returns (radiance in DN/s, clipped
    mask). Frames of one exposure time are averaged first (their usable frames), as the thesis merges one image
    per exposure time. Float64; the shared rules of the module docstring apply."""
    x = np.asarray(x, dtype=float)
    usable = np.asarray(usable, dtype=bool)
    t = np.asarray(exposures, dtype=float)
    if x.shape != usable.shape or x.shape[0] != len(t):
        raise ValueError(f"{len(t)} exposure times, signals {x.shape} and usable masks {usable.shape} disagree")
    if np.any(t <= 0):
        raise ValueError(f"exposure times must be positive, got {t.tolist()}")
    xbar, n, every, tg = _by_exposure_time(x, usable, t)
    w = HDR_MERGE_METHODS[check_method(method)](xbar, n, tg, span, noise)
    tt = tg.reshape((-1,) + (1,) * (x.ndim - 1))
    per_s = xbar / tt
    den = w.sum(axis=0)
    num = (w * per_s).sum(axis=0)
    any_usable = n.sum(axis=0) > 0
    has = n > 0
    last = (has.shape[0] - 1) - np.argmax(has[::-1], axis=0)               # longest exposure time with usable frames
    longest = np.take_along_axis(per_s, last[None], axis=0)[0]
    fallback = np.where(any_usable, longest, every[0] / tg[0])
    radiance = np.where(den > 0, num / np.where(den > 0, den, 1.0), fallback)
    return radiance, ~any_usable


def default_method(mode: str | None) -> str:
    """The estimator ``dualrgb study hdr`` chose for ``mode`` (resources/parsimony.json, key ``hdr_merge``).
    ``mode`` None (a merge that does not know what it images: the bare HdrMerge of a test): the choice both
    modes share; ValueError when they differ, so no caller silently takes the other mode's estimator."""
    from dualrgb.simulation.choices import MODES
    from dualrgb.simulation.defaults import load_defaults

    if mode is None:
        chosen = {m: default_method(m) for m in MODES}
        if len(set(chosen.values())) > 1:
            raise ValueError(f"the HDR merge default differs by mode ({chosen}): pass the mode")
        return chosen[MODES[0]]
    method = load_defaults(mode).get("hdr_merge", HDR_THESIS)
    if method not in HDR_MERGE_METHODS:
        log.warning("parsimony defaults name HDR merge %r for %s, unknown here; using %s", method, mode, HDR_THESIS)
        return HDR_THESIS
    return method
