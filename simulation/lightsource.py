"""LightSource: which LEDs of the sphere, at which levels (1-based LED numbers as in the thesis, levels 0..1)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualrgb.common.formatting import SIGNIFICANT as LEVEL_DIGITS  # noqa: F401 - one formatting (common)
from dualrgb.common.formatting import format_level
from dualrgb.simulation.choices import N_SPHERE_LEDS


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
