"""Charts as data: a colour chart's reference spectra (as its file gives them), its layout on the stand and the
patches the calibration leaves out. The packaged targets are charts of the same kind; ``dualrgb calibrate
--train-target / --test-target``, the GUI's calibration box and the demo read a stand's own through
:func:`read_chart`, which reads the spectra through the one reader of reference spectra
(simulation.datasets.load_target: spectral CGATS from X-Rite, BabelColor or ArgyllCMS, or a spectral CSV).

Layout: ``rows`` x ``cols`` cells, numbered row by row from the chart's top-left corner. Where the file names its
patches as a grid does (a letter and a number: SG's ``A1`` .. ``N10``, IT8's ``A01`` .. ``L22``), each patch goes
to the cell its name gives: the letter counts along the axis with as many cells as the file has letters (SG:
14 columns A-N, 10 rows 1-10; a ColorChecker Classic file: rows A-D, columns 1-6), the rows when both fit. Any
other names fill the cells in file order. A cell no patch of the file names is left out of the calibration and
rendered a mid grey in the virtual lab. Patches left out (``leave_out``, e.g. an SG's repeated border greys)
stay on the chart (the virtual lab renders them) but are not used by the calibration.

Patches: every patch used must be a measurement a calibration can use, else the chart is refused in one line
before anything is lit: none 0 at every wavelength, at least three independent spectra (a chart of 24 identical
patches is refused), and no coloured spectrum found twice (charts repeat only neutral patches; a coloured repeat
is a row copied over another). The unit of a CGATS file's values is decided from the whole file (simulation.cgats).

Kind: a file that says it holds transmittances (a CSV's ``# units:`` line, a CGATS keyword value naming
transmission) is a film chart; one that says reflectance a reflective one; one that says neither is the
calibration's mode. A chart of the other kind is refused.
"""
from __future__ import annotations

import dataclasses
import hashlib
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dualrgb import resources
from dualrgb.simulation.choices import MODES
from dualrgb.simulation.datasets import TARGET_FILES, Target, load_target
from dualrgb.simulation.grid import SpectralGrid
from dualrgb.simulation.spectral_io import SpectralDataError, SpectralTable

log = logging.getLogger(__name__)

ROLES = ("train", "test")
ROLE_NAMES = {"train": "training", "test": "test"}
EMPTY_CELL_REFLECTANCE = 0.18          # a cell no patch of the file names (virtual lab: mid grey)
MAX_CELLS = 2000                       # the largest layout accepted (an IT8.7/4 has 1617 patches)
MIN_DISTINCT = 3                       # independent spectra a chart must hold (XYZ has three dimensions)
RANK_RTOL = 1e-2                       # below 1 % of the largest singular value a spectrum adds no dimension
NEUTRAL_SPREAD = 0.15                  # (max - min) / mean over 420-700 nm at most this: a neutral patch
#: What each packaged target stands for (docs/how-to/own-charts.md says the same).
PACKAGED_STANDS_FOR = {
    ("reflective", "train"): "no physical chart: 190 reflectances of the rawtoaces training set",
    ("reflective", "test"): "a ColorChecker Classic (BabelColor's average of 30 charts, 380-730 nm)",
    ("transmissive", "train"): "an IT8.7/1 transparency (synthetic: a three-dye film model, 288 patches)",
    ("transmissive", "test"): "a ColorChecker Classic reproduced on film (synthetic)",
}
_LAYOUT = re.compile(r"^\s*(\d+)\s*[x×X*]\s*(\d+)\s*$")
_GRID_NAME = re.compile(r"^([A-Za-z]{1,2})[-_ ]?0*(\d{1,3})$")


class ChartError(SpectralDataError):
    """A chart file, layout or patch list that cannot be used (one line)."""


def parse_layout(text: str) -> tuple[int, int]:
    """'10x14' (rows x columns; 'x', 'X', '×' or '*') -> (10, 14); one-line ChartError otherwise."""
    m = _LAYOUT.match(str(text))
    rows, cols = (int(m.group(1)), int(m.group(2))) if m else (0, 0)
    if not m or rows < 1 or cols < 1 or rows * cols > MAX_CELLS:
        raise ChartError(f"layout {text!r}: expected ROWSxCOLUMNS such as 10x14 (at most {MAX_CELLS} cells)")
    return rows, cols


def parse_names(text: str | None) -> tuple[str, ...]:
    """'A1, A2,N10' -> ('A1', 'A2', 'N10'): a comma-separated patch list (empty entries ignored)."""
    return tuple(n.strip() for n in (text or "").split(",") if n.strip())


def default_layout(n: int, layout: tuple[int, int] | None = None) -> tuple[int, int]:
    """``layout`` when it holds ``n`` patches, else a grid about 1.5 times as wide as high that does."""
    if layout and layout[0] * layout[1] >= n:
        return int(layout[0]), int(layout[1])
    cols = int(math.ceil(math.sqrt(n * 1.5)))
    return int(math.ceil(n / cols)), cols


def _letter_index(letters: str) -> int:
    value = 0
    for ch in letters.upper():
        value = value * 26 + (ord(ch) - ord("A") + 1)
    return value - 1


def grid_labels(names: list[str]) -> list[tuple[int, int]] | None:
    """(letter index, number - 1) of every name when all name grid cells ('A1', 'N10', 'A01'), else None."""
    out = []
    for name in names:
        m = _GRID_NAME.match(name.strip())
        if m is None or int(m.group(2)) < 1:
            return None
        out.append((_letter_index(m.group(1)), int(m.group(2)) - 1))
    return out if len(set(out)) == len(out) else None


def label_layout(labels: list[tuple[int, int]]) -> tuple[int, int]:
    """The layout grid names describe when no layout is given: letters are rows (the CGATS convention)."""
    return max(a for a, _ in labels) + 1, max(b for _, b in labels) + 1


def place_patches(names: list[str], layout: tuple[int, int], source: str = "") -> list[int]:
    """The cell (row-major index) of every patch: by its grid name where the names are grid cells and fit the
    layout (module docstring), else in file order; one-line ChartError when they cannot fit."""
    rows, cols = layout
    where = f"{source}: " if source else ""
    if len(names) > rows * cols:
        raise ChartError(f"{where}{len(names)} patches do not fit a {rows}x{cols} layout ({rows * cols} cells)")
    labels = grid_labels(names)
    if labels is None:
        return list(range(len(names)))
    n_letters, n_numbers = max(a for a, _ in labels) + 1, max(b for _, b in labels) + 1
    letter_rows = n_letters <= rows and n_numbers <= cols
    letter_cols = n_letters <= cols and n_numbers <= rows
    if letter_rows and (not letter_cols or n_letters == rows or n_letters != cols):
        return [a * cols + b for a, b in labels]
    if letter_cols:
        return [b * cols + a for a, b in labels]
    raise ChartError(f"{where}patch names run to {names[int(np.argmax([a for a, _ in labels]))]!r} "
                     f"({n_letters} letters, {n_numbers} numbers): they do not fit a {rows}x{cols} layout")


def _file_layout(layout: tuple[int, int] | None, n: int) -> tuple[int, int] | None:
    """A file's own layout line; when it does not hold every patch its columns stay and rows are added (the
    packaged IT8: '12x22 + 24 grey scale' is 14 rows of 22), as the virtual lab's scenes place them."""
    if layout is None:
        return None
    rows, cols = int(layout[0]), int(layout[1])
    return (max(rows, -(-n // cols)), cols) if cols > 0 else None


def _kind_of(table: SpectralTable) -> str:
    """'transmissive' / 'reflective' when the file says which it holds, '' when it does not."""
    said = " ".join(str(v) for v in table.meta.values()).lower()
    if "transmi" in said:
        return "transmissive"
    return "reflective" if "reflect" in said else ""


@dataclass(frozen=True)
class ChartFile:
    """What the calibration profile records of a chart's reference file."""

    name: str
    path: str
    sha256: str
    format: str                         # 'CGATS' or 'CSV'
    patches: int                        # in the file
    wavelength_range_nm: tuple[float, float]
    extended: str = ""                  # how the grid was reached beyond the measured range ('' = not)
    warnings: tuple[str, ...] = ()      # the reader's warning lines (e.g. NUMBER_OF_FIELDS)


@dataclass
class Chart:
    """A chart on the stand (module docstring): every patch of its file (file order, on the simulation grid),
    where each lies, which are used."""

    role: str                           # 'train' | 'test'
    target: Target
    layout: tuple[int, int]
    cells: list[int]                    # the cell of each patch (file order)
    kind: str                           # 'reflective' | 'transmissive'
    file: ChartFile
    leave_out: tuple[str, ...] = ()
    packaged: bool = False
    stands_for: str = ""                # what physical chart a packaged target stands for
    notes: list[str] = field(default_factory=list)

    @property
    def used(self) -> list[int]:
        """Indices (file order) of the patches the calibration uses."""
        out = set(self.leave_out)
        return [i for i, n in enumerate(self.target.patch_names) if n not in out]

    @property
    def used_cells(self) -> list[int]:
        return [self.cells[i] for i in self.used]

    def reference(self) -> Target:
        """The used patches as a Target (file order; the spectra as measured kept for ASTM E308)."""
        t, used = self.target, self.used
        measured = None
        if t.measured is not None:
            m = t.measured
            measured = SpectralTable(m.wavelengths, m.values[:, used], [m.columns[i] for i in used], m.meta, m.source)
        return dataclasses.replace(t, spectra=np.asarray(t.spectra)[used], patch_names=[t.patch_names[i] for i in used],
                                   layout=self.layout, measured=measured)

    def render_target(self) -> Target:
        """Every cell of the layout in row-major order, as the virtual lab puts it on the stand: each patch of the
        file in its cell (left-out ones too: they are on the chart), cells no patch names a flat mid grey."""
        rows, cols = self.layout
        if self.cells == list(range(len(self.cells))):          # file order: the scene fills the cells row by row
            return dataclasses.replace(self.target, layout=(rows, cols), measured=None)
        spectra = np.full((rows * cols, np.asarray(self.target.spectra).shape[1]), EMPTY_CELL_REFLECTANCE)
        names = [f"(empty {c})" for c in range(rows * cols)]
        for i, cell in enumerate(self.cells):
            spectra[cell] = self.target.spectra[i]
            names[cell] = self.target.patch_names[i]
        return dataclasses.replace(self.target, spectra=spectra, patch_names=names, layout=(rows, cols),
                                   measured=None)

    def label(self) -> str:
        used = len(self.used)
        left = f", {len(self.target) - used} left out" if used < len(self.target) else ""
        return f"{self.file.name} ({used} patches{left}, {self.layout[0]}x{self.layout[1]})"

    def record(self) -> dict:
        """The calibration profile's record of this chart (file name, sha256, patch counts, wavelength range,
        layout, what was left out, how it was extended)."""
        f = self.file
        out = {"file": f.name, "path": f.path, "sha256": f.sha256, "format": f.format, "patches": f.patches,
               "used": len(self.used), "left_out": list(self.leave_out), "layout": list(self.layout),
               "wavelength_range_nm": list(f.wavelength_range_nm), "extended": f.extended, "kind": self.kind,
               "name": self.target.name, "packaged": self.packaged}
        if self.stands_for:
            out["stands_for"] = self.stands_for
        if f.warnings:
            out["warnings"] = list(f.warnings)
        return out


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _check_leave_out(names: list[str], leave_out: tuple[str, ...], source: str) -> None:
    unknown = [n for n in leave_out if n not in names]
    if unknown:
        raise ChartError(f"{source}: cannot leave out {', '.join(map(repr, unknown[:5]))}: no such patch "
                         f"(the file names {', '.join(names[:4])} ... {names[-1]})")
    if len(names) - len(set(leave_out)) < 3:
        raise ChartError(f"{source}: {len(names) - len(set(leave_out))} patches left to use; a chart needs at least 3")


def _check_patches(table: SpectralTable, leave_out: tuple[str, ...], source: str) -> None:
    """The used patches (every patch not left out) must be measurements a calibration can use: none 0 at every
    wavelength, at least :data:`MIN_DISTINCT` different spectra spanning as many independent ones, and no coloured
    patch repeated (charts repeat only their neutral patches, e.g. an SG's border of white, grey and black: a
    coloured spectrum found twice is a row copied over another)."""
    skip = set(leave_out)
    used = [i for i, name in enumerate(table.columns) if name not in skip]
    spectra = np.asarray(table.values, dtype=float)[:, used].T            # (patches, wavelengths) as measured
    names = [table.columns[i] for i in used]
    for name, spectrum in zip(names, spectra, strict=True):
        if not spectrum.any():
            raise ChartError(f"{source}: patch {name!r} is 0 at every wavelength, which no real surface is (a "
                             "missing measurement?); measure it again, or leave it out")
    distinct, count = np.unique(spectra, axis=0, return_counts=True)
    rank = int(np.linalg.matrix_rank(spectra, tol=RANK_RTOL * float(np.linalg.norm(spectra, 2))))
    if len(distinct) < MIN_DISTINCT or rank < MIN_DISTINCT:
        what = (f"{len(distinct)} different spectr{'um' if len(distinct) == 1 else 'a'}" if len(distinct) <
                MIN_DISTINCT else f"spectra spanning only {rank} independent ones")
        raise ChartError(f"{source}: its {len(names)} patches used hold {what}; a calibration needs at least "
                         f"{MIN_DISTINCT} independent colours (is this the right file?)")
    band = (table.wavelengths >= 420) & (table.wavelengths <= 700)
    for k in np.flatnonzero(count > 1):
        twice = [names[i] for i in np.flatnonzero((spectra == distinct[k]).all(axis=1))]
        s = distinct[k][band] if band.any() else distinct[k]
        if (s.max() - s.min()) > NEUTRAL_SPREAD * max(float(s.mean()), 1e-12):
            raise ChartError(f"{source}: patches {', '.join(map(repr, twice[:4]))} hold the same coloured spectrum; "
                             "a chart repeats only its neutral patches: a row copied over another? fix the file, or "
                             f"leave the copies out ({','.join(twice[1:4])})")
        log.debug("%s: neutral patch repeated %d times (%s)", source, count[k], ", ".join(twice[:4]))


def _check_kind(kind: str, mode: str, source: str, role: str) -> str:
    if mode not in MODES:
        raise ValueError(f"mode {mode!r}: expected one of {', '.join(MODES)}")
    if kind and kind != mode:
        said = "transmittances (film)" if kind == "transmissive" else "reflectances"
        raise ChartError(f"{source}: the file holds {said}, but this is a {mode} calibration; give a {mode} "
                         f"{ROLE_NAMES[role]} chart, or calibrate with --mode {kind}")
    return kind or mode


def read_chart(path: str | Path, grid: SpectralGrid, *, role: str, mode: str,
               layout: tuple[int, int] | str | None = None, leave_out: tuple[str, ...] | str = ()) -> Chart:
    """A chart from its reference file (module docstring). ``layout`` None: the file's (a CSV's ``# layout:``
    line, else what its grid names span, else about 1.5:1); ``leave_out``: patch names the calibration skips."""
    if role not in ROLES:
        raise ValueError(f"chart role {role!r}: expected one of {', '.join(ROLES)}")
    path = Path(path)
    target = load_target(path, grid)
    table = target.measured
    assert table is not None
    names = list(target.patch_names)
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise ChartError(f"{path}: patch {dup!r} is named twice; every patch needs its own name")
    if isinstance(layout, str):
        layout = parse_layout(layout)
    labels = grid_labels(names)
    shape = layout or _file_layout(target.layout, len(names)) or (label_layout(labels) if labels
                                                                  else default_layout(len(names)))
    cells = place_patches(names, shape, str(path))
    leave = parse_names(leave_out) if isinstance(leave_out, str) else tuple(leave_out)
    _check_leave_out(names, leave, str(path))
    packaged = path.resolve().is_relative_to(resources.path().resolve())
    from dualrgb.simulation.cgats import is_cgats

    info = ChartFile(path.name, str(path), _sha256(path), "CGATS" if is_cgats(path) else "CSV", len(names),
                     (float(table.wavelengths[0]), float(table.wavelengths[-1])), target.extended,
                     tuple(table.warnings))
    kind = _check_kind(_kind_of(table), mode, str(path), role)
    _check_patches(table, leave, str(path))
    return Chart(role, target, shape, cells, kind, info, leave, packaged,
                 PACKAGED_STANDS_FOR.get((mode, role), "") if packaged else "")


def packaged_chart(mode: str, role: str, grid: SpectralGrid) -> Chart:
    """The packaged training or test target of ``mode`` as a chart (simulation.datasets.TARGET_FILES)."""
    if mode not in TARGET_FILES:
        raise ValueError(f"mode {mode!r}: expected one of {', '.join(MODES)}")
    return read_chart(resources.path("targets", TARGET_FILES[mode][ROLES.index(role)]), grid, role=role, mode=mode)
