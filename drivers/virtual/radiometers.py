"""The virtual lab's radiance instruments: what a technician measures the monochromator's output with, placed where
the camera stands (thesis 4.2: a Konica Minolta CS-2000 telespectroradiometer), writing the files
``simulation.radiance_reference`` reads.

* :class:`VirtualSpectroradiometer`: for each set wavelength the output spectrum of the virtual monochromator
  (drivers/virtual/monochromator_light.py, at its current grating and filter), sampled every 1 nm over
  380-780 nm (the CS-2000's range), with noise: a repeatability factor per reading (``repeatability``, 0.3 %) and a
  per-sample noise (``sample_noise``, 0.2 % of the value + a floor of ``floor`` W sr-1 m-2 nm-1), clipped at 0
  as the instrument reports. Written as a spectral CSV (a column per set wavelength) or CGATS (a row each).
* :class:`VirtualPhotodiode`: a calibrated silicon photodiode of 1 mm2 x 1 sr etendue: its responsivity file
  (the calibration certificate: ``R = lambda / 1239.84 nm x QE``, QE a smooth silicon curve, 1 % uncertainty)
  and the photocurrents it reads at each set wavelength (the band integrated against R, 0.2 % noise).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.integrate import trapezoid

from dualrgb.common.atomic_files import atomic_write
from dualrgb.drivers.virtual.monochromator_light import MonochromatorOptics
from dualrgb.simulation.spectral_io import write_spectral_csv
from dualrgb.simulation.versions import dualrgb_version

log = logging.getLogger(__name__)

TSR_WAVELENGTHS = np.arange(380.0, 781.0, 1.0)        # CS-2000: 380-780 nm every 1 nm
PLANCK_NM_EV = 1239.84                                  # h c / e in nm V: responsivity of a unit quantum efficiency


def column_name(set_nm: float) -> str:
    """The column (CSV) or sample (CGATS) name of the reading at a set wavelength: ``mono_550``."""
    return f"mono_{set_nm:g}"


@dataclass
class VirtualSpectroradiometer:
    """Reads the virtual monochromator's output spectrum at each set wavelength (see the module docstring)."""

    optics: MonochromatorOptics
    grating: int = 1
    filter_position: int = 1
    repeatability: float = 0.003
    sample_noise: float = 0.002
    floor: float = 1e-6
    seed: int | None = 0

    def readings(self, set_nm: list[float]) -> np.ndarray:
        """(n_wavelengths, n_set) spectral radiance, W sr-1 m-2 nm-1, one measured spectrum per set wavelength."""
        rng = np.random.default_rng(self.seed)
        out = np.empty((len(TSR_WAVELENGTHS), len(set_nm)))
        for j, nm in enumerate(set_nm):
            true = self.optics.spectrum(float(nm), TSR_WAVELENGTHS, self.grating, self.filter_position)
            gain = 1.0 + self.repeatability * rng.standard_normal()
            noise = rng.standard_normal(true.shape) * (self.sample_noise * true + self.floor)
            out[:, j] = np.maximum(true * gain + noise, 0.0)
        return out

    def _meta(self, set_nm: list[float]) -> dict[str, str]:
        return {"title": "monochromator output, one spectrum per set wavelength",
                "instrument": "dualrgb virtual spectroradiometer (CS-2000-like, 380-780 nm / 1 nm)",
                "units": "spectral radiance, W sr-1 m-2 nm-1",
                "uncertainty_percent": f"{100 * self.repeatability:g}",
                "set_wavelengths_nm": f"{min(set_nm):g}-{max(set_nm):g} ({len(set_nm)} readings)",
                "monochromator": f"grating {self.grating}, filter {self.filter_position}, "
                                 f"FWHM {self.optics.fwhm_nm(self.grating):g} nm",
                "generated_by": f"dualrgb {dualrgb_version()} drivers/virtual/radiometers.py"}

    def write_csv(self, path: str | Path, set_nm: list[float]) -> Path:
        """The readings as a spectral CSV: ``wavelength_nm,mono_380,...``."""
        write_spectral_csv(path, TSR_WAVELENGTHS, self.readings(set_nm), [column_name(nm) for nm in set_nm],
                           self._meta(set_nm))
        log.info("virtual spectroradiometer: %d readings -> %s", len(set_nm), path)
        return Path(path)

    def write_cgats(self, path: str | Path, set_nm: list[float]) -> Path:
        """The readings as CGATS.17: one row per set wavelength, ``SAMPLE_NAME mono_550``, ``SPECTRAL_NM380`` ..."""
        values = self.readings(set_nm)
        fields = ["SAMPLE_ID", "SAMPLE_NAME"] + [f"SPECTRAL_NM{int(w)}" for w in TSR_WAVELENGTHS]
        lines = ["CGATS.17", 'ORIGINATOR "dualrgb virtual spectroradiometer"',
                 f'DESCRIPTOR "{self._meta(set_nm)["title"]}"', 'KEYWORD "UNITS"',
                 'UNITS "W sr-1 m-2 nm-1"', f"NUMBER_OF_FIELDS {len(fields)}", "BEGIN_DATA_FORMAT",
                 " ".join(fields), "END_DATA_FORMAT", f"NUMBER_OF_SETS {len(set_nm)}", "BEGIN_DATA"]
        for j, nm in enumerate(set_nm):
            lines.append(" ".join([str(j + 1), column_name(nm), *(f"{v:.6g}" for v in values[:, j])]))
        lines.append("END_DATA")
        return atomic_write(Path(path), "\n".join(lines) + "\n")


@dataclass
class VirtualPhotodiode:
    """A calibrated silicon photodiode in the camera's place (see the module docstring)."""

    optics: MonochromatorOptics
    grating: int = 1
    filter_position: int = 1
    etendue_m2_sr: float = 1e-6
    noise: float = 0.002
    calibration_uncertainty: float = 0.01
    seed: int | None = 0

    @staticmethod
    def responsivity(wavelengths: np.ndarray) -> np.ndarray:
        """A/W: ``lambda / 1239.84 nm x QE``, QE rising from the blue to ~0.9 and falling past 1000 nm."""
        wl = np.asarray(wavelengths, dtype=float)
        qe = 0.9 * (1.0 - np.exp(-(wl - 250.0) / 150.0)) / (1.0 + np.exp((wl - 1050.0) / 25.0))
        return wl / PLANCK_NM_EV * np.clip(qe, 0.0, None)

    def write(self, responsivity_path: str | Path, photocurrent_path: str | Path, set_nm: list[float]) -> None:
        """The calibration certificate (300-1100 nm / 10 nm) and the photocurrents at ``set_nm``."""
        rng = np.random.default_rng(self.seed)
        cal_wl = np.arange(300.0, 1101.0, 10.0)
        r = self.responsivity(cal_wl)
        version = f"dualrgb {dualrgb_version()} drivers/virtual/radiometers.py"
        write_spectral_csv(responsivity_path, cal_wl, np.column_stack([r, self.calibration_uncertainty * r]),
                           ["responsivity", "u_responsivity"],
                           {"title": "virtual silicon photodiode, calibration certificate", "units": "A/W",
                            "generated_by": version})
        currents = []
        for nm in set_nm:
            wl, radiance = self.optics.band(float(nm), self.grating, self.filter_position)
            i = self.etendue_m2_sr * float(trapezoid(radiance * self.responsivity(wl), wl))
            currents.append(i * (1.0 + self.noise * rng.standard_normal()))
        cur = np.array(currents)
        write_spectral_csv(photocurrent_path, np.asarray(set_nm, dtype=float),
                           np.column_stack([cur, self.noise * np.abs(cur)]), ["photocurrent", "u_photocurrent"],
                           {"title": "photocurrent of the virtual photodiode at each set wavelength", "units": "A",
                            "generated_by": version})
