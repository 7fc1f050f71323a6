"""Spectroradiometer readings of the sphere's LEDs: what each reading is, and reading them from instrument files.

A reading is named by one grammar (the CGATS ``SAMPLE_ID``, the CSV column, or the file name of a one-reading
file such as ArgyllCMS ``spotread``'s ``.sp``), built by :func:`level_id` / :func:`warmup_id` and read by
:func:`parse_reading_id`:

* ``LED<n>_level<x>``: LED ``n`` alone at PWM level ``x`` (0..1), e.g. ``LED3_level0.05``; level 1 is its
  spectrum at full level;
* ``LED<n>_t<s>``: LED ``n`` alone at full level, ``s`` seconds after it came on (a warm-up series), e.g.
  ``LED3_t120``.

Files (:func:`read_readings`): spectral CGATS files (``.ti3``, ``.sp``, ... with SPEC_<nm> / nm<nm> fields,
``simulation.cgats``) and spectral CSVs (``wavelength_nm`` then one column per reading,
``simulation.spectral_io``), all on the same wavelengths, in one unit (spectral radiance: the files' ``units``).
"""
from __future__ import annotations

import logging
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

MAX_RADIANCE = 1e6              # no LED reads within six orders of this (W/(sr m^2 nm)); 1e308 is an edit
NEGATIVE_NOISE = 0.05           # a reading may dip below 0 by this fraction of its peak (instrument noise)
_ID = re.compile(r"^LED(\d{1,2})_(?:level(\d+(?:\.\d*)?(?:e-?\d+)?)|t(\d+(?:\.\d*)?))$", re.IGNORECASE)
ID_EXAMPLES = "LED3_level0.05 (LED 3 at level 0.05) or LED3_t120 (LED 3 at full level, 120 s after it came on)"


@dataclass(frozen=True)
class ReadingId:
    """LED ``led`` (1-based) at ``level``, or at full level ``t_s`` seconds after it came on (warm-up)."""

    led: int
    level: float | None = None
    t_s: float | None = None

    @property
    def warmup(self) -> bool:
        return self.t_s is not None


def level_id(led: int, level: float) -> str:
    return f"LED{int(led)}_level{float(level):.6g}"


def warmup_id(led: int, t_s: float) -> str:
    return f"LED{int(led)}_t{float(t_s):.1f}"


def parse_reading_id(text: str, where: str = "", n_leds: int = 10) -> ReadingId:
    """The :class:`ReadingId` of a reading's name; ``ValueError`` (one line naming ``where``) otherwise."""
    m = _ID.match(text.strip())
    prefix = f"{where}: " if where else ""
    if not m:
        raise ValueError(f"{prefix}reading {text!r}: expected a name like {ID_EXAMPLES}")
    led = int(m.group(1))
    if not 1 <= led <= n_leds:
        raise ValueError(f"{prefix}reading {text!r}: LED {led} outside 1..{n_leds}")
    if m.group(2) is not None:
        level = float(m.group(2))
        if not 0.0 <= level <= 1.0:
            raise ValueError(f"{prefix}reading {text!r}: level {level:g} outside 0..1")
        return ReadingId(led, level=level)
    return ReadingId(led, t_s=float(m.group(3)))


@dataclass
class LedReadings:
    """Readings by LED: ``levels[led]`` = [(level, spectrum)], ``warmup[led]`` = [(seconds on, spectrum)], all at
    ``wavelengths`` in ``units``; ``sources`` the files they came from."""

    wavelengths: np.ndarray
    units: str = ""
    levels: dict[int, list[tuple[float, np.ndarray]]] = field(default_factory=dict)
    warmup: dict[int, list[tuple[float, np.ndarray]]] = field(default_factory=dict)
    sources: list[str] = field(default_factory=list)

    def add(self, rid: ReadingId, spectrum: np.ndarray) -> None:
        if rid.t_s is not None:
            self.warmup.setdefault(rid.led, []).append((rid.t_s, spectrum))
        else:
            assert rid.level is not None
            self.levels.setdefault(rid.led, []).append((rid.level, spectrum))

    def sort(self) -> None:
        for series in (*self.levels.values(), *self.warmup.values()):
            series.sort(key=lambda p: p[0])

    @property
    def leds(self) -> list[int]:
        return sorted(set(self.levels) | set(self.warmup))


def _read_table(path: Path):
    from dualrgb.simulation.cgats import is_cgats, read_cgats_emission
    from dualrgb.simulation.spectral_io import read_spectral_csv

    if is_cgats(path):
        return read_cgats_emission(path)
    return read_spectral_csv(path, allow_negative=True)


def check_spectrum(spectrum: np.ndarray, where: str) -> np.ndarray:
    """A reading's spectrum if it can be one: finite and within :data:`MAX_RADIANCE`; ValueError otherwise."""
    if not np.isfinite(spectrum).all():
        raise ValueError(f"{where}: holds a value that is not a finite number")
    peak, low = float(spectrum.max()), float(spectrum.min())
    if max(abs(peak), abs(low)) > MAX_RADIANCE:
        raise ValueError(f"{where}: value {peak if abs(peak) >= abs(low) else low:g} is not a radiance an LED gives "
                         f"(at most {MAX_RADIANCE:g})")
    return spectrum


def check_leds(readings: LedReadings) -> None:
    """Each LED's lit readings (level > 0, warm-up) rise above 0 somewhere, and no reading dips below 0 by more
    than instrument noise (:data:`NEGATIVE_NOISE` of the LED's brightest reading); ValueError naming the LED."""
    for led in readings.leds:
        lit = [s for lv, s in readings.levels.get(led, []) if lv > 0] + [s for _, s in readings.warmup.get(led, [])]
        peak = max((float(s.max()) for s in lit), default=0.0)
        if lit and peak <= 0:
            raise ValueError(f"LED {led}: every lit reading is 0 or below at every wavelength "
                             f"({', '.join(readings.sources)}): are they the right readings?")
        low = min(float(s.min()) for s in [*(s for _, s in readings.levels.get(led, [])), *lit])
        if low < -NEGATIVE_NOISE * max(peak, 0.0) and low < 0:
            raise ValueError(f"LED {led}: a reading reaches {low:g}, below the instrument noise ({NEGATIVE_NOISE:.0%} "
                             f"of its brightest reading, {peak:g}); expected spectral radiances")


def read_readings(paths: Iterable[str | Path], n_leds: int = 10) -> LedReadings:
    """Every reading in ``paths`` (module docstring), checked: one set of wavelengths, names in the grammar."""
    out: LedReadings | None = None
    for p in map(Path, paths):
        table = _read_table(p)
        units = table.meta.get("dualrgb_units") or table.meta.get("units", "")
        if out is None:
            out = LedReadings(table.wavelengths, units)
        elif len(table.wavelengths) != len(out.wavelengths) or not np.allclose(table.wavelengths, out.wavelengths):
            raise ValueError(f"{p}: wavelengths {table.wavelengths[0]:g}-{table.wavelengths[-1]:g} nm "
                             f"({len(table.wavelengths)} samples) differ from the first file's "
                             f"{out.wavelengths[0]:g}-{out.wavelengths[-1]:g} nm ({len(out.wavelengths)}); "
                             "export every reading with the same sampling")
        for j, name in enumerate(table.columns):
            out.add(parse_reading_id(name, str(p), n_leds),
                    check_spectrum(table.values[:, j].copy(), f"{p}: reading {name!r}"))
        out.sources.append(str(p))
    if out is None:
        raise ValueError("no reading files given")
    check_leds(out)
    out.sort()
    log.info("read %d files: levels of LEDs %s, warm-up of LEDs %s", len(out.sources), sorted(out.levels),
             sorted(out.warmup))
    return out
