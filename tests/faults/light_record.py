"""Light-safety test helpers: settings, lights, and reading the sphere emulator's own record of lit periods (its
clock, not the host's) for light-safety tests."""
from __future__ import annotations

import time
from dataclasses import dataclass

from dualrgb.app.sequences.calibration import NamedLight
from dualrgb.core.light_safety import SafetySettings
from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator
from dualrgb.simulation.lightsource import LightSource

MARGIN_S = 0.5          # issue 9: the LEDs are off within the limit + 0.5 s, on the emulator's clock
LS1 = NamedLight("LS1", LightSource((1, 6, 8)))
LS2 = NamedLight("LS2", LightSource((3, 5, 9)))
# short limits so the faults play out in a second: limit = settle + exposure + latency
FAST = SafetySettings(settle_s=0.05, latency_s=0.2, expose_timeout_s=1.0, fetch_timeout_s=10.0)


@dataclass
class LitSpan:
    """Contiguous light (level changes while lit joined): from ``t_on`` to ``t_off`` (None: still lit)."""

    t_on: float
    t_off: float | None
    ended_by: str

    def duration(self, now: float) -> float:
        return (now if self.t_off is None else self.t_off) - self.t_on


def lit_spans(emulator: SphereEmulator, since: float = float("-inf")) -> list[LitSpan]:
    """The emulator's lit periods that began at or after ``since``, contiguous ones joined."""
    spans: list[LitSpan] = []
    for i in emulator.light_record():
        if i.t_on < since:
            continue
        if spans and spans[-1].t_off is not None and abs(spans[-1].t_off - i.t_on) < 1e-9:
            spans[-1].t_off, spans[-1].ended_by = i.t_off, i.ended_by
        else:
            spans.append(LitSpan(i.t_on, i.t_off, i.ended_by))
    return spans


def wait_dark(emulator: SphereEmulator, since: float, limit_s: float) -> None:
    """Wait (real time) until the last lit span since ``since`` has ended, or until it has lasted the limit +
    MARGIN_S + 0.2 s (then the assertion that follows fails, saying how long it was lit)."""
    while True:
        spans = lit_spans(emulator, since)
        if not spans or spans[-1].t_off is not None or spans[-1].duration(emulator.clock()) > limit_s + MARGIN_S + 0.2:
            return
        time.sleep(0.02)


def longest_lit_s(emulator: SphereEmulator, since: float) -> float:
    """The longest lit span since ``since`` (0 when there was none), on the emulator's clock."""
    now = emulator.clock()
    return max((s.duration(now) for s in lit_spans(emulator, since)), default=0.0)


def assert_dark_within(emulator: SphereEmulator, since: float, limit_s: float, what: str) -> float:
    """Every lit span since ``since`` ended within ``limit_s`` + MARGIN_S and the sphere is dark now; returns the
    worst overrun past the limit (s), printed for the report."""
    spans = lit_spans(emulator, since)
    now = emulator.clock()
    assert spans, f"{what}: the light never came on (the fault did not happen as intended)"
    assert all(s.t_off is not None for s in spans), f"{what}: still lit {spans[-1].duration(now):.2f} s after on"
    worst = max(s.duration(now) for s in spans)
    overrun = worst - limit_s
    print(f"[light safety] {what}: lit {worst:.3f} s for a {limit_s:.3f} s limit (overrun {overrun:+.3f} s; "
          f"ended by {spans[-1].ended_by})")
    assert worst <= limit_s + MARGIN_S, f"{what}: lit {worst:.3f} s, over the {limit_s:.3f} s limit + {MARGIN_S} s"
    return overrun
