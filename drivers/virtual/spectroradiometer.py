"""A virtual spectroradiometer pointed at the virtual sphere's port: measures the spectral radiance the world's
sphere emits right now (an LED at a level, or any mix), as a real instrument would, and writes the files real
instruments write.

* what it sees: the sphere emulator's physical state (emitted levels, each LED's drift and fade at this moment on
  the emulator's clock) through :class:`drivers.virtual.sphere_light.SphereLight` (the world's LED shapes,
  output scale and low-level response), in W sr^-1 m^-2 nm^-1 (a relative unit is LED 2's peak radiance in thesis
  Table 4.2);
* its own wavelength sampling (default 380-780 nm by 1 nm; e.g. 5 nm like many instruments), the spectrum
  sampled there (no slit function: an instrument whose bandwidth is well under an LED's ~23 nm FWHM);
* instrument noise (assumed, of the order of a good spectroradiometer): per sample a Gaussian with sd
  ``relative_noise`` x the value + ``floor_relative`` x the reading's peak (auto-ranged integration) +
  ``floor_absolute`` (the sensitivity limit); seeded, so a series is reproducible;
* files (:meth:`VirtualSpectroradiometer.save`): a plain spectral CSV (one column per reading,
  ``simulation.spectral_io``) and a spectral CGATS file (``.ti3``: SAMPLE_ID + SPEC_<nm> fields and the
  ArgyllCMS keywords SPECTRAL_BANDS / START_NM / END_NM / NORM; ``simulation.cgats``), the units in the header.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.drivers.virtual.sphere_light import RADIANCE_UNIT, SphereLight, radiance_per_relative_unit
from dualrgb.simulation.cgats import write_cgats_spectra
from dualrgb.simulation.spectral_io import write_spectral_csv

log = logging.getLogger(__name__)

MODEL = "dualrgb virtual spectroradiometer"


@dataclass(frozen=True)
class RadiometerSettings:
    """The instrument's sampling and noise (module docstring)."""

    start_nm: float = 380.0
    end_nm: float = 780.0
    step_nm: float = 1.0
    relative_noise: float = 0.002
    floor_relative: float = 1e-3
    floor_absolute: float = 5e-9            # W sr^-1 m^-2 nm^-1
    serial: str = "VSR-000001"

    def __post_init__(self) -> None:
        if not (self.step_nm > 0 and self.end_nm > self.start_nm + self.step_nm):
            raise ValueError(f"spectroradiometer sampling {self.start_nm:g}-{self.end_nm:g} nm by {self.step_nm:g}: "
                             "expected start < end and a positive step")

    @property
    def wavelengths(self) -> np.ndarray:
        n = int(round((self.end_nm - self.start_nm) / self.step_nm)) + 1
        return self.start_nm + self.step_nm * np.arange(n)


@dataclass(frozen=True)
class SpectralReading:
    """One reading: ``radiance`` (W sr^-1 m^-2 nm^-1) at ``wavelengths``, taken at ``t_s`` (instrument clock)."""

    sample_id: str
    wavelengths: np.ndarray
    radiance: np.ndarray
    t_s: float


class VirtualSpectroradiometer:
    """Reads ``light()`` (an emulator snapshot: ``levels``, ``peak_shift_nm``, ``light_on``) through the world's
    :class:`SphereLight`; ``clock`` time-stamps the readings (share the emulator's)."""

    units = RADIANCE_UNIT
    model = MODEL

    def __init__(self, light: Callable[[], Any], sphere_light: SphereLight,
                 settings: RadiometerSettings | None = None, seed: int | None = 0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self._light = light
        self.sphere_light = sphere_light
        self.settings = settings or RadiometerSettings()
        self._clock = clock
        self._rng = np.random.default_rng(seed)
        self._scale = radiance_per_relative_unit()

    def true_radiance(self, snapshot: Any = None) -> np.ndarray:
        """The noise-free spectral radiance at the instrument's wavelengths for ``snapshot`` (default: now)."""
        snap = self._light() if snapshot is None else snapshot
        levels = np.asarray(snap.levels, dtype=float)
        if not getattr(snap, "light_on", True):
            levels = np.zeros_like(levels)
        emitted = self.sphere_light.emitted(levels, getattr(snap, "peak_shift_nm", None))
        return self._scale * np.interp(self.settings.wavelengths, self.sphere_light.wavelengths, emitted)

    def measure(self, sample_id: str = "") -> SpectralReading:
        """One reading of what the sphere emits now, with instrument noise."""
        t = self._clock()
        clean = self.true_radiance()
        s = self.settings
        sd = s.relative_noise * np.abs(clean) + s.floor_relative * float(np.abs(clean).max()) + s.floor_absolute
        noisy = clean + sd * self._rng.standard_normal(clean.shape)
        log.debug("spectroradiometer reading %s at %.1f s: peak %.3g %s", sample_id, t, noisy.max(), self.units)
        return SpectralReading(sample_id, s.wavelengths, noisy, t)

    def describe(self) -> dict[str, Any]:
        return {"model": self.model, "units": self.units, **asdict(self.settings)}

    def save(self, readings: Sequence[SpectralReading], folder: str | Path, stem: str,
             meta: dict[str, str] | None = None) -> list[Path]:
        """Write ``readings`` as ``<stem>.csv`` (one column per reading) and ``<stem>.ti3`` (one row each)."""
        if not readings:
            raise ValueError(f"{stem}: no readings to save")
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        wl = readings[0].wavelengths
        values = np.stack([r.radiance for r in readings], axis=1)
        names = [r.sample_id for r in readings]
        s = self.settings
        header = {"title": f"spectroradiometer readings {stem}", "units": f"spectral radiance {self.units}",
                  "instrument": f"{self.model} {s.serial} ({s.start_nm:g}-{s.end_nm:g} nm by {s.step_nm:g} nm)",
                  "times_s": " ".join(f"{r.t_s:.3f}" for r in readings), **(meta or {})}
        csv_path = folder / f"{stem}.csv"
        write_spectral_csv(csv_path, wl, values, names, header)
        ti3 = write_cgats_spectra(folder / f"{stem}.ti3", wl, values, names, descriptor=header["title"],
                                  keywords={"MEAS_TYPE": "EMISSION", "INSTRUMENT": header["instrument"],
                                            "DUALRGB_UNITS": self.units})
        return [csv_path, ti3]
