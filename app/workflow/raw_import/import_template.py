"""A roles file to start from (``dualrgb import FOLDER --roles-template ROLES.csv``, the window's table before it is
edited): every raw file of a folder in capture order, with a role and a light guessed for the technician to check.

How it guesses, from each file's metadata and its signal (the mosaic's mean above black, as a fraction of the
range up to white):

* a frame whose signal is under :data:`DARK_SIGNAL` is a dark (lens capped: its exposure is what matters);
* each light has its own exposure (auto-exposure on the open gate): the lit exposures, in the order they first
  appear, are lights 1, 2, ... (an HDR bracket's longer exposures are not told apart: check them);
* at one exposure the open gate is the brightest thing on the stand: a lit frame within :data:`FLAT_SHARE` of the
  brightest frame at its exposure is a flat;
* the other lit frames are subjects, one after the other: a new one starts after a pause longer than
  :data:`GAP_S` (something else was put on the stand) or when the lights start again from an earlier one (every
  subject is shot under light 1, then light 2, ...); the first subject is the training target, the second the
  test target, every later one an original (``ORIGINAL-1``, ``ORIGINAL-2``, ... to be replaced by its
  identifier).

The ``guess`` column says why; ``exposure_s``, ``captured_at`` and ``camera`` show what the file says (all four are
information: an import reads the files again and ignores them). A file that cannot be imported (not a Bayer raw)
is listed with an empty role and the reason, so nothing in the folder goes unmentioned.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from dualrgb.app.workflow.raw_import.import_roles import COLUMNS, INFORMATION, write_roles
from dualrgb.core.vocabulary import Role

log = logging.getLogger(__name__)

RAW_SUFFIXES = frozenset({".nef", ".nrw", ".cr2", ".cr3", ".crw", ".arw", ".srf", ".sr2", ".dng", ".iiq", ".orf",
                          ".rw2", ".pef", ".raf", ".3fr", ".fff", ".erf", ".kdc", ".mos", ".mef", ".srw", ".rwl",
                          ".x3f"})
DARK_SIGNAL = 0.01          # of the range black..white: a capped lens
FLAT_SHARE = 0.8            # of the brightest frame at the same exposure: the open gate
GAP_S = 20.0                # a pause that means something else was put on the stand
HEADER = [*COLUMNS, "title", *INFORMATION]


@dataclass
class Guess:
    """One file's row of the template."""

    file: str
    role: str = ""
    light: str = ""
    identifier: str = ""
    exposure_s: float | None = None
    captured_at: str = ""
    camera: str = ""
    signal: float | None = None
    why: str = ""
    seconds: float | None = None            # capture time as seconds (for gaps)

    def cells(self) -> list[str]:
        return [self.file, self.role, self.light, self.identifier, "",
                "" if self.exposure_s is None else f"{self.exposure_s:.6g}", self.captured_at, self.camera, self.why]


def raw_files(folder: Path) -> list[Path]:
    """The folder's raw files (by extension, as LibRaw's formats are named), by name."""
    return sorted(p for p in Path(folder).iterdir() if p.is_file() and p.suffix.lower() in RAW_SUFFIXES)


def read_guesses(folder: Path) -> list[Guess]:
    """Every raw file's metadata and signal, in capture order (unreadable files last, with the reason)."""
    from dualrgb.drivers.raw import RawFileError
    from dualrgb.drivers.raw_metadata import exiftool_tags, read_raw_metadata

    files = raw_files(folder)
    tool = exiftool_tags(files)
    good, bad = [], []
    for path in files:
        try:
            m = read_raw_metadata(path, tool.get(path))
        except RawFileError as exc:
            bad.append(Guess(path.name, why=f"not importable: {exc.problem}"))
            continue
        when = m.captured_at
        good.append(Guess(path.name, exposure_s=m.exposure_s, captured_at=when.isoformat() if when else "",
                          camera=m.camera, signal=m.extra.get("signal"),
                          seconds=when.timestamp() if when else None))
    good.sort(key=lambda g: (g.seconds if g.seconds is not None else math.inf, g.file))
    return good + bad


def _lights(lit: Sequence[Guess], n_lights: int) -> dict[float | None, int]:
    """Exposure -> light number: the lit exposures in the order they first appear (capped at ``n_lights``)."""
    order = list(dict.fromkeys(g.exposure_s for g in lit))
    return {t: min(i + 1, n_lights) for i, t in enumerate(order)}


def _subjects(frames: Sequence[Guess], light: dict[float | None, int]) -> list[list[Guess]]:
    """The subjects' frames: a new subject after a pause or when the lights start again from an earlier one."""
    out: list[list[Guess]] = []
    prev: Guess | None = None
    for g in frames:
        paused = (prev is not None and prev.seconds is not None and g.seconds is not None
                  and g.seconds - prev.seconds > GAP_S)
        if prev is None or paused or light[g.exposure_s] < light[prev.exposure_s]:
            out.append([g])
        else:
            out[-1].append(g)
        prev = g
    return out


def guess_roles(guesses: Sequence[Guess], n_lights: int = 2) -> list[Guess]:
    """Roles, lights and identifiers guessed (module docstring) in place; returns ``guesses``."""
    usable = [g for g in guesses if not g.why.startswith("not importable")]
    for g in usable:
        if g.signal is not None and g.signal < DARK_SIGNAL:
            g.role, g.why = Role.DARK.value, f"dark: signal {100 * g.signal:.2f} % of white"
    lit = [g for g in usable if not g.role]
    light = _lights(lit, n_lights)
    brightest: dict[float | None, float] = {}
    for g in lit:
        brightest[g.exposure_s] = max(brightest.get(g.exposure_s, 0.0), g.signal or 0.0)
    for g in lit:
        g.light = str(light[g.exposure_s])
        if (g.signal or 0.0) >= FLAT_SHARE * brightest[g.exposure_s]:
            g.role = Role.FLAT.value
            g.why = f"flat: the brightest at its exposure ({100 * (g.signal or 0):.1f} % of white)"
    names = [(Role.TARGET.value, "train"), (Role.TARGET.value, "test")]
    for i, subject in enumerate(_subjects([g for g in lit if not g.role], light)):
        role, ident = names[i] if i < len(names) else (Role.ORIGINAL.value, f"ORIGINAL-{i - len(names) + 1}")
        for g in subject:
            g.role, g.identifier = role, ident
            g.why = (f"subject {i + 1} ({len(subject)} frames): {role} {ident}; signal {100 * (g.signal or 0):.1f} % "
                     "of white")
    return list(guesses)


def template_table(folder: Path, n_lights: int = 2) -> tuple[list[str], list[list[str]]]:
    """The template's header and rows for ``folder`` (what :func:`write_template` writes; the window's table)."""
    guesses = guess_roles(read_guesses(folder), n_lights)
    if not guesses:
        raise ValueError(f"{folder}: no raw files ({', '.join(sorted(RAW_SUFFIXES))})")
    return list(HEADER), [g.cells() for g in guesses]


def write_template(folder: Path, out: Path, n_lights: int = 2) -> list[Guess]:
    """Write the roles template of ``folder`` to ``out`` (module docstring); returns its rows."""
    guesses = guess_roles(read_guesses(folder), n_lights)
    if not guesses:
        raise ValueError(f"{folder}: no raw files ({', '.join(sorted(RAW_SUFFIXES))})")
    write_roles(out, HEADER, [g.cells() for g in guesses])
    return guesses


__all__ = ["DARK_SIGNAL", "FLAT_SHARE", "GAP_S", "HEADER", "RAW_SUFFIXES", "Guess", "guess_roles", "raw_files",
           "read_guesses", "template_table", "write_template"]
