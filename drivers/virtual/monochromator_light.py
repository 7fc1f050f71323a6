"""What comes out of the virtual lab's monochromator: a halogen lamp through a grating and a filter, in a narrow
band at the set wavelength (the light of the thesis' CSRF measurement, 4.2: a halogen lamp into a monochromator,
its output diffused by an integrating sphere in front of the camera).

The model, per set wavelength ``lambda_0`` (spectral radiance of the diffused output, W sr-1 m-2 nm-1)::

    L(lambda; lambda_0) = L_lamp(lambda) * tau * eta_g(lambda) * T_f(lambda) * tri((lambda - lambda_0) / FWHM)

* ``L_lamp``: a Planck radiator at ``lamp_temperature_k`` (3000 K, a quartz-tungsten-halogen lamp;
  ``colour.colorimetry.planck_law``), scaled to ``lamp_radiance_560`` at 560 nm;
* ``tau``: the transmittance of the optics and the diffusing sphere (wavelength-independent);
* ``eta_g``: the grating's first-order efficiency, the scalar blaze model in Littrow,
  ``eta_peak * sinc^2(1 - lambda_blaze / lambda)`` (1 at the blaze wavelength, 0.41 at half and at twice it);
* ``T_f``: the filter wheel position's transmittance (open, or an order-sorting long-pass with a 10 nm logistic
  edge);
* ``tri``: the slit function of equal entrance and exit slits, a triangle of full width at half maximum
  ``FWHM = slit width x reciprocal linear dispersion`` (default 1.0 mm x 6.4 nm/mm = 6.4 nm for the
  1200 l/mm grating of a Cornerstone 130), zero beyond +-FWHM.

Second-order light and stray light are not modelled (an order-sorting filter removes the former on a real stand).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

log = logging.getLogger(__name__)

SAMPLE_NM = 0.25                   # the band's sampling for the camera (the triangle's corners fall on samples)


@dataclass(frozen=True)
class Grating:
    """One grating of the turret: what ``GRAT?`` reports, and its optics."""

    number: int
    lines_per_mm: int
    label: str
    blaze_nm: float
    dispersion_nm_per_mm: float           # reciprocal linear dispersion at the exit slit
    range_nm: tuple[float, float]         # where GOWAVE is allowed (else error 3)
    steps_per_nm: float = 100.0           # the wavelength drive's resolution (WAVE? is quantised to it)

    def efficiency(self, wavelengths: np.ndarray, peak: float = 0.8) -> np.ndarray:
        """First-order efficiency, the scalar blaze model: ``peak * sinc^2(1 - blaze / lambda)``."""
        wl = np.asarray(wavelengths, dtype=float)
        return peak * np.sinc(1.0 - self.blaze_nm / np.maximum(wl, 1e-9)) ** 2


@dataclass(frozen=True)
class FilterPosition:
    """A filter wheel position: open (``cut_on_nm`` None) or a long-pass with a logistic edge."""

    label: str
    cut_on_nm: float | None = None
    edge_nm: float = 10.0                 # 10 % to 90 % width of the edge is about 4.4 x this / 1.0
    blocked: bool = False

    def transmittance(self, wavelengths: np.ndarray) -> np.ndarray:
        wl = np.asarray(wavelengths, dtype=float)
        if self.blocked:
            return np.zeros_like(wl)
        if self.cut_on_nm is None:
            return np.ones_like(wl)
        return 1.0 / (1.0 + np.exp(-(wl - self.cut_on_nm) / (self.edge_nm / 4.4)))


def _default_gratings() -> tuple[Grating, ...]:
    return (Grating(1, 1200, "500NM", 500.0, 6.4, (180.0, 1400.0)),
            Grating(2, 600, "1.0UM", 1000.0, 12.8, (400.0, 2500.0), steps_per_nm=50.0))


def _default_filters() -> dict[int, FilterPosition]:
    return {1: FilterPosition("open"), 2: FilterPosition("400 nm long-pass", 400.0),
            3: FilterPosition("590 nm long-pass", 590.0), 4: FilterPosition("1000 nm long-pass", 1000.0),
            5: FilterPosition("open"), 6: FilterPosition("blocked", blocked=True)}


@dataclass(frozen=True)
class MonochromatorOptics:
    """The lamp, slits, gratings and filter wheel of the virtual monochromator (see the module docstring)."""

    lamp_temperature_k: float = 3000.0
    lamp_radiance_560: float = 0.1        # W sr-1 m-2 nm-1 of the lamp at 560 nm, before the monochromator
    transmittance: float = 0.3            # optics + diffusing sphere
    slit_mm: float = 1.0
    gratings: tuple[Grating, ...] = field(default_factory=_default_gratings)
    filters: dict[int, FilterPosition] = field(default_factory=_default_filters)

    def grating(self, number: int) -> Grating:
        for g in self.gratings:
            if g.number == number:
                return g
        raise KeyError(number)

    def fwhm_nm(self, grating: int = 1) -> float:
        """The band's full width at half maximum: slit width x reciprocal linear dispersion."""
        return self.slit_mm * self.grating(grating).dispersion_nm_per_mm

    def lamp(self, wavelengths: np.ndarray) -> np.ndarray:
        """The lamp's spectral radiance (W sr-1 m-2 nm-1): Planck at the lamp temperature, scaled at 560 nm."""
        from colour.colorimetry import planck_law

        wl = np.asarray(wavelengths, dtype=float)
        shape = planck_law(wl * 1e-9, self.lamp_temperature_k)
        return self.lamp_radiance_560 * np.asarray(shape) / float(planck_law(560e-9, self.lamp_temperature_k))

    def throughput(self, wavelengths: np.ndarray, grating: int = 1, filter_position: int = 1) -> np.ndarray:
        """tau * eta_g * T_f: what the monochromator passes of the lamp at each wavelength (before the slit)."""
        g = self.grating(grating)
        return self.transmittance * g.efficiency(wavelengths) * self.filters[filter_position].transmittance(
            wavelengths)

    def spectrum(self, set_nm: float, wavelengths: np.ndarray, grating: int = 1,
                 filter_position: int = 1) -> np.ndarray:
        """Spectral radiance of the output (W sr-1 m-2 nm-1) at ``wavelengths`` with the drive at ``set_nm``."""
        wl = np.asarray(wavelengths, dtype=float)
        fwhm = self.fwhm_nm(grating)
        slit = np.clip(1.0 - np.abs(wl - set_nm) / fwhm, 0.0, None)
        return self.lamp(wl) * self.throughput(wl, grating, filter_position) * slit

    def band(self, set_nm: float, grating: int = 1, filter_position: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """(wavelengths, radiance) sampling the band every SAMPLE_NM over +-FWHM around ``set_nm`` (the corners of
        the triangle fall on samples, so the trapezoid rule integrates the slit exactly)."""
        fwhm = self.fwhm_nm(grating)
        n = int(math.ceil(fwhm / SAMPLE_NM))
        wl = set_nm + SAMPLE_NM * np.arange(-n, n + 1, dtype=float)
        wl = np.concatenate(([set_nm - fwhm], wl[np.abs(wl - set_nm) < fwhm], [set_nm + fwhm]))
        return wl, self.spectrum(set_nm, wl, grating, filter_position)
