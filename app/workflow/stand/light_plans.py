"""The light held on by hand as plans of the run engine: the manual light (the Light source panel's *Light ON*)
and the framing light (a low light while framing in live view: issue 30), and the dark (*Light OFF*).

Each is a plan like a capture (core.engine runs it; it holds no device): the light is switched on with its
cap (the driver's supervisor and the sphere's own ``ON <ms>`` end it there whatever the host does), held by
waiting in short ticks (a cancel - *Light OFF*, a sequence starting, the window closing - ends it within one tick)
and switched off, read back, by the plan or the engine's clean-up; the run starts and ends dark, read back, and
every lit period's light dose is counted by the engine (in the session's manifest when one is open).

* :class:`HeldLight`: one lit period of at most ``cap_s`` (at most :data:`MAX_MANUAL_ON_S`); the levels may
  change while it is on (:meth:`HeldLight.change`: the same lit period, never extended).
* :class:`FramingLight`: lit periods at most ``cap_s`` each, *renewed* (off, read back, and on again: a new lit
  period, never an extended one) :data:`RENEW_MARGIN_S` before each cap, at most :data:`MAX_FRAMING_LEVEL` of full
  on every LED, for at most :data:`MAX_FRAMING_S` in all.
* :class:`Dark`: nothing but the run's read-back: every LED 0 and the light off, confirmed.
"""
from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass

import numpy as np

from dualrgb.app.sequences.base import Sequence
from dualrgb.core.messages import (
    LightOff,
    LightOn,
    PlannedFrame,
    PlanSteps,
    ProgressEvent,
    ReadBack,
    SetLight,
    Wait,
)
from dualrgb.simulation.lightsource import N_SPHERE_LEDS, LightSource

log = logging.getLogger(__name__)

MAX_MANUAL_ON_S = 10.0           # a light held by hand: LED peaks drift after 10 s (thesis 4.3.2)
MAX_FRAMING_LEVEL = 0.05         # of full, per LED
DEFAULT_FRAMING_LEVEL = 0.02
RENEW_MARGIN_S = 1.0             # a framing period is renewed this long before its cap
MAX_FRAMING_S = 300.0            # one framing lasts at most 5 min (then it stops; start it again)
TICK_S = 0.1                     # a held light checks for a cancel and for new levels this often


def framing_light(first: LightSource | None, level: float) -> LightSource:
    """The framing light: ``first`` (the day's first light) scaled so its brightest LED is at ``level`` (at most
    :data:`MAX_FRAMING_LEVEL`), else every LED at ``level``."""
    level = min(max(float(level), 0.0), MAX_FRAMING_LEVEL)
    if first is not None and max(first.levels, default=0.0) > 0:
        levels = np.asarray(first.levels, dtype=float)
        return LightSource(first.leds, tuple(float(v) for v in levels * (level / float(levels.max()))),
                           name="framing")
    return LightSource(tuple(range(1, N_SPHERE_LEDS + 1)), (level,) * N_SPHERE_LEDS, name="framing")


def _check_cap(cap_s: float, most: float, what: str) -> float:
    if not 0 < float(cap_s) <= most:
        raise ValueError(f"{what}: a lit period of {cap_s:g} s; expected more than 0 and at most {most:g} s")
    return float(cap_s)


class _Mailbox:
    """New levels for a held light, from any thread (the plan takes them between ticks)."""

    def __init__(self, light: LightSource):
        self._lock = threading.Lock()
        self._light, self._new = light, False

    def put(self, light: LightSource) -> None:
        with self._lock:
            self._light, self._new = light, True

    def take(self) -> LightSource | None:
        with self._lock:
            new, self._new = self._new, False
            return self._light if new else None


class HeldLight(Sequence):
    """The manual light (module docstring); ``period`` is its lit period once on."""

    name = "manual light"

    def __init__(self, light: LightSource, cap_s: float, tick_s: float = TICK_S):
        super().__init__()
        if light.is_dark:
            raise ValueError("the light to switch on has every LED at 0: set the levels first")
        self.light, self.cap_s, self.tick_s = light, _check_cap(cap_s, MAX_MANUAL_ON_S, "the manual light"), tick_s
        self._mailbox = _Mailbox(light)
        self.period = None

    def change(self, light: LightSource) -> None:
        """New levels while it is on (the same lit period: its cap is not moved)."""
        self._mailbox.put(light)

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame("light", self.cap_s, self.light.label(), f"held at most {self.cap_s:g} s")]

    def _steps(self) -> PlanSteps:
        yield SetLight(self.light)
        self.period = period = yield LightOn(self.cap_s, what=self.name)
        yield ProgressEvent(0, 1, f"light on for at most {self.cap_s:g} s")
        while (left := period.deadline - time.monotonic()) > 0:
            yield Wait(min(self.tick_s, left))
            new = self._mailbox.take()
            if new is not None and not new.is_dark:
                yield SetLight(new)
        yield LightOff()
        yield ProgressEvent(1, 1, f"light off at its {self.cap_s:g} s cap")


@dataclass
class FramingPeriod:
    """One lit period the framing light asked for (host monotonic clock)."""

    t_on: float
    max_on_s: float
    levels: tuple[float, ...]
    t_off: float | None = None

    def lit_s(self, now: float | None = None) -> float:
        end = self.t_off if self.t_off is not None else (time.monotonic() if now is None else now)
        return max(0.0, min(end, self.t_on + self.max_on_s) - self.t_on)


class FramingLight(Sequence):
    """The framing light (module docstring); ``periods`` are its lit periods so far."""

    name = "framing light"

    def __init__(self, light: LightSource, cap_s: float, *, max_s: float = MAX_FRAMING_S,
                 margin_s: float = RENEW_MARGIN_S, tick_s: float = TICK_S):
        super().__init__()
        self._check_level(light)
        self.light, self.cap_s = light, _check_cap(cap_s, MAX_MANUAL_ON_S, "the framing light")
        self.max_s, self.margin_s, self.tick_s = max_s, margin_s, tick_s
        self._mailbox = _Mailbox(light)
        self.periods: list[FramingPeriod] = []
        self.ended = ""                    # why it ended by itself ('' while on, or when cancelled)

    @staticmethod
    def _check_level(light: LightSource) -> None:
        if max(light.levels, default=0.0) > MAX_FRAMING_LEVEL + 1e-9:
            raise ValueError(f"framing light {light.label()}: an LED above {100 * MAX_FRAMING_LEVEL:g} % of full")

    def change(self, light: LightSource) -> None:
        """New framing levels (taken at the next tick, within the lit period)."""
        self._check_level(light)
        self._mailbox.put(light)

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame("light", self.cap_s, self.light.label(), "framing, renewed before each cap")]

    def level_seconds(self) -> float:
        """Sum over its periods of (brightest LED level x seconds lit): at most 5 % x the time."""
        return sum(max(p.levels, default=0.0) * p.lit_s() for p in self.periods)

    def _steps(self) -> PlanSteps:
        stop_at = time.monotonic() + self.max_s
        light = self.light
        while time.monotonic() < stop_at:
            yield SetLight(light)
            lit = yield LightOn(self.cap_s, what=self.name)
            period = FramingPeriod(lit.t_on, self.cap_s, tuple(light.levels))
            self.periods.append(period)
            yield ProgressEvent(len(self.periods), 0, f"framing light on at {100 * max(light.levels):.3g} %")
            renew_at = min(lit.deadline - self.margin_s, stop_at)
            while (left := renew_at - time.monotonic()) > 0:
                yield Wait(min(self.tick_s, left))
                new = self._mailbox.take()
                if new is not None:
                    light = new
                    yield SetLight(light)
            yield LightOff()
            period.t_off = time.monotonic()
        self.ended = f"stopped after {self.max_s / 60:g} min of framing"


class Dark(Sequence):
    """Every LED 0 and the light off, read back (the run's own read-backs, and one in between)."""

    name = "light off"

    def plan(self) -> list[PlannedFrame]:
        return []

    def _steps(self) -> PlanSteps:
        yield ReadBack()
