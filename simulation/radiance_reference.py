"""The radiance of a monochromator's output at each set wavelength: the reference a camera's spectral sensitivity
is measured against (thesis 4.2, eq 4.1: CSRF = DN / L).

Three kinds of file give it (docs/how-to/measure-stand.md documents them):

* **spectroradiometer readings**, one spectrum per set wavelength (a telespectroradiometer such as the Konica
  Minolta CS-2000 of the thesis, placed where the camera stands):

  - a spectral CSV ``wavelength_nm,mono_380,mono_390,...`` (a column per set wavelength, named by it: ``550``,
    ``mono_550``, ``set_550``, ``550nm``), optional ``# uncertainty_percent: <p>`` header;
  - a CGATS file with one row per set wavelength (``SAMPLE_NAME`` or ``SAMPLE_ID`` holding it, e.g.
    ``mono_550``) and spectral fields ``SPECTRAL_NM380`` ...;

  each spectrum is reduced to one number by a method of :data:`REDUCTION_METHODS`: ``integral`` (default: the
  band radiance, the spectrum integrated within +-``window_nm`` of the set wavelength; what a camera pixel
  integrates) or ``peak`` (the spectrum's maximum within the window, the thesis' L of eq 4.1). For a band of
  constant width the two differ by a constant factor, which the normalisation of the CSRF removes;
* **a radiance table** ``wavelength_nm,radiance[,u_radiance]``: the band radiance per set wavelength, already
  reduced (``u_radiance`` its standard uncertainty, same units);
* **a calibrated photodiode**: its responsivity file ``wavelength_nm,responsivity[,u_responsivity]`` (A/W, the
  calibration certificate) and the photocurrents read at each set wavelength
  ``wavelength_nm,photocurrent[,u_photocurrent]`` (A); the radiant power is ``I / R(lambda)`` (R interpolated
  linearly at the set wavelength), proportional to the band radiance for a fixed geometry.

Units only have to be consistent within a file: the CSRF is normalised afterwards. Every problem is a one-line
:class:`RadianceDataError` naming the file (and line or column) and what was expected.
"""
from __future__ import annotations

import logging
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.integrate import trapezoid

from dualrgb.simulation.spectral_io import SpectralDataError, SpectralTable, read_spectral_csv

log = logging.getLogger(__name__)

DEFAULT_WINDOW_NM = 20.0
MATCH_NM = 0.05                    # a set wavelength found in the file this close is taken as it is
_SET_NAME = re.compile(r"^(?:mono|set|nm)?[ _-]?(\d+(?:\.\d+)?)\s*(?:nm)?$", re.IGNORECASE)


class RadianceDataError(SpectralDataError):
    """A radiance reference file that cannot be used (one line: file, line or column, problem)."""


@dataclass(frozen=True)
class RadianceReference:
    """Band radiance (or radiant power) per set wavelength, with its relative standard uncertainty."""

    wavelengths: np.ndarray           # set wavelengths, nm, increasing
    radiance: np.ndarray              # one value per set wavelength (the file's units)
    u_relative: np.ndarray            # relative standard uncertainty per set wavelength (0: not given)
    source: str
    kind: str                         # 'spectroradiometer', 'radiance table' or 'photodiode'
    method: str = ""                  # how spectra were reduced (REDUCTION_METHODS), '' for tables
    meta: dict[str, str] = field(default_factory=dict)

    def at(self, wavelength_nm: float) -> tuple[float, float]:
        """(radiance, relative uncertainty) at a set wavelength: the file's value when it lists that wavelength,
        linear interpolation between the two around it otherwise; RadianceDataError outside the file's range."""
        wl = self.wavelengths
        k = int(np.argmin(np.abs(wl - wavelength_nm)))
        if abs(wl[k] - wavelength_nm) <= MATCH_NM:
            value, u = float(self.radiance[k]), float(self.u_relative[k])
        elif wl[0] <= wavelength_nm <= wl[-1]:
            value = float(np.interp(wavelength_nm, wl, self.radiance))
            u = float(np.interp(wavelength_nm, wl, self.u_relative))
        else:
            raise RadianceDataError(f"{self.source}: no reading at {wavelength_nm:g} nm (it covers "
                                    f"{wl[0]:g}-{wl[-1]:g} nm); measure the radiance over the whole range")
        if not value > 0:
            raise RadianceDataError(f"{self.source}: the radiance at {wavelength_nm:g} nm is {value:g}; a reading "
                                    "of the monochromator's output must be positive")
        return value, u

    def describe(self) -> dict[str, str]:
        d = {"radiance_reference": Path(self.source).name, "radiance_kind": self.kind}
        if self.method:
            d["radiance_reduction"] = self.method
        return d


# --------------------------------------------------------------------------------------------------- spectra
def _window(wl: np.ndarray, spectrum: np.ndarray, set_nm: float, window_nm: float) -> tuple[np.ndarray, np.ndarray]:
    inside = np.abs(wl - set_nm) <= window_nm
    return wl[inside], spectrum[inside]


def band_integral(wl: np.ndarray, spectrum: np.ndarray, set_nm: float, window_nm: float) -> float:
    """The spectrum integrated (trapezoid) within +-``window_nm`` of the set wavelength: the band radiance."""
    w, s = _window(wl, spectrum, set_nm, window_nm)
    return float(trapezoid(s, w)) if len(w) >= 2 else float("nan")


def band_peak(wl: np.ndarray, spectrum: np.ndarray, set_nm: float, window_nm: float) -> float:
    """The spectrum's maximum within +-``window_nm`` of the set wavelength.

    References
    ----------
    Thesis *High Dynamic Range Imaging for Dual-RGB System for Cultural Heritage*, 4.2, eq 4.1 (L, "the peak
    value of the light source radiance captured at lambda").
    """
    _, s = _window(wl, spectrum, set_nm, window_nm)
    return float(s.max()) if len(s) else float("nan")


#: How one measured spectrum becomes one number per set wavelength.
REDUCTION_METHODS: dict[str, Callable[[np.ndarray, np.ndarray, float, float], float]] = {
    "integral": band_integral,
    "peak": band_peak,
}


def set_wavelength(name: str, source: str, where: str) -> float:
    """The set wavelength a column or sample is named by ('550', 'mono_550', 'set_550', '550nm')."""
    m = _SET_NAME.match(name.strip())
    if m is None:
        raise RadianceDataError(f"{source}: {where} {name!r} does not name a set wavelength (expected e.g. "
                                "'mono_550' or '550')")
    return float(m.group(1))


def reduce_spectra(table: SpectralTable, set_nm: list[float], *, method: str = "integral",
                   window_nm: float = DEFAULT_WINDOW_NM) -> RadianceReference:
    """One value per set wavelength from spectra ``table.values[:, i]`` measured at ``set_nm[i]``."""
    if method not in REDUCTION_METHODS:
        raise ValueError(f"radiance reduction {method!r}: expected one of {', '.join(REDUCTION_METHODS)}")
    order = np.argsort(set_nm)
    wl_set = np.asarray(set_nm, dtype=float)[order]
    if np.any(np.diff(wl_set) <= 0):
        raise RadianceDataError(f"{table.source}: set wavelength {wl_set[np.argmin(np.diff(wl_set))]:g} nm is "
                                "measured twice")
    reduce = REDUCTION_METHODS[method]
    values = np.array([reduce(table.wavelengths, table.values[:, i], set_nm[i], window_nm) for i in order])
    bad = ~np.isfinite(values) | (values <= 0)
    if bad.any():
        nm = wl_set[int(np.argmax(bad))]
        raise RadianceDataError(f"{table.source}: the spectrum measured at {nm:g} nm has no positive reading "
                                f"within +-{window_nm:g} nm of it (is it the right column, in nm?)")
    u = _percent(table.meta.get("uncertainty_percent"), table.source)
    return RadianceReference(wl_set, values, np.full(len(values), u), table.source, "spectroradiometer", method,
                             dict(table.meta))


def _percent(text: str | None, source: str) -> float:
    if text is None:
        return 0.0
    try:
        value = float(text.rstrip("% "))
    except ValueError:
        raise RadianceDataError(f"{source}: uncertainty_percent {text!r} is not a number") from None
    if not 0 <= value < 100:
        raise RadianceDataError(f"{source}: uncertainty_percent {value:g} is outside 0..100")
    return value / 100.0


def _read_cgats_readings(path: Path) -> tuple[SpectralTable, list[float]]:
    from dualrgb.simulation.cgats import read_cgats

    cg = read_cgats(path)
    wl, values = cg.spectral_values()
    names = cg.names()
    set_nm = [set_wavelength(n, str(path), f"sample (line {line})") for n, line in zip(names, cg.row_lines,
                                                                                        strict=True)]
    meta = {k.lower(): v for k, v in cg.keywords.items()}
    return SpectralTable(wl, values, names, meta, str(path)), set_nm


# --------------------------------------------------------------------------------------------------- readers
def read_radiance_reference(path: str | Path, *, method: str = "integral",
                            window_nm: float = DEFAULT_WINDOW_NM) -> RadianceReference:
    """The radiance reference in ``path``: spectroradiometer spectra (CSV or CGATS) or a radiance table."""
    from dualrgb.simulation.cgats import is_cgats

    p = Path(path)
    if is_cgats(p):
        table, set_nm = _read_cgats_readings(p)
        return reduce_spectra(table, set_nm, method=method, window_nm=window_nm)
    table = read_spectral_csv(p, allow_negative=True)
    names = [c.strip().lower() for c in table.columns]
    if "radiance" in names:
        return _radiance_table(table, names)
    set_nm = [set_wavelength(c, str(p), "column") for c in table.columns]
    return reduce_spectra(table, set_nm, method=method, window_nm=window_nm)


def _column(table: SpectralTable, names: list[str], name: str, *, required: bool = True) -> np.ndarray | None:
    if name not in names:
        if required:
            raise RadianceDataError(f"{table.source}: no column {name!r} (columns: {', '.join(table.columns)})")
        return None
    values = table.values[:, names.index(name)]
    if np.any(values < 0):
        k = int(np.argmax(values < 0))
        raise RadianceDataError(f"{table.source}: column {name!r} is negative ({values[k]:g}) at "
                                f"{table.wavelengths[k]:g} nm")
    return values


def _radiance_table(table: SpectralTable, names: list[str]) -> RadianceReference:
    extra = set(names) - {"radiance", "u_radiance"}
    if extra:
        raise RadianceDataError(f"{table.source}: unexpected column(s) {', '.join(sorted(extra))} in a radiance "
                                "table (expected wavelength_nm,radiance[,u_radiance])")
    radiance = _column(table, names, "radiance")
    assert radiance is not None
    u = _column(table, names, "u_radiance", required=False)
    u_rel = np.zeros(len(radiance)) if u is None else u / np.where(radiance > 0, radiance, np.inf)
    return RadianceReference(table.wavelengths, radiance, u_rel, table.source, "radiance table", "", dict(table.meta))


def read_photodiode_reference(responsivity_path: str | Path, photocurrent_path: str | Path) -> RadianceReference:
    """Radiant power ``I / R(lambda)`` per set wavelength from a calibrated photodiode's responsivity (A/W) and
    the photocurrents (A) read at each set wavelength; uncertainties combined in quadrature."""
    resp = read_spectral_csv(responsivity_path)
    current = read_spectral_csv(photocurrent_path)
    r_names = [c.strip().lower() for c in resp.columns]
    i_names = [c.strip().lower() for c in current.columns]
    r = _column(resp, r_names, "responsivity")
    i = _column(current, i_names, "photocurrent")
    assert r is not None and i is not None
    wl = current.wavelengths
    if wl[0] < resp.wavelengths[0] or wl[-1] > resp.wavelengths[-1]:
        raise RadianceDataError(f"{responsivity_path}: the responsivity covers {resp.wavelengths[0]:g}-"
                                f"{resp.wavelengths[-1]:g} nm but photocurrents were read at {wl[0]:g}-{wl[-1]:g} nm")
    r_at = np.interp(wl, resp.wavelengths, r)
    if np.any(r_at <= 0):
        raise RadianceDataError(f"{responsivity_path}: responsivity 0 at {wl[int(np.argmax(r_at <= 0))]:g} nm")
    u_r = _column(resp, r_names, "u_responsivity", required=False)
    u_i = _column(current, i_names, "u_photocurrent", required=False)
    rel_r = np.zeros(len(wl)) if u_r is None else np.interp(wl, resp.wavelengths, u_r) / r_at
    rel_i = np.zeros(len(wl)) if u_i is None else u_i / np.where(i > 0, i, np.inf)
    return RadianceReference(wl, i / r_at, np.hypot(rel_r, rel_i), str(photocurrent_path), "photodiode", "",
                             {"responsivity": str(responsivity_path)})
