"""The light the virtual sphere emits in a world: what the virtual camera renders and the virtual
spectroradiometer measures (one model for both).

* shape: each LED's 1 nm spectrum (resources/leds/sphere10_relative.csv, thesis Table 4.2 shaped with
  ``colour.sd_single_led``), moved by the world's peak shift plus the emulator's drift at that moment (thesis
  4.3.2, drivers/virtual/led_physics.py), and stretched about its peak by the world's width scale:
  ``S'(lambda) = S(p + (lambda - p - shift) / width)`` (peak height kept, FWHM x width) - with
  :func:`simulation.led_shapes.shaped_led_spectra`, the function the fitted stand model predicts with;
* output: times the world's output scale; the PWM level becomes output through the world's low-level response
  (:class:`drivers.virtual.world.LowLevelResponse`), and LEDs add up (superposition, thesis 3.1.2);
* absolute scale (the spectroradiometer): a relative unit is LED 2's peak spectral radiance in thesis Table 4.2
  (resources/leds/sphere10_absolute.csv), W sr^-1 m^-2 nm^-1.

In the nominal world every step is skipped or exact, so the camera renders bit for bit what it did before worlds.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from dualrgb import resources
from dualrgb.drivers.virtual.world import World, load_world
from dualrgb.simulation.led_shapes import shaped_led_spectra, table_peaks
from dualrgb.simulation.spectral_io import read_spectral_csv

log = logging.getLogger(__name__)

RELATIVE_LEDS = ("leds", "sphere10_relative.csv")
ABSOLUTE_LEDS = ("leds", "sphere10_absolute.csv")
RADIANCE_UNIT = "W sr^-1 m^-2 nm^-1"


def radiance_per_relative_unit() -> float:
    """Spectral radiance (W sr^-1 m^-2 nm^-1) of one relative unit: LED 2's peak in the absolute table over its
    peak in the relative table (thesis Table 4.2)."""
    rel = read_spectral_csv(resources.path(*RELATIVE_LEDS)).values[:, 1]
    absolute = read_spectral_csv(resources.path(*ABSOLUTE_LEDS)).values[:, 1]
    return float(absolute.max() / rel.max())


class SphereLight:
    """The world's sphere emission on the LED table's own wavelengths (1 nm in the resources)."""

    def __init__(self, world: World | None = None, leds_csv: str | Path | None = None) -> None:
        self.world = load_world(world)
        table = read_spectral_csv(leds_csv or resources.path(*RELATIVE_LEDS))
        self.wavelengths = table.wavelengths
        self.native = table.values.T.copy()                      # (n_leds, n_wl) relative radiance
        self.n_leds = self.native.shape[0]
        self.peaks_nm = table_peaks(self.wavelengths, self.native)
        if self.n_leds != len(self.world.led_peak_shift_nm) and not self.world.leds_nominal:
            raise ValueError(f"world {self.world.name!r} describes {len(self.world.led_peak_shift_nm)} LEDs but "
                             f"{table.source} has {self.n_leds}")

    def _world_shift(self) -> np.ndarray:
        if self.world.leds_nominal:
            return np.zeros(self.n_leds)
        return np.asarray(self.world.led_peak_shift_nm, dtype=float)

    def spectra(self, drift_nm: np.ndarray | None = None, *, nominal: bool = False) -> np.ndarray:
        """(n_leds, n_wl) each LED's spectrum at full output on :attr:`wavelengths`: the world's shift + the drift
        ``drift_nm`` (n_leds,), its width and output scale (``nominal``: the nominal shapes, drift only)."""
        drift = np.zeros(self.n_leds) if drift_nm is None else np.asarray(drift_nm, dtype=float)
        if drift.shape != (self.n_leds,):
            raise ValueError(f"peak_shift_nm has shape {drift.shape}; expected ({self.n_leds},)")
        use_world = not nominal and not self.world.leds_nominal
        if not use_world:
            return shaped_led_spectra(self.wavelengths, self.native, drift, peaks_nm=self.peaks_nm)
        w = self.world
        return shaped_led_spectra(self.wavelengths, self.native, self._world_shift() + drift, w.led_width_scale,
                                  w.led_output_scale, self.peaks_nm)

    def output(self, levels: np.ndarray) -> np.ndarray:
        """Relative output of each LED at PWM ``levels`` (the world's low-level response; ideal: ``levels``)."""
        return self.world.led_low_level.output(levels)

    def emitted(self, levels: np.ndarray, drift_nm: np.ndarray | None = None) -> np.ndarray:
        """(n_wl,) the sphere's relative spectral radiance with each LED at ``levels`` (superposition)."""
        return np.asarray(self.output(np.asarray(levels, dtype=float)), dtype=float) @ self.spectra(drift_nm)
