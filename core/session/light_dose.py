"""The light dose an object receives: on-time x level per LED, and lux.seconds estimated from the LEDs'
absolute spectral radiance (thesis Table 4.2 peaks; resources/leds/sphere10_absolute.csv).

A capture session logs every lit period in its manifest as it ends (``CaptureSession.record_dose``) and sums
them with ``CaptureSession.light_dose()`` into a :class:`LightDose`, so a killed and resumed run still reports
the whole dose the object received.

Illuminance from a uniform diffuse source of radiance L: E = pi * L (lambertian hemisphere), and
lux = 683 lm/W * sum(E_e(lambda) * ybar(lambda) * dlambda). This is an estimate for conservation records,
not a measurement: the sphere's geometry and the stand distance scale it.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from functools import lru_cache

import colour
import numpy as np

from dualrgb import resources
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.spectral_io import read_spectral_csv

log = logging.getLogger(__name__)

KM = 683.0   # lm/W


@lru_cache(maxsize=1)
def lux_per_led() -> np.ndarray:
    """Estimated illuminance (lx) of each LED alone at level 1."""
    table = read_spectral_csv(resources.path("leds", "sphere10_absolute.csv"))
    shape = colour.SpectralShape(table.wavelengths[0], table.wavelengths[-1], 1)
    ybar = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape).values[:, 1]
    step = float(np.diff(table.wavelengths).mean())
    return KM * math.pi * (table.values * ybar[:, None]).sum(axis=0) * step


@dataclass
class LightDose:
    """Accumulates level x seconds per LED and lux x seconds over a session."""

    level_s: np.ndarray = field(default_factory=lambda: np.zeros(10))
    lux_s: float = 0.0
    on_s: float = 0.0

    def add(self, light: LightSource, seconds: float) -> None:
        w = light.weights(len(self.level_s))
        self.level_s += w * seconds
        self.lux_s += float(w @ lux_per_led()) * seconds
        self.on_s += seconds

    def to_dict(self) -> dict:
        return {"on_s": round(self.on_s, 3), "lux_s": round(self.lux_s, 3),
                "level_s_per_led": {f"LED{i + 1}": round(float(v), 4) for i, v in enumerate(self.level_s)}}


def light_from_record(light: dict) -> LightSource:
    """The LightSource of a manifest dose line's ``light`` ({"name", "leds", "levels"}, levels exact)."""
    return LightSource(tuple(light["leds"]), tuple(light.get("levels") or ()), str(light.get("name", "")))
