"""Qt-free helpers that turn driver / simulation results into what the panels draw (tested without Qt).

Nothing here decides anything about the capture: it mixes spectra for display, bins raw values for the
histogram, adds up the light dose shown next to the on/off switch, formats times and calibrations, and keeps the
best light set a search has found so far.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualrgb.app.gui.units import dn, light_pct, percent, shutters
from dualrgb.app.processing.hdr import LINEAR_LIMIT_DN  # the one linear limit (thesis 4.1), used everywhere
from dualrgb.common.formatting import format_duration  # noqa: F401 - one formatting, shared with the CLI
from dualrgb.core.session.light_dose import LightDose
from dualrgb.simulation.lightsource import LightSource


def light_from_levels(levels: Sequence[float] | np.ndarray, name: str = "") -> LightSource:
    """Ten slider levels -> a LightSource (LEDs at 0 are left out; an all-zero light lists LED 1 at 0)."""
    leds = tuple(i + 1 for i, v in enumerate(levels) if v > 0)
    if not leds:
        return LightSource((1,), (0.0,), name)
    return LightSource(leds, tuple(float(levels[i - 1]) for i in leds), name)


def mixed_spectrum(levels: Sequence[float] | np.ndarray, led_spectra: np.ndarray) -> np.ndarray:
    """The sphere's output for ``levels`` by superposition (thesis 3.1.2): (n_wl,)."""
    return light_from_levels(levels).spectrum(led_spectra)


@dataclass
class RawHistogram:
    edges: np.ndarray                 # (bins + 1,) DN
    counts: dict[str, np.ndarray]     # channel letter -> (bins,)
    white_level: float
    linear_limit: float
    fraction_clipped: float           # pixels at or above the white level
    fraction_nonlinear: float         # pixels above the linear limit (clipped included)
    max_dn: float

    def summary(self) -> str:
        return (f"max {dn(self.max_dn)}; {percent(self.fraction_nonlinear)} above the linear limit "
                f"({dn(self.linear_limit)}); {percent(self.fraction_clipped)} clipped (white level "
                f"{dn(self.white_level)})")


def raw_histogram(planes: dict[str, np.ndarray], white_level: float, linear_limit: float = LINEAR_LIMIT_DN,
                  bins: int = 128) -> RawHistogram:
    """Histogram of raw DN per channel (black not subtracted, as the thresholds are in raw DN)."""
    top = max(float(white_level) * 1.05, 1.0)
    edges = np.linspace(0.0, top, bins + 1)
    counts, n, clipped, nonlinear, mx = {}, 0, 0, 0, 0.0
    for name, plane in planes.items():
        v = np.asarray(plane, dtype=np.float64).ravel()
        counts[name] = np.histogram(v, edges)[0]
        n += v.size
        clipped += int(np.count_nonzero(v >= white_level))
        nonlinear += int(np.count_nonzero(v > linear_limit))
        mx = max(mx, float(v.max()) if v.size else 0.0)
    return RawHistogram(edges, counts, float(white_level), float(linear_limit),
                        clipped / n if n else 0.0, nonlinear / n if n else 0.0, mx)


class DoseFeed:
    """Feeds core.session.light_dose.LightDose from the panel's status polls (levels and light switch as the sphere
    reports them): the light shown between two polls is counted for the time between them."""

    def __init__(self) -> None:
        self.dose = LightDose()
        self._last_t: float | None = None
        self._last_light: LightSource | None = None

    def update(self, t: float, light_on: bool, levels: Sequence[float]) -> LightDose:
        if self._last_t is not None and self._last_light is not None:
            self.dose.add(self._last_light, max(0.0, t - self._last_t))
        self._last_t = t
        self._last_light = light_from_levels(levels) if light_on else None
        return self.dose

    def reset(self) -> None:
        self.dose = LightDose()
        self._last_t = None
        self._last_light = None


def display_rgb(linear: np.ndarray, full_scale: float | None = None, gamma: float = 2.2) -> np.ndarray:
    """Linear camera RGB (H, W, 3) -> uint8 for the screen: scaled to ``full_scale`` (default: 99.5th
    percentile), gamma-encoded. For looking at frames only; nothing measured comes from it."""
    img = np.nan_to_num(np.asarray(linear, dtype=np.float32), nan=0.0)
    scale = float(full_scale) if full_scale else float(np.percentile(img, 99.5)) or 1.0
    img = np.clip(img / max(scale, 1e-12), 0.0, 1.0) ** (1.0 / gamma)
    return (img * 255.0 + 0.5).astype(np.uint8)


@dataclass
class RawView:
    """One raw frame as the panels show it: picture, DN histogram, what the camera recorded, and its check (dark,
    clipped: app.workflow.calibration.frame_checks)."""

    image: np.ndarray                  # (H/2, W/2, 3) uint8
    histogram: RawHistogram
    path: str
    exposure_s: float | None
    iso: float | None
    camera: str
    check: Any = None                  # app.workflow.calibration.frame_checks.FrameCheck


def raw_view(path) -> RawView:
    """Load a raw file (drivers.raw) and make its picture and DN histogram (run in a worker)."""
    from dualrgb.app.workflow.calibration.frame_checks import check_frame
    from dualrgb.drivers.raw import load_raw, superpixel

    frame = load_raw(path)
    planes = {name: frame.plane(name) for name, _, _ in frame.channels()}
    hist = raw_histogram(planes, frame.white_level)
    black = float(np.mean(frame.black_levels))
    image = display_rgb(superpixel(frame), full_scale=frame.white_level - black)
    return RawView(image, hist, str(path), frame.exposure_s, frame.iso, frame.camera, check_frame(frame))


class ConvergenceTap:
    """Wraps the objective's evaluator (simulation.runner.make_evaluator) for the live convergence plot: after
    every cost batch it calls ``on_batch(evaluations, best_cost_so_far)`` (from the worker thread) and keeps the
    best light set seen, so a cancelled search still has its best so far (:meth:`partial`). Costs are unchanged;
    everything else is the wrapped evaluator's."""

    def __init__(self, inner, on_batch) -> None:
        self._inner = inner
        self._on_batch = on_batch
        self.best = math.inf
        self.best_idx: np.ndarray | None = None       # (L, m) 0-based LED indices of the best set so far
        self.best_w: np.ndarray | None = None         # (L, m) its levels

    @staticmethod
    def make(setup, on_batch, objective: str = "expected-captured") -> ConvergenceTap:
        from dualrgb.simulation.runner import make_evaluator

        return ConvergenceTap(make_evaluator(setup, objective), on_batch)

    def __getattr__(self, name):
        return getattr(self._inner, name)

    @property
    def base(self):
        """The wrapped evaluator (simulation.runner.run warms its kernels up)."""
        return self._inner

    @property
    def evaluations(self) -> int:                 # read and written through (simulation.warmup restores it)
        return self._inner.evaluations

    @evaluations.setter
    def evaluations(self, value: int) -> None:
        self._inner.evaluations = value

    def cost_indexed(self, idx, w):
        costs = self._inner.cost_indexed(idx, w)
        if len(costs):
            k = int(np.nanargmin(costs)) if np.isfinite(costs).any() else -1
            if k >= 0 and float(costs[k]) < self.best:
                self.best = float(costs[k])
                self.best_idx, self.best_w = np.array(idx[k]), np.array(w[k], dtype=float)
            self._on_batch(self._inner.evaluations, self.best)
        return costs

    def partial(self):
        """The best light set seen so far as a simulation.search.Candidate evaluated like a finished search's
        (simulation.search.evaluate_candidate: float64 train / test errors, expected captured ones where the
        objective has them), or None when no cost was computed yet."""
        from dualrgb.simulation.search import Candidate, evaluate_candidate

        if self.best_idx is None:
            return None
        sources = []
        for leds, levels in zip(self.best_idx, self.best_w, strict=True):
            on = levels > 0
            sources.append(LightSource(tuple(int(i) + 1 for i in leds[on]), tuple(float(v) for v in levels[on]))
                           if on.any() else LightSource((int(leds[0]) + 1,), (0.0,)))
        return evaluate_candidate(self._inner, Candidate(tuple(sources), self.best))


def preview_histogram(frame: np.ndarray, black_level: float, white_level: float, gamma: float = 2.2,
                      linear_limit: float = LINEAR_LIMIT_DN) -> RawHistogram:
    """Live-view histogram in raw DN for a preview that is encoded like the raw data (the virtual camera's:
    (DN - black) / (white - black), gamma 1/2.2). An estimate: 8-bit steps, no per-pixel noise."""
    f = np.asarray(frame, dtype=np.float64) / 255.0
    dn = black_level + f ** gamma * (white_level - black_level)
    planes = {"R": dn[..., 0], "G": dn[..., 1], "B": dn[..., 2]}
    return raw_histogram(planes, white_level, linear_limit)


def calibration_lines(profile, check=None) -> list[str]:
    """What the window says about a calibration profile: id and age, camera, lights (levels in %), exposures,
    target errors, and the last check against the stand."""
    stats = profile.statistics.get("methods", {}).get(profile.statistics.get("best", ""), {})
    train = (stats.get("train") or {}).get("mean")
    cam = profile.camera
    lines = [f"{profile.id} ({profile.preset}, {profile.mode}), made {profile.age_h():.1f} h ago",
             f"camera {cam.model or '?'}" + (f" serial {cam.serial}" if cam.serial else "")
             + f", ISO {cam.iso}, f/{cam.aperture:g}" if cam.aperture else f"camera {cam.model or '?'}, ISO {cam.iso}"]
    for nl in profile.lights:
        lines.append(f"{nl.name}: {light_pct(nl.light)}; {shutters(profile.exposures.get(nl.name, []))}")
    if train is not None or profile.test_mean is not None:
        lines.append(f"target ΔE00 train {_num(train)} / test {_num(profile.test_mean)} "
                     f"({profile.matrix.method} matrix)")
    for role, chart in (getattr(profile, "charts", None) or {}).items():
        left = f", {len(chart['left_out'])} left out" if chart.get("left_out") else ""
        lines.append(f"{'training' if role == 'train' else 'test'} chart {chart.get('file')}"
                     f"{' (packaged)' if chart.get('packaged') else ''}: {chart.get('used')} patches{left}")
    if check is not None:
        lines += [f"does not match the stand: {r}" for r in check.refusals] + list(check.warnings)
        if check.ok:
            lines.append("matches the stand (camera, ISO, aperture, sphere)")
    return lines


def _num(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.2f}"
