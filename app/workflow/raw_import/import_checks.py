"""Everything an import of raw files checks before it writes anything (``dualrgb import``, the window's *Import raw
files...*): each problem one line naming the file (or the roles file's row), all of them listed at once.

* the files: each named in the roles file exists in the folder, once; LibRaw reads it as a 2x2 Bayer mosaic (a film
  scanner's RGB NEF, a linear DNG are refused: drivers.raw_metadata); no two files are the same bytes (sha256);
* the shot, read from each file's metadata (LibRaw, exiftool): an exposure time on every file; one camera (model
  and serial), one ISO, one aperture, one sensor (size, CFA) for the whole import;
* the calibration: dark frames at every exposure a lit frame used (+-2 %, as a master dark serves); a light for every
  lit frame, within the preset's lights; flats, the training and the test target under every light; calibration
  exposures within the light-on cap a profile holds; the targets' reference data and grids usable;
* the originals: each under every light; one mode (the calibration's); their deliverables folders free;
* the session folder: new, or a session of this same import (resumed: the frames it holds are kept).
"""
from __future__ import annotations

import hashlib
import logging
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dualrgb.app.workflow.calibration.profile_check import DARK_RTOL, MAX_EXPOSURE_S
from dualrgb.app.workflow.raw_import.import_roles import RoleRow, RolesTable
from dualrgb.core.vocabulary import TARGET_NAMES, NamedLight, Role, Subject, format_exposure, light_name
from dualrgb.simulation.lightsource import LightSource

if TYPE_CHECKING:
    from dualrgb.app.processing.patches import PatchGrid
    from dualrgb.app.workflow.calibration.targets import TargetSpec
    from dualrgb.drivers.raw_metadata import RawMetadata
    from dualrgb.simulation.charts import Chart
    from dualrgb.simulation.presets import Preset

log = logging.getLogger(__name__)

UNKNOWN_PRESET = "unknown"          # the preset of an import without one: its lights are unknown
MAX_NAMED = 3                       # files named in one line before '(and N more)'
DOSE_UNKNOWN = "light dose unknown: the frames were shot by another program (no lit period was recorded)"


def imported_warnings(session_settings: dict) -> list[str]:
    """What every delivery of an imported session's originals says (``dualrgb process`` too): the dose unknown."""
    return [DOSE_UNKNOWN] if session_settings.get("imported") else []


class ImportRefused(ValueError):
    """An import refused before anything was written: ``lines`` holds one line per problem."""

    def __init__(self, lines: Sequence[str]):
        self.lines = list(lines)
        super().__init__(f"{len(self.lines)} problem{'s' if len(self.lines) > 1 else ''}; nothing was written"
                         + (f": {self.lines[0]}" if len(self.lines) == 1 else ""))


@dataclass(frozen=True)
class ImportFrame:
    """One raw file to import: its row in the roles file, what its metadata say, its bytes' sha256."""

    row: RoleRow
    meta: RawMetadata
    sha256: str
    size: int

    @property
    def path(self) -> Path:
        return self.meta.path

    @property
    def exposure_s(self) -> float:
        assert self.meta.exposure_s is not None            # checked (every file's exposure is known)
        return float(f"{self.meta.exposure_s:.6g}")


@dataclass
class ImportSettings:
    """What an import is asked to do besides its files (the calibrate options)."""

    mode: str
    preset: Preset | None = None                      # None: the lights are unknown
    charts: dict[str, Chart] = field(default_factory=dict)
    grids: dict[str, PatchGrid] = field(default_factory=dict)   # 'train' / 'test' -> grid in stack pixels
    session: Path | None = None
    out_dir: Path | None = None                       # the deliverables (default <session>/deliverables)


def sha256_of(path: Path, chunk: int = 1 << 22) -> tuple[str, int]:
    """(sha256 hex digest, size in bytes) of a file, read in chunks."""
    h, size = hashlib.sha256(), 0
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(chunk), b""):
            h.update(block)
            size += len(block)
    return h.hexdigest(), size


def capture_order(frames: Sequence[ImportFrame]) -> list[ImportFrame]:
    """The frames by capture time (the camera's clock), then by name (a camera's counter within a second)."""
    return sorted(frames, key=lambda f: (f.meta.captured_at or datetime.max, f.row.file))


def _named(files: Sequence[str]) -> str:
    more = f" (and {len(files) - MAX_NAMED} more)" if len(files) > MAX_NAMED else ""
    return ", ".join(files[:MAX_NAMED]) + more


def unlisted_files(folder: Path, rows: Sequence[RoleRow]) -> list[str]:
    """A note naming the folder's raw files that no row of the roles file lists: left out of the import, said (a test
    shot, or a row forgotten), never skipped silently."""
    from dualrgb.app.workflow.raw_import.import_template import raw_files

    listed = {row.file for row in rows}
    left = [p.name for p in raw_files(folder) if p.name not in listed]
    if not left:
        return []
    return [f"{len(left)} raw file{'s' if len(left) > 1 else ''} in {folder} not in the roles file, left out of the "
            f"import: {_named(left)}"]


def read_frames(folder: Path, rows: Sequence[RoleRow], where: Callable[[int], str],
                progress: Callable[[float, str], None] | None = None) -> tuple[list[ImportFrame], list[str]]:
    """Each row's file read (metadata and sha256) and the problems: missing, listed twice, unreadable or not a
    Bayer mosaic, the same bytes as another file."""
    from dualrgb.drivers.raw import RawFileError
    from dualrgb.drivers.raw_metadata import exiftool_tags, read_raw_metadata

    problems: list[str] = []
    seen: dict[str, int] = {}
    todo = []
    for row in rows:
        path = folder / row.file
        if row.file in seen:
            problems.append(f"{where(row.row)}: {row.file} is also row {seen[row.file]} (one role per file)")
        elif not path.is_file():
            problems.append(f"{path}: no such file in {folder} ({where(row.row)})")
        else:
            todo.append(row)
        seen.setdefault(row.file, row.row)
    tool = exiftool_tags([folder / r.file for r in todo])
    frames: list[ImportFrame] = []
    by_hash: dict[str, str] = {}
    for i, row in enumerate(todo):
        path = folder / row.file
        if progress is not None:
            progress(i / max(1, len(todo)), f"reading {row.file}")
        try:
            meta = read_raw_metadata(path, tool.get(path))
            digest, size = sha256_of(path)
        except RawFileError as exc:
            problems.append(str(exc))
            continue
        except OSError as exc:
            problems.append(f"{path}: cannot read ({exc.strerror or exc})")
            continue
        if digest in by_hash:
            problems.append(f"{path}: the same file as {by_hash[digest]} (sha256 {digest[:12]}...): a duplicate, "
                            "refused (each frame is imported once)")
            continue
        by_hash[digest] = row.file
        frames.append(ImportFrame(row, meta, digest, size))
    return capture_order(frames), problems


def _odd_ones(frames: Sequence[ImportFrame], what: str, key: Callable[[ImportFrame], Any],
              show: Callable[[Any], str]) -> list[str]:
    """One line per file whose ``key`` differs from the most common one (one camera, one ISO ... per import)."""
    values = Counter(key(f) for f in frames)
    if len(values) < 2:
        return []
    usual = values.most_common(1)[0][0]
    return [f"{f.path}: {what} {show(key(f))}, the other files {show(usual)} (one {what} per import)"
            for f in frames if key(f) != usual]


def shot_problems(frames: Sequence[ImportFrame]) -> tuple[list[str], list[str]]:
    """(problems, notes) of the shots' metadata: exposure known, one camera, ISO, aperture and sensor."""
    problems = [f"{f.path}: no exposure time in its metadata (LibRaw, exiftool): an import needs each frame's "
                "exposure to match darks and merge exposures" for f in frames if f.meta.exposure_s is None]
    problems += _odd_ones(frames, "camera", lambda f: (f.meta.camera, f.meta.serial),
                          lambda v: f"{v[0] or 'unknown'!r} serial {v[1] or 'unknown'!r}")
    problems += _odd_ones(frames, "ISO", lambda f: f.meta.iso, lambda v: "unknown" if v is None else f"{v:g}")
    problems += _odd_ones(frames, "aperture", lambda f: f.meta.aperture,
                          lambda v: "unknown" if v is None else f"f/{v:g}")
    problems += _odd_ones(frames, "sensor", lambda f: (f.meta.width, f.meta.height, f.meta.cfa),
                          lambda v: f"{v[0]}x{v[1]} px {v[2]}")
    notes = []
    for what, missing in (("ISO", [f for f in frames if f.meta.iso is None]),
                          ("aperture", [f for f in frames if f.meta.aperture is None]),
                          ("camera serial", [f for f in frames if not f.meta.serial]),
                          ("capture time", [f for f in frames if f.meta.captured_at is None])):
        if missing and len(missing) == len(frames):
            notes.append(f"no {what} in the files' metadata ({_named([f.row.file for f in missing])})")
    return problems, notes


def dark_problems(frames: Sequence[ImportFrame]) -> list[str]:
    """One line per exposure a lit frame used that no dark frame was shot at (+-2 %, as a master dark serves)."""
    darks = sorted({f.exposure_s for f in frames if f.row.role is Role.DARK})
    lit: dict[float, list[str]] = {}
    for f in frames:
        if f.row.role is not Role.DARK and f.meta.exposure_s is not None:
            lit.setdefault(f.exposure_s, []).append(str(f.path))
    have = ", ".join(format_exposure(t) for t in darks) or "none"
    return [f"{files[0]}: its exposure {format_exposure(t)} has no dark frame (darks at: {have}); shoot darks at "
            f"{format_exposure(t)} with the lens capped" + (f" (also {_named(files[1:])})" if len(files) > 1 else "")
            for t, files in sorted(lit.items()) if not any(abs(d - t) <= DARK_RTOL * max(d, t) for d in darks)]


def import_lights(preset: Preset | None, numbers: Sequence[int]) -> list[NamedLight]:
    """The calibration's lights: the preset's (every one of them), or with no preset lights 1..n named
    ``unknown light N`` whose LEDs and levels are unknown (an empty LightSource)."""
    from dualrgb.core.vocabulary import lights_of

    if preset is not None:
        return lights_of(preset)
    return [NamedLight(name, LightSource((), (), name))
            for name in (light_name(UNKNOWN_PRESET, n) for n in range(1, max(numbers, default=0) + 1))]


def lights_known(lights: Sequence[NamedLight]) -> bool:
    return all(nl.light.leds for nl in lights)


def light_problems(frames: Sequence[ImportFrame], lights: Sequence[NamedLight], preset: Preset | None,
                   where: Callable[[int], str]) -> list[str]:
    """Every lit frame's light is one of the calibration's; flats and both targets under every light; each
    original under every light; calibration exposures within the light-on cap."""
    n = len(lights)
    out = [f"{where(f.row.row)}: {f.row.file}: light {f.row.light}, but preset {preset.name} has {n} light"
           f"{'s' if n > 1 else ''}" for f in frames
           if preset is not None and f.row.light is not None and f.row.light > n]
    lit = [f for f in frames if f.row.light is not None and f.row.light <= n]
    for number in range(1, n + 1):
        under = [f for f in lit if f.row.light == number]
        name = lights[number - 1].name
        for role, ident, what in ((Role.FLAT, "", "flat (open-gate) frame"),
                                  *((Role.TARGET, t, f"frame of the {Subject.target(t).label}") for t in TARGET_NAMES)):
            if not any(f.row.role is role and f.row.identifier == ident for f in under):
                out.append(f"light {number} ({name}): no {what} under it in the roles file")
        for ident in sorted({f.row.identifier for f in lit if f.row.role is Role.ORIGINAL}):
            if not any(f.row.role is Role.ORIGINAL and f.row.identifier == ident for f in under):
                first = next(f for f in lit if f.row.identifier == ident)
                out.append(f"{where(first.row.row)}: original {ident!r} has no frame under light {number} ({name})")
    out += [f"{f.path}: a {f.row.role.value} frame of {format_exposure(f.exposure_s)}: a calibration holds "
            f"exposures up to {MAX_EXPOSURE_S:g} s (the light-on cap)" for f in lit
            if f.row.role in (Role.FLAT, Role.TARGET) and f.meta.exposure_s is not None
            and f.exposure_s > MAX_EXPOSURE_S]
    return out


def target_specs(settings: ImportSettings) -> tuple[dict[str, TargetSpec], list[str]]:
    """The training and test targets' specs (reference data, grid) or the lines saying why one cannot be used."""
    from dualrgb.app.workflow.calibration.targets import target_spec
    from dualrgb.simulation.charts import ChartError

    specs, problems = {}, []
    for name in TARGET_NAMES:
        try:
            specs[name] = target_spec(settings.mode, Subject.target(name), settings.grids.get(name),
                                      chart=settings.charts.get(name))
        except (ValueError, ChartError) as exc:
            problems.append(str(exc))
    return specs, problems


def mode_problems(roles: RolesTable, mode: str) -> list[str]:
    """One mode per import: every original's mode is the calibration's."""
    return [f"{roles.source}: original {o.identifier!r} is {o.mode}, the import calibrates {mode} (one mode per "
            "import: import the other mode's files with --mode and their own targets)"
            for o in roles.originals.values() if o.mode != mode]


__all__ = ["DOSE_UNKNOWN", "ImportFrame", "ImportRefused", "ImportSettings", "UNKNOWN_PRESET", "capture_order",
           "corner_grid", "dark_problems",
           "parse_corners", "import_lights", "imported_warnings", "light_problems", "lights_known",
           "mode_problems", "read_frames", "sha256_of", "shot_problems", "target_specs", "unlisted_files"]


def parse_corners(text: str) -> tuple[float, ...]:
    """``X,Y,X,Y,X,Y,X,Y`` (commas, semicolons or spaces between) -> the 8 numbers, or ValueError (one line)."""
    import math

    parts = [p for p in text.replace(";", ",").replace(" ", ",").split(",") if p.strip()]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 8 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"corners {text!r}: expected X,Y,X,Y,X,Y,X,Y: the chart's top-left, top-right, "
                         "bottom-right and bottom-left corners in the raw file's pixels")
    return values


def corner_grid(mode: str, name: str, corners: Sequence[float], charts: dict[str, Chart] | None = None
                ) -> PatchGrid:
    """The patch grid of target ``name`` from its four corners on the sensor (x, y in the raw file's pixels, the
    outer corners of its corner patches: top-left, top-right, bottom-right, bottom-left of the chart, where one
    clicks them in an image viewer), its rows and columns the chart's layout; in the processed stack's (2x2-cell)
    pixels."""
    from dualrgb.app.processing.patches import PatchGrid
    from dualrgb.app.workflow.calibration.targets import chart_of

    if len(corners) != 8:
        raise ValueError(f"{name} corners: {len(corners)} numbers, expected 8 (x,y of the top-left, top-right, "
                         "bottom-right and bottom-left corners)")
    rows, cols = chart_of(mode, name, charts).layout
    return PatchGrid(np.reshape(np.asarray(corners, dtype=float), (4, 2)), rows, cols).scaled(0.5)
