"""Measuring the sphere's LEDs with a spectroradiometer (thesis 4.3): each LED alone at a series of PWM levels
(finely at the low end), then held on at full level for a warm-up series (spectra every ``interval_s`` for
``warmup_s``).

Light safety: this measures the sphere itself, with *no original on the stand* (the spectroradiometer looks at the
sphere's port), so the 10 s cap per exposure that protects originals does not apply to the warm-up; what does
apply is stated before anything is switched on (the first event) and holds on every path:

* a level reading is lit for at most ``reading_cap_s`` (settle + reading), then switched off;
* a warm-up is one lit period of at most ``warmup_s + WARMUP_MARGIN_S``, the limit sent with the switch-on so the
  sphere enforces it by itself (``ON <ms>``) as well as the driver's supervisor (drivers.led_sphere);
* the light is off between readings and LEDs, and every LED is set to 0 and the light off after completion,
  cancel or any error (``_cleanup``: the driver's ``ensure_off``).

The plan holds no device: it yields messages (SetLight, LightOn with its cap, Wait, Measure, LightOff,
SaveReadings) and the run engine (core.engine) applies them. Time passes through Wait: on the virtual lab
the engine moves the emulator's clock (its ``sleep`` is the clock's skip: the drift model on its own clock, never
a wall-clock wait); on a real stand it sleeps. Either way the sphere hears from the host at least every
``KEEPALIVE_S`` (its watchdog). Each LED's readings are written by the instrument as one series
(``levels_LED<n>`` / ``warmup_LED<n>``, a spectral CSV and a CGATS .ti3; app.workflow.calibration.led_readings names
them).
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.sequences.base import Sequence as BaseSequence
from dualrgb.app.workflow.calibration.led_readings import level_id, warmup_id
from dualrgb.core.messages import (
    LightOff,
    LightOn,
    Measure,
    PlanSteps,
    SaveReadings,
    SetLight,
    Wait,
)
from dualrgb.core.vocabulary import EventKind
from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)

# finely at the low end (0.2 %..5 %, where drivers drop out), coarser above
DEFAULT_LEVELS = (0.0, 0.002, 0.004, 0.006, 0.008, 0.01, 0.0125, 0.015, 0.0175, 0.02, 0.025, 0.03, 0.035, 0.04,
                  0.045, 0.05, 0.06, 0.08, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1.0)
WARMUP_MARGIN_S = 30.0      # the warm-up's lit-period limit beyond its last reading
MAX_WARMUP_S = 3600.0 - WARMUP_MARGIN_S     # the sphere's longest lit period is one hour (ON <ms>)


@dataclass(frozen=True)
class LedMeasurementPlan:
    """Which LEDs at which levels, which LEDs get a warm-up series, and its timing."""

    leds: tuple[int, ...] = tuple(range(1, 11))
    levels: tuple[float, ...] = DEFAULT_LEVELS
    warmup_leds: tuple[int, ...] = tuple(range(1, 11))
    warmup_s: float = 3540.0
    interval_s: float = 60.0
    settle_s: float = 0.5
    reading_cap_s: float = 10.0

    def __post_init__(self) -> None:
        if not 0 < self.warmup_s <= MAX_WARMUP_S:
            raise ValueError(f"warm-up of {self.warmup_s:g} s: expected more than 0 and at most {MAX_WARMUP_S:g} s "
                             "(the sphere's longest lit period is one hour)")
        if not 0 < self.interval_s <= self.warmup_s:
            raise ValueError(f"warm-up interval {self.interval_s:g} s: expected more than 0 and at most the "
                             f"warm-up's {self.warmup_s:g} s")
        if any(not 0.0 <= lv <= 1.0 for lv in self.levels):
            raise ValueError(f"levels {self.levels}: expected levels from 0 to 1")
        if not 0 <= self.settle_s < self.reading_cap_s:
            raise ValueError(f"settle {self.settle_s:g} s: expected less than the reading's cap "
                             f"{self.reading_cap_s:g} s")

    @property
    def warmup_times(self) -> list[float]:
        """Seconds on of the warm-up readings: every ``interval_s`` from 0, and at ``warmup_s``."""
        n = int(self.warmup_s / self.interval_s + 1e-9)
        times = [i * self.interval_s for i in range(n + 1)]
        return times if self.warmup_s - times[-1] < 1e-6 else [*times, self.warmup_s]

    @property
    def steps(self) -> int:
        return len(self.leds) * len(self.levels) + len(self.warmup_leds) * len(self.warmup_times)

    def light_mode(self) -> str:
        return (f"light: measuring the sphere with no original on the stand; each level reading lit at most "
                f"{self.reading_cap_s:g} s, each warm-up {self.warmup_s / 60:g} min at full level in one lit "
                f"period the sphere itself limits to {self.warmup_s + WARMUP_MARGIN_S:g} s; off between readings "
                "and after any error")


def _one_led(led: int, level: float) -> LightSource:
    return LightSource((led,), (level,), f"LED {led} at {level:g}")


class LedMeasurement(BaseSequence):
    """The sequence (module docstring): the readings are written by the run's spectroradiometer into
    ``out_dir``; ``clock`` is the one the engine's Wait moves (the emulator's on the virtual lab)."""

    name = "LED measurement"

    def __init__(self, out_dir: Path, clock: Callable[[], float] = time.monotonic,
                 settings: LedMeasurementPlan | None = None) -> None:
        super().__init__()
        self.out_dir = Path(out_dir)
        self.clock = clock
        self.settings = settings or LedMeasurementPlan()
        self.files: list[Path] = []

    def plan(self) -> list[PlannedFrame]:
        p = self.settings
        return ([PlannedFrame("reading", 0.0, f"LED {n} x {lv:g}") for n in p.leds for lv in p.levels]
                + [PlannedFrame("reading", 0.0, f"LED {n}", f"warm-up {t:g} s") for n in p.warmup_leds
                   for t in p.warmup_times])

    def _steps(self) -> PlanSteps:
        p = self.settings
        total = p.steps
        log.info("%s", p.light_mode())
        yield ProgressEvent(0, total, p.light_mode(), data={"light_mode": p.light_mode()})
        step = 0
        for led in p.leds:
            readings = []
            for lv in p.levels:
                readings.append((yield from self._level_reading(led, lv)))
                step += 1
                yield ProgressEvent(step, total, f"LED {led} at level {lv:g}", kind=EventKind.FRAME)
            self.files += yield SaveReadings(readings, self.out_dir, f"levels_LED{led}")
        for led in p.warmup_leds:
            step = yield from self._warmup(led, step, total)
        yield ProgressEvent(total, total, f"LED measurement done: {len(self.files)} files", kind=EventKind.DONE)

    def _level_reading(self, led: int, level: float) -> PlanSteps:
        """One reading lit at most ``reading_cap_s``; the engine switches off after an error."""
        yield SetLight(_one_led(led, level))
        if level <= 0:                            # nothing to switch on: the dark reading
            reading = yield Measure(level_id(led, level))
            return reading
        yield LightOn(self.settings.reading_cap_s, what="LED measurement")
        yield Wait(self.settings.settle_s)
        reading = yield Measure(level_id(led, level))
        yield LightOff()
        return reading

    def _warmup(self, led: int, step: int, total: int) -> PlanSteps:
        p = self.settings
        yield SetLight(_one_led(led, 1.0))
        readings = []
        yield LightOn(p.warmup_s + WARMUP_MARGIN_S, what="LED measurement")
        t_on = self.clock()
        for t in p.warmup_times:
            yield Wait(max(0.0, t - (self.clock() - t_on)))
            readings.append((yield Measure(warmup_id(led, self.clock() - t_on))))
            step += 1
            yield ProgressEvent(step, total, f"LED {led} warm-up: {t / 60:.1f} min on", kind=EventKind.FRAME)
        yield LightOff()
        self.files += yield SaveReadings(readings, self.out_dir, f"warmup_LED{led}")
        return step
