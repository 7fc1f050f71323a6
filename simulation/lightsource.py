"""LightSource: which LEDs of the sphere, at which levels (1-based LED numbers as in the thesis, levels 0..1)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualrgb.simulation.choices import N_SPHERE_LEDS

LEVEL_DIGITS = 4      # significant digits printed: retyping printed levels reproduces the mean dE00 to < 1e-4


def format_level(v: float) -> str:
    """One LED level for people: 4 significant digits (0.002242, 0.4164, 1), never rounded to 0 when it is not.

    Two decimals were not enough: the reflective PSO optimum needs LED 1 at 0.0022 and, printed as 0.00, the
    retyped light gave 0.95 instead of 0.41 mean dE00. Measured on the PSO and GA optima of both modes, 4
    significant digits reproduce the training error within 2e-5 (3 decimals: up to 0.44 off, 4 decimals:
    5e-4). Preset files store the exact value."""
    return f"{float(v):.{LEVEL_DIGITS}g}"


@dataclass(frozen=True)
class LightSource:
    leds: tuple[int, ...]
    levels: tuple[float, ...] = ()
    name: str = ""

    def __post_init__(self) -> None:
        leds = tuple(int(n) for n in self.leds)
        levels = tuple(float(v) for v in self.levels) if self.levels else (1.0,) * len(leds)
        if len(levels) != len(leds):
            raise ValueError(f"light source {self.name or leds}: {len(leds)} LEDs but {len(levels)} levels")
        if len(set(leds)) != len(leds):
            raise ValueError(f"light source {self.name or leds}: an LED is listed twice")
        for n in leds:
            if not 1 <= n <= N_SPHERE_LEDS:
                raise ValueError(f"light source {self.name or leds}: LED {n} is outside 1..{N_SPHERE_LEDS}")
        for v in levels:
            if not (0.0 <= v <= 1.0) or v != v:
                raise ValueError(f"light source {self.name or leds}: level {v} is outside 0..1")
        object.__setattr__(self, "leds", leds)
        object.__setattr__(self, "levels", levels)

    def weights(self, n_leds: int = N_SPHERE_LEDS) -> np.ndarray:
        """Dense level vector over all LEDs (0 for LEDs not in this source)."""
        w = np.zeros(n_leds)
        for n, v in zip(self.leds, self.levels, strict=True):
            w[n - 1] = v
        return w

    def spectrum(self, led_spectra: np.ndarray) -> np.ndarray:
        """Mixed spectrum: ``led_spectra`` has shape (n_leds, n_wavelengths)."""
        return self.weights(led_spectra.shape[0]) @ led_spectra

    @property
    def is_dark(self) -> bool:
        return not any(v > 0 for v in self.levels)

    def label(self) -> str:
        inner = ", ".join(str(n) for n in self.leds)
        if all(v == 1.0 for v in self.levels):
            return f"({inner})"
        return f"({inner}) @ ({', '.join(format_level(v) for v in self.levels)})"

    def to_dict(self) -> dict:
        """Exact levels (JSON keeps every digit of a float), so a saved preset reproduces the optimum."""
        return {"leds": list(self.leds), "levels": [float(v) for v in self.levels], "name": self.name}

    @classmethod
    def from_dict(cls, data: dict) -> LightSource:
        return cls(tuple(data["leds"]), tuple(data.get("levels") or ()), data.get("name", ""))
