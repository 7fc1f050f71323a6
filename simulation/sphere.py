"""What the LED sphere can actually hold: level resolution and the minimum stable level (one home for both).

The sphere sets each LED by 16-bit PWM (docs/led-sphere-protocol.md: level 1.0 = PWM 65 535), so a level is a
multiple of 1/65 535. LED drivers do not hold very small duty cycles stably (the current regulator drops out,
the output flickers or drifts), so the sphere's settings name a *minimum stable level*: a level is either 0 or
at least that. The optimisers' levels are continuous; :meth:`SphereProperties.realise` maps them to what the
sphere will emit, and the expected-captured objective scores that, so no preset relies on a trace level
(issue 14: LED 1 at 0.0022 in the reflective PSO optimum, PWM 20 of 65 535 in the transmissive one).

``min_stable_level`` = 1 % is an assumption for a typical constant-current PWM LED driver (not measured on the
thesis' sphere); a stand measurement (``dualrgb measure leds`` / ``import-leds``, simulation/led_fit.py) gives the
measured value, which ``simulate --stand-dir`` uses instead. :class:`LowLevelResponse` is the model of how an LED's
output follows its level near the bottom (a dead band, then a curve up to a knee): the virtual lab's worlds
render with it and the stand measurement fits it.

**One model of the sphere's levels** (issue 29): :class:`SphereProperties` answers two questions, each in one
method, for the fit, the calibration's prediction, ``simulate --stand`` and the optimisers alike:

* :meth:`SphereProperties.realise`: which levels a *search* may set for new lights (0 or at least the minimum
  stable level, on the PWM grid);
* :meth:`SphereProperties.emitted`: what each LED *emits*, relative to its full output, at levels as the sphere
  set them: the PWM grid, then the LED's measured level -> output curve (:class:`LevelCurve`, from a stand
  folder's stand.json) or, where none was measured, the nominal proportional response. Nothing is forbidden
  there: a captured LED below the minimum stable level is predicted with the output its curve gives, never
  rounded off (LED 1 at 0.01 with a measured minimum of 0.04 emits 0.2 % of its full output, not 0).

A search scores ``emitted(realise(levels))``; a light already captured is scored with ``emitted(levels)``
(:meth:`SphereProperties.as_captured`: the same sphere with no level forbidden).
"""
from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)

PWM_MAX = 65535


@dataclass(frozen=True)
class LowLevelResponse:
    """How an LED's output follows its PWM level near the bottom (relative to full output = 1).

    ``level <= dead_band``: no output; ``dead_band < level < knee``: ``knee * ((level - dead_band) / (knee -
    dead_band)) ** exponent`` (a curve meeting the proportional response at the knee); ``level >= knee``:
    proportional (output = level). ``dead_band = knee = 0`` is the ideal driver (the nominal model).
    """

    dead_band: float = 0.0
    knee: float = 0.0
    exponent: float = 1.0

    @property
    def identity(self) -> bool:
        return self.knee <= 0.0 and self.dead_band <= 0.0

    def output(self, levels: np.ndarray) -> np.ndarray:
        """Relative output for ``levels`` (any shape, 0..1); the same array object when the response is ideal."""
        if self.identity:
            return levels
        lv = np.asarray(levels, dtype=float)
        d, k = self.dead_band, max(self.knee, self.dead_band)
        out = lv.copy()
        low = lv < k
        if k > d:
            x = np.clip((lv[low] - d) / (k - d), 0.0, None)
            out[low] = k * x ** self.exponent
        else:
            out[low] = 0.0
        return out

    def to_dict(self) -> dict[str, float]:
        return {"dead_band": self.dead_band, "knee": self.knee, "exponent": self.exponent}


@dataclass(frozen=True)
class LevelCurve:
    """One LED's measured level -> output curve: ``levels`` (increasing, in (0, 1]) and ``outputs`` (its output
    there relative to its full output; stand.json's ``level`` / ``relative_output``).

    :meth:`output` interpolates linearly between the measured points through (0, 0) (a level of 0 is off) and is
    proportional above the last point (its output / level ratio). The points themselves are used, not a fitted
    curve: the measurement steps finely through the low end (0.2 % steps to 1 %, app/sequences/led_measurement.py),
    where a fitted form would be one more model.
    """

    levels: tuple[float, ...]
    outputs: tuple[float, ...]

    def __post_init__(self) -> None:
        lv, out = np.asarray(self.levels, dtype=float), np.asarray(self.outputs, dtype=float)
        if lv.ndim != 1 or lv.shape != out.shape or len(lv) < 1:
            raise ValueError(f"level curve: {len(self.levels)} levels and {len(self.outputs)} outputs; expected "
                             "the same number, at least one")
        if not (np.all(np.isfinite(lv)) and np.all(np.isfinite(out))):
            raise ValueError("level curve: a level or output is not a finite number")
        if lv[0] <= 0.0 or lv[-1] > 1.0 or np.any(np.diff(lv) <= 0.0):
            raise ValueError(f"level curve: levels {self.levels}: expected increasing levels in (0, 1]")

    @classmethod
    def measured(cls, levels: Sequence[float], outputs: Sequence[float]) -> LevelCurve:
        """From a measurement's points in any order: level 0 dropped (off is 0), negative outputs (instrument
        noise) set to 0, repeated levels averaged."""
        lv, out = np.asarray(levels, dtype=float), np.asarray(outputs, dtype=float)
        keep = lv > 0.0
        uniq, inv = np.unique(lv[keep], return_inverse=True)
        mean = np.bincount(inv, weights=np.clip(out[keep], 0.0, None)) / np.bincount(inv)
        return cls(tuple(float(v) for v in uniq), tuple(float(v) for v in mean))

    def output(self, levels: np.ndarray) -> np.ndarray:
        """Relative output at ``levels`` (any shape, 0..1)."""
        lv = np.asarray(levels, dtype=float)
        xs, ys = np.asarray(self.levels), np.asarray(self.outputs)
        inside = np.interp(lv, np.concatenate([[0.0], xs]), np.concatenate([[0.0], ys]))
        return np.where(lv > xs[-1], lv * (ys[-1] / xs[-1]), inside)

    def to_dict(self) -> dict[str, list[float]]:
        return {"level": list(self.levels), "relative_output": list(self.outputs)}

    @classmethod
    def from_dict(cls, doc: Any) -> LevelCurve:
        """ValueError (one line) for anything but ``{"level": [...], "relative_output": [...]}`` of numbers."""
        if not isinstance(doc, dict) or not all(isinstance(doc.get(k), list) for k in ("level", "relative_output")):
            raise ValueError(f"level curve: expected {{'level': [...], 'relative_output': [...]}}, found {doc!r:.80}")
        values = [doc["level"], doc["relative_output"]]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for col in values for v in col):
            raise ValueError("level curve: expected numbers in 'level' and 'relative_output'")
        return cls.measured(*values)


LevelCurves = tuple[LevelCurve | None, ...]


def curves_to_dict(curves: LevelCurves) -> dict[str, dict[str, list[float]]]:
    """``{"<LED number>": curve}`` for the LEDs with a measured curve."""
    return {str(k + 1): c.to_dict() for k, c in enumerate(curves) if c is not None}


def curves_from_dict(doc: Any, n_leds: int) -> LevelCurves:
    """The per-LED curves of :func:`curves_to_dict` (LEDs left out: proportional); ValueError names a bad one."""
    if doc in (None, {}):
        return ()
    if not isinstance(doc, dict):
        raise ValueError(f"level curves: expected an object keyed by LED number, found {doc!r:.60}")
    out: list[LevelCurve | None] = [None] * n_leds
    for key, value in doc.items():
        if not str(key).isdigit() or not 1 <= int(key) <= n_leds:
            raise ValueError(f"level curves: LED {key!r}: expected an LED number from 1 to {n_leds}")
        try:
            out[int(key) - 1] = LevelCurve.from_dict(value)
        except ValueError as exc:
            raise ValueError(f"LED {key}: {exc}") from None
    return tuple(out)


@dataclass(frozen=True)
class SphereProperties:
    """The sphere's levels (module docstring): ``pwm_max`` steps (resolution 1/pwm_max), the minimum stable
    level, and per LED its measured level -> output curve (``curves``: LED 1 first, None or left out:
    proportional)."""

    pwm_max: int = PWM_MAX
    min_stable_level: float = 0.01
    curves: LevelCurves = ()

    def __post_init__(self) -> None:
        if self.pwm_max < 1:
            raise ValueError(f"sphere pwm_max {self.pwm_max}: expected a positive number of PWM steps")
        if not 0.0 <= self.min_stable_level <= 1.0:
            raise ValueError(f"sphere min_stable_level {self.min_stable_level}: expected 0..1")

    @property
    def level_resolution(self) -> float:
        return 1.0 / self.pwm_max

    @property
    def lowest_level(self) -> float:
        """The smallest non-zero level the sphere holds: the minimum stable level rounded up to a PWM step."""
        return max(1, math.ceil(self.min_stable_level * self.pwm_max - 1e-9)) / self.pwm_max

    @property
    def measured_curves(self) -> bool:
        return any(c is not None for c in self.curves)

    def on_grid(self, levels: np.ndarray) -> np.ndarray:
        """``levels`` (any shape) clipped to 0..1 and rounded to the PWM grid, as a new array."""
        return np.round(np.clip(np.asarray(levels, dtype=float), 0.0, 1.0) * self.pwm_max) / self.pwm_max

    def realise(self, levels: np.ndarray) -> np.ndarray:
        """Levels a search may set for the requested ``levels`` (any shape, 0..1), as a new array.

        Rounded to the PWM grid; a level below the minimum stable level goes to 0 if it is below half of it,
        else up to the lowest stable level (the nearer of the two). For new lights only: what a light already
        set emits is :meth:`emitted` of its levels.
        """
        q = self.on_grid(levels)
        low = self.lowest_level
        unstable = (q > 0.0) & (q < low)
        if unstable.any():
            q[unstable] = np.where(q[unstable] >= 0.5 * low, low, 0.0)
        return q

    def emitted(self, levels: np.ndarray, leds: np.ndarray | None = None) -> np.ndarray:
        """Each LED's output relative to its full output at ``levels`` as the sphere set them (module docstring),
        as a new array of their shape.

        ``levels`` (..., K) with the LED on the last axis, or any shape with ``leds`` (the same shape) giving each
        level's LED (0-based; the optimisers' indexed batches). The PWM grid, then each LED's measured curve
        (proportional without one); no level is forbidden or rounded off here.
        """
        q = self.on_grid(levels)
        if not self.measured_curves:
            return q
        which = np.broadcast_to(np.arange(q.shape[-1]), q.shape) if leds is None else np.asarray(leds)
        if which.shape != q.shape:
            raise ValueError(f"emitted: leds {which.shape} do not match levels {q.shape}")
        out = q.copy()
        for k, curve in enumerate(self.curves):
            sel = which == k
            if curve is not None and sel.any():
                out[sel] = curve.output(q[sel])
        return out

    def as_captured(self) -> SphereProperties:
        """This sphere with no level forbidden (realise = the PWM grid alone): for lights already captured."""
        return dataclasses.replace(self, min_stable_level=0.0)

    def measured(self, min_stable_level: float | None = None, curves: LevelCurves = ()) -> SphereProperties:
        """This sphere with a stand's measurements (each None or empty: keep this one's)."""
        return dataclasses.replace(self, min_stable_level=self.min_stable_level if min_stable_level is None
                                   else min_stable_level, curves=curves or self.curves)

    def is_realisable(self, levels: np.ndarray, tol: float = 1e-9) -> bool:
        """True if every level is 0 or in [lowest level, 1] (within ``tol``); PWM rounding is not checked."""
        v = np.asarray(levels, dtype=float)
        return bool(np.all((v == 0.0) | ((v >= self.lowest_level - tol) & (v <= 1.0 + tol))))

    def to_dict(self) -> dict[str, Any]:
        return {"pwm_max": self.pwm_max, "level_resolution": self.level_resolution,
                "min_stable_level": self.min_stable_level,
                **({"level_curves": curves_to_dict(self.curves)} if self.measured_curves else {})}


def realisable_mix(leds: np.ndarray, target: np.ndarray, sphere: SphereProperties = SphereProperties()) -> np.ndarray:
    """Levels (K,) of the sphere mix closest to the spectrum ``target`` that the sphere can hold.

    Non-negative least squares of the LED spectra to ``target`` (thesis 1.4), largest level 1, realised on the
    sphere's grid. Rounding the tiny levels of a plain NNLS fit to 0 can ruin the mix (the D65 mix puts the
    dim LED 7 at 1 and the bright blue LEDs at 0.3-0.4 %), so LEDs are dropped greedily, one at a time, while
    that lowers the realised mix's spectral residual (after the best common scale).
    """
    from scipy.optimize import nnls

    leds = np.asarray(leds, dtype=float)
    target = np.asarray(target, dtype=float)

    def solve(active: list[int]) -> tuple[float, np.ndarray]:
        x = np.zeros(leds.shape[0])
        x[active] = nnls(leds[active].T, target)[0]
        if x.max() <= 0:
            return np.inf, x
        x = sphere.realise(x / x.max())
        spd = x @ leds
        scale = float(spd @ target) / float(spd @ spd)
        return float(np.linalg.norm(scale * spd - target)), x

    active = list(range(leds.shape[0]))
    best, levels = solve(active)
    while len(active) > 1:
        trials = [(solve([a for a in active if a != k]), k) for k in active]
        (res, x), k = min(trials, key=lambda t: t[0][0])
        if res >= best:
            break
        best, levels = res, x
        active.remove(k)
    return levels


def realisable_d65_mix(leds: np.ndarray, illuminant: np.ndarray, cmfs: np.ndarray,
                       sphere: SphereProperties = SphereProperties()) -> tuple[LightSource, float]:
    """The 3-channel baseline's D65-like sphere mix (thesis 1.4) realisable on ``sphere``, and its CIE 1976
    u'v' distance to D65."""
    import colour

    levels = realisable_mix(leds, illuminant, sphere)
    used = np.nonzero(levels)[0]
    uv = [colour.xy_to_Luv_uv(colour.XYZ_to_xy(spd @ cmfs))
          for spd in (levels @ leds, np.asarray(illuminant, dtype=float))]
    return (LightSource(tuple(int(i) + 1 for i in used), tuple(float(levels[i]) for i in used), "D65 mix"),
            float(np.linalg.norm(uv[0] - uv[1])))
