"""How numbers are written for people, in one place for the command line and the window: 4 significant digits
(LED levels, temperatures, exposures that are no 1/n shutter speed), shutter speeds as the camera writes them
('1/60 s'), durations as a clock reads ('42 s', '3 min 05 s').

    format_level(0.002242)        # '0.002242'
    format_exposure(1 / 60)       # '1/60 s';  format_exposure(0.7727) -> '0.7727 s'; format_exposure(8) -> '8 s'
    format_temperature(24.0045)   # '24 °C'
    format_duration(220.4)        # '3 min 40 s'
    counted(1, "frame")           # '1 frame';  counted(6, "frame") -> '6 frames'; counted(2, "delivery", "deliveries")

Four digits because retyping a printed LED level must reproduce the light (simulation.lightsource.format_level's
reasoning); the rest follows so a number reads the same in every place.
"""
from __future__ import annotations

import math

SIGNIFICANT = 4          # significant digits printed: retyping printed levels reproduces the mean dE00 to < 1e-4


def significant(value: float, digits: int = SIGNIFICANT) -> str:
    """``value`` with ``digits`` significant digits ('0.002242', '41.64', '100')."""
    return f"{float(value):.{digits}g}"


def format_level(v: float) -> str:
    """One LED level for people: 4 significant digits (0.002242, 0.4164, 1), never rounded to 0 when it is not.

    Two decimals were not enough: the reflective PSO optimum needs LED 1 at 0.0022 and, printed as 0.00, the
    retyped light gave 0.95 instead of 0.41 mean dE00. Measured on the PSO and GA optima of both modes, 4
    significant digits reproduce the training error within 2e-5 (3 decimals: up to 0.44 off, 4 decimals:
    5e-4). Preset files store the exact value."""
    return significant(v)


def format_exposure(seconds: float | None) -> str:
    """An exposure time as photographers read it: '1/60 s' below a second when it is a 1/n speed (the camera's
    notation), else 4 significant digits ('0.7727 s', '8 s'); None: 'bulb'."""
    if seconds is None:
        return "bulb"
    if 0 < seconds < 1:
        inv = 1.0 / seconds
        if abs(inv - round(inv)) < 0.05 * inv and inv >= 2:
            return f"1/{inv:.0f} s"
    return f"{significant(seconds)} s"


def format_temperature(celsius: float | None) -> str:
    return "—" if celsius is None or not math.isfinite(celsius) else f"{significant(celsius)} °C"


def format_duration(seconds: float | None) -> str:
    """'—' for unknown, '42 s', '3 min 05 s', '1 h 02 min'."""
    if seconds is None or not math.isfinite(seconds):
        return "—"
    s = int(round(max(seconds, 0.0)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {(s % 3600) // 60:02d} min"


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` and its noun, singular for one: '1 frame', '0 frames', '6 frames' (``plural``: an irregular one,
    'deliveries'). The one plural rule of the window and the command line ('1 frames' was a bug, issue 42)."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


__all__ = ["SIGNIFICANT", "counted", "format_duration", "format_exposure", "format_level", "format_temperature",
           "significant"]
