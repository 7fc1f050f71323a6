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
            out.add(parse_reading_id(name, str(p), n_leds), table.values[:, j].copy())
        out.sources.append(str(p))
    if out is None:
        raise ValueError("no reading files given")
    out.sort()
    log.info("read %d files: levels of LEDs %s, warm-up of LEDs %s", len(out.sources), sorted(out.levels),
             sorted(out.warmup))
    return out
