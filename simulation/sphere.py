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
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

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
class SphereProperties:
    """The sphere's level grid: ``pwm_max`` steps (resolution 1/pwm_max) and the minimum stable level."""

    pwm_max: int = PWM_MAX
    min_stable_level: float = 0.01

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

    def realise(self, levels: np.ndarray) -> np.ndarray:
        """Levels the sphere will emit for the requested ``levels`` (any shape, 0..1), as a new array.

        Rounded to the PWM grid; a level below the minimum stable level goes to 0 if it is below half of it,
        else up to the lowest stable level (the nearer of the two).
        """
        q = np.round(np.clip(np.asarray(levels, dtype=float), 0.0, 1.0) * self.pwm_max) / self.pwm_max
        low = self.lowest_level
        unstable = (q > 0.0) & (q < low)
        if unstable.any():
            q[unstable] = np.where(q[unstable] >= 0.5 * low, low, 0.0)
        return q

    def is_realisable(self, levels: np.ndarray, tol: float = 1e-9) -> bool:
        """True if every level is 0 or in [lowest level, 1] (within ``tol``); PWM rounding is not checked."""
        v = np.asarray(levels, dtype=float)
        return bool(np.all((v == 0.0) | ((v >= self.lowest_level - tol) & (v <= 1.0 + tol))))

    def to_dict(self) -> dict:
        return {"pwm_max": self.pwm_max, "level_resolution": self.level_resolution,
                "min_stable_level": self.min_stable_level}


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
