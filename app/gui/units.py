"""How numbers are written for people in the window (Qt-free): LED levels in %, shutter times as photographers
write them, light dose in lux·h, numbers never split from their unit when a label wraps."""
from __future__ import annotations

import math
import re
from collections.abc import Sequence

from dualrgb.common.formatting import format_level, format_temperature
from dualrgb.core.vocabulary import format_exposure
from dualrgb.simulation.lightsource import LightSource

NBSP = "\u00a0"          # between a number and its unit: a wrapping label never splits "90 %"


def with_unit(number: str, unit: str) -> str:
    return f"{number}{NBSP}{unit}"


def level_pct(level: float) -> str:
    """One LED level (0..1) as a percentage with the 4 significant digits of format_level: '0.2242 %'."""
    return with_unit(format_level(100.0 * float(level)), "%")


def light_pct(light: LightSource) -> str:
    """'LEDs 1, 6, 7 at 0.2242 %, 41.64 %, 100 %' (levels exact in the preset files)."""
    if light.is_dark:
        return "all LEDs off"
    leds = ", ".join(str(i) for i in light.leds)
    return f"LED{'s' if len(light.leds) > 1 else ''} {leds} at " + ", ".join(level_pct(v) for v in light.levels)


def shutter(seconds: float | None) -> str:
    """'1/80 s', '2 s' (the camera driver's notation) with a non-breaking space."""
    return format_exposure(seconds).replace(" ", NBSP)


def temperature(celsius: float | None) -> str:
    """'24 °C' (4 significant digits, common.formatting) with a non-breaking space."""
    return format_temperature(celsius).replace(" ", NBSP)


def shutters(times: Sequence[float]) -> str:
    return ", ".join(shutter(t) for t in times)


_FRACTION = re.compile(r"^\s*(\d+(?:[.,]\d*)?)\s*/\s*(\d+(?:[.,]\d*)?)\s*(?:s|sec)?\s*$")
_DECIMAL = re.compile(r"^\s*(\d*[.,]?\d+)\s*(?:s|sec)?\s*$")


def parse_exposure(text: str) -> float:
    """'1/80', '1/80 s', '0.0125', '2 s', '2,5' -> seconds; ValueError naming what was expected."""
    m = _FRACTION.match(text or "")
    if m:
        num, den = (float(g.replace(",", ".")) for g in m.groups())
        value = num / den if den else math.nan
    else:
        m = _DECIMAL.match(text or "")
        value = float(m.group(1).replace(",", ".")) if m else math.nan
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"exposure {text!r}: expected a positive time such as 1/80 or 0.5 (seconds)")
    return value


def dose(lux_s: float) -> str:
    """A light dose as conservators budget it: '0.0383 lux·h (138 lux·s)'."""
    return f"{with_unit(f'{lux_s / 3600.0:.3g}', 'lux·h')} ({with_unit(f'{lux_s:.3g}', 'lux·s')})"


def dn(value: float) -> str:
    """Raw digital numbers with a thin space per thousand: '11 000 DN'."""
    return with_unit(f"{value:,.0f}".replace(",", "\u2009"), "DN")


def percent(fraction: float, digits: int = 2) -> str:
    return with_unit(f"{100.0 * fraction:.{digits}f}", "%")


def time_left_s(elapsed_s: float, fraction: float) -> float | None:
    """Seconds left at ``fraction`` done after ``elapsed_s`` (None before anything is done)."""
    if fraction <= 0.0 or elapsed_s <= 0.0:
        return None
    return elapsed_s * max(1.0 - fraction, 0.0) / fraction
