"""A roles file to start from (``dualrgb import FOLDER --roles-template ROLES.csv``, the window's table before it is
edited): every raw file of a folder in capture order, with a role and a light guessed for the technician to check.

How it guesses, from each file's metadata and its signal (the mosaic's mean above black, as a fraction of the
range up to white; a subsample):

* a frame whose signal is under :data:`DARK_SIGNAL` is a dark (lens capped: its exposure is what matters);
* the lit frames form groups: a new group starts after a dark, after a pause longer than :data:`GAP_S` (the
  technician changed what lies on the stand) or where the signal jumps by more than :data:`JUMP` times at the same
  exposure (another subject under the same light);
* the first group is the flats (open gate), the next two the training and the test target, every later one an
  original (``ORIGINAL-1``, ``ORIGINAL-2``, ... to be replaced by its identifier);
* within a group the lights follow in order (the copy stand shoots every frame under light 1, then light 2): the
  group is cut into as many equal runs as there are lights.

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

from dualrgb.app.workflow.import_roles import COLUMNS, INFORMATION, write_roles
from dualrgb.app.workflow.vocabulary import Role

log = logging.getLogger(__name__)

RAW_SUFFIXES = frozenset({".nef", ".nrw", ".cr2", ".cr3", ".crw", ".arw", ".srf", ".sr2", ".dng", ".iiq", ".orf",
                          ".rw2", ".pef", ".raf", ".3fr", ".fff", ".erf", ".kdc", ".mos", ".mef", ".srw", ".rwl",
                          ".x3f"})
DARK_SIGNAL = 0.01          # of the range black..white: a capped lens
GAP_S = 20.0                # a pause that means something else was put on the stand
JUMP = 1.5                  # the signal at one exposure changing this many times: another subject
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


def _new_group(prev: Guess | None, g: Guess) -> bool:
    if prev is None or prev.role == Role.DARK.value:
        return True
    if prev.seconds is not None and g.seconds is not None and g.seconds - prev.seconds > GAP_S:
        return True
    same_t = prev.exposure_s is not None and g.exposure_s == prev.exposure_s
    if same_t and prev.signal and g.signal:
        return max(prev.signal, g.signal) / max(min(prev.signal, g.signal), 1e-9) > JUMP
    return False


def guess_roles(guesses: Sequence[Guess], n_lights: int = 2) -> list[Guess]:
    """Roles, lights and identifiers guessed (module docstring) in place; returns ``guesses``."""
    groups: list[list[Guess]] = []
    prev: Guess | None = None
    for g in guesses:
        if g.why.startswith("not importable"):
            continue
        if g.signal is not None and g.signal < DARK_SIGNAL:
            g.role, g.why = Role.DARK.value, f"dark: signal {100 * g.signal:.2f} % of white"
        elif _new_group(prev, g):
            groups.append([g])
        else:
            groups[-1].append(g)
        prev = g
    names = [(Role.FLAT.value, ""), (Role.TARGET.value, "train"), (Role.TARGET.value, "test")]
    for i, group in enumerate(groups):
        role, ident = names[i] if i < len(names) else (Role.ORIGINAL.value, f"ORIGINAL-{i - len(names) + 1}")
        per = max(1, math.ceil(len(group) / n_lights))
        for j, g in enumerate(group):
            g.role, g.identifier, g.light = role, ident, str(min(n_lights, j // per + 1))
            g.why = (f"group {i + 1} ({len(group)} frames): {role}{' ' + ident if ident else ''}, light by order; "
                     f"signal {100 * (g.signal or 0):.1f} % of white")
    return list(guesses)


def write_template(folder: Path, out: Path, n_lights: int = 2) -> list[Guess]:
    """Write the roles template of ``folder`` to ``out`` (module docstring); returns its rows."""
    guesses = guess_roles(read_guesses(folder), n_lights)
    if not guesses:
        raise ValueError(f"{folder}: no raw files ({', '.join(sorted(RAW_SUFFIXES))})")
    write_roles(out, HEADER, [g.cells() for g in guesses])
    return guesses


__all__ = ["DARK_SIGNAL", "GAP_S", "HEADER", "JUMP", "RAW_SUFFIXES", "Guess", "guess_roles", "raw_files",
           "read_guesses", "write_template"]
