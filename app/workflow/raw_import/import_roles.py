"""The roles file of an import (``dualrgb import FOLDER --roles ROLES.csv``, the window's *Import raw files...*):
one row per raw file saying why it was shot.

Format
    A CSV as a queue CSV is read (UTF-8 with or without a byte-order mark, comma, semicolon or tab, quoted fields;
    row 1 the header, rows numbered as a spreadsheet shows them). Columns, matched ignoring case:

    ``file``        the file's name in the folder (required);
    ``role``        ``dark``, ``flat``, ``target`` or ``original`` (required);
    ``light``       the light's number in the preset (1, 2, ...); empty for darks, required for every other role;
    ``identifier``  the original's identifier (accession number); ``train`` or ``test`` for a target; empty for
                    darks and flats;
    ``exposure_s``, ``captured_at``, ``camera``, ``guess``: what ``--roles-template`` writes for the technician to
                    check against; read from the files again on import, so ignored here.

    Every other column (``title``, ``operator``, ``notes``, ``mode``, and any other: extra metadata) describes the
    original of its row exactly as in a queue CSV: the first row of each original is read by
    app.workflow.day.queue_csv.read_queue_csv, the one reader of that mapping (its checks, its column notes, its
    deliverables-folder check); the original's other rows (its other lights and exposures) must leave those
    columns empty or say the same.

Each problem is one line naming the row (``ROLES.csv row 5: role 'drak': expected dark, flat, target or original``).
"""
from __future__ import annotations

import csv
import io
import logging
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from dualrgb.app.workflow.day.queue_csv import DELIMITERS, MAX_QUEUE_BYTES, read_queue_csv
from dualrgb.core.metadata import MetadataError, Original, normalise_identifier
from dualrgb.core.vocabulary import TARGET_NAMES, Role

log = logging.getLogger(__name__)

ROLES = (Role.DARK, Role.FLAT, Role.TARGET, Role.ORIGINAL)
COLUMNS = ("file", "role", "light", "identifier")
INFORMATION = ("exposure_s", "captured_at", "camera", "guess")    # written by the template, ignored on import
MAX_LIGHTS = 8                                                    # a calibration profile holds at most 8 lights


@dataclass(frozen=True)
class RoleRow:
    """One raw file and why it was shot (``light`` None for a dark; ``identifier`` '' for darks and flats)."""

    row: int
    file: str
    role: Role
    light: int | None = None
    identifier: str = ""


@dataclass
class RolesTable:
    """The rows of a roles file, the originals they name (by identifier) and the problems of its bad rows."""

    source: str                                              # how lines name it: the file's name
    rows: list[RoleRow] = field(default_factory=list)
    originals: dict[str, Original] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)           # unmapped columns not kept whole (queue_csv)

    def where(self, row: int) -> str:
        return f"{self.source} row {row}"


def read_records(path: Path) -> list[list[str]]:
    """The CSV's records (header first), as a queue CSV is read; ValueError (one line) for a file that is not one."""
    try:
        size = path.stat().st_size
        if size > MAX_QUEUE_BYTES:
            raise ValueError(f"{path}: {size / 2 ** 20:.1f} MiB is not a roles file (at most "
                             f"{MAX_QUEUE_BYTES // 2 ** 20} MiB)")
        text = path.read_bytes().decode("utf-8-sig")
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the roles file ({exc.strerror or exc})") from exc
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not UTF-8 text (at byte {exc.start}); save the roles file as UTF-8") from None
    delimiter = max(DELIMITERS, key=text.split("\n", 1)[0].count)
    try:
        rows = list(csv.reader(io.StringIO(text, newline=""), delimiter=delimiter, strict=True))
    except csv.Error as exc:
        raise ValueError(f"{path}: not CSV ({exc})") from None
    if not rows or not any(c.strip() for c in rows[0]):
        raise ValueError(f"{path}: no header row (row 1 names the columns: {', '.join(COLUMNS)})")
    return rows


def _columns(source: str, header: list[str]) -> dict[str, int]:
    names = [c.strip().casefold() for c in header]
    out = {}
    for name in COLUMNS:
        hits = [i for i, n in enumerate(names) if n == name]
        if len(hits) > 1:
            raise ValueError(f"{source}: row 1: column {name!r} appears twice")
        if hits:
            out[name] = hits[0]
        elif name in ("file", "role"):
            raise ValueError(f"{source}: row 1: no {name!r} column (the roles file's columns: "
                             f"{', '.join(COLUMNS)}, then the originals' title, operator, ...)")
    return out


def _light(cell: str, role: Role) -> int | None:
    text = cell.strip()
    if role is Role.DARK:
        if text:
            raise ValueError(f"light {text!r}: a dark frame is shot with the light off (leave it empty)")
        return None
    if not text:
        raise ValueError(f"{'an' if role is Role.ORIGINAL else 'a'} {role.value} frame needs its light's number in "
                         "the preset (1, 2, ...)")
    if not text.isdigit() or not 1 <= int(text) <= MAX_LIGHTS:
        raise ValueError(f"light {text!r}: expected the light's number in the preset, 1 to {MAX_LIGHTS}")
    return int(text)


def _identifier(cell: str, role: Role) -> str:
    text = cell.strip()
    if role in (Role.DARK, Role.FLAT):
        if text:
            raise ValueError(f"identifier {text!r}: a {role.value} frame names no original (leave it empty)")
        return ""
    if role is Role.TARGET:
        if text.lower() not in TARGET_NAMES:
            raise ValueError(f"identifier {text!r}: a target is {' or '.join(TARGET_NAMES)}")
        return text.lower()
    try:
        return normalise_identifier(text, "identifier")
    except MetadataError as exc:
        raise ValueError(str(exc)) from None


def _row(number: int, cells: list[str], index: dict[str, int]) -> RoleRow:
    def cell(name: str) -> str:
        i = index.get(name)
        return cells[i] if i is not None and i < len(cells) else ""

    file = cell("file").strip()
    if not file or file in (".", "..") or "/" in file or "\\" in file:
        raise ValueError(f"file {file!r}: expected the name of a raw file in the folder (no folder part)")
    text = cell("role").strip().lower()
    try:
        role = Role(text)
    except ValueError:
        role = None
    if role not in ROLES:
        raise ValueError(f"role {text!r}: expected {', '.join(r.value for r in ROLES[:-1])} or {ROLES[-1].value}")
    assert role is not None
    return RoleRow(number, file, role, _light(cell("light"), role), _identifier(cell("identifier"), role))


def read_roles(path: Path, *, default_mode: str = "reflective", out_dir: Path | None = None) -> RolesTable:
    """Read and check a roles file (module docstring): every row's file, role, light and identifier, and the
    originals' metadata (queue CSV rules; ``default_mode`` for an empty mode, ``out_dir``: a row whose
    deliverables folder holds another original's files is refused). ValueError (one line) for a file that is not
    a roles file at all."""
    path = Path(path)
    records = read_records(path)
    table = RolesTable(path.name)
    index = _columns(path.name, records[0])
    first: dict[str, tuple[int, list[str]]] = {}
    for number, cells in enumerate(records[1:], start=2):
        if not any(c.strip() for c in cells):
            continue
        try:
            row = _row(number, cells, index)
        except ValueError as exc:
            table.problems.append(f"{table.where(number)}: {exc}")
            continue
        table.rows.append(row)
        if row.role is Role.ORIGINAL:
            first.setdefault(row.identifier, (number, cells))
    _check_repeats(table, records, first)
    _read_originals(table, records[0], first, default_mode, out_dir)
    return table


def _metadata_columns(header: list[str]) -> list[int]:
    """The columns that describe an original (everything but the roles' own and the template's information)."""
    own = {*COLUMNS, *INFORMATION} - {"identifier"}
    return [i for i, c in enumerate(header) if c.strip().casefold() not in own]


def _check_repeats(table: RolesTable, records: list[list[str]], first: dict[str, tuple[int, list[str]]]) -> None:
    """An original's later rows leave its metadata empty or say what its first row says."""
    cols = [i for i in _metadata_columns(records[0]) if records[0][i].strip().casefold() != "identifier"]
    for row in table.rows:
        if row.role is not Role.ORIGINAL or first[row.identifier][0] == row.row:
            continue
        number0, cells0 = first[row.identifier]
        cells = records[row.row - 1]
        for i in cols:
            mine = cells[i].strip() if i < len(cells) else ""
            theirs = cells0[i].strip() if i < len(cells0) else ""
            if mine and mine != theirs:
                table.problems.append(f"{table.where(row.row)}: column {records[0][i].strip()!r}: {mine!r} differs "
                                      f"from row {number0} of the same original ({theirs!r}); say it once")


def _read_originals(table: RolesTable, header: list[str], first: dict[str, tuple[int, list[str]]],
                    default_mode: str, out_dir: Path | None) -> None:
    """Each original's first row through the queue CSV reader (the one mapping of columns to an original)."""
    if not first:
        return
    cols = _metadata_columns(header)
    numbers = [number for number, _cells in first.values()]
    with tempfile.TemporaryDirectory(prefix="dualrgb-roles-") as tmp:
        queue = Path(tmp) / "originals.csv"
        with open(queue, "w", encoding="utf-8", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow([header[i] for i in cols])
            for _number, cells in first.values():
                writer.writerow([cells[i] if i < len(cells) else "" for i in cols])
        read = read_queue_csv(queue, default_mode=default_mode, out_dir=out_dir)
    for entry in read.entries:
        table.originals[entry.original.identifier] = entry.original
    for line_row, text in zip(read.bad_rows, read.bad_lines(), strict=True):
        number = numbers[line_row - 2]
        table.problems.append(f"{table.where(number)}: {text.partition(', ')[2]}")
    table.notes += [f"{table.source}: {line}" for line in read.column_lines()]
    for row in table.rows:
        if row.role is Role.ORIGINAL and row.identifier not in table.originals:
            table.rows = [r for r in table.rows if not (r.role is Role.ORIGINAL and r.identifier == row.identifier)]


def roles_from_table(header: Sequence[str], rows: Sequence[Sequence[str]], *, default_mode: str = "reflective",
                     out_dir: Path | None = None, source: str = "the table") -> RolesTable:
    """:func:`read_roles` of a table as the window holds it (``header`` and ``rows`` of cells): the same rules and
    lines, the rows named ``<source> row N``."""
    with tempfile.TemporaryDirectory(prefix="dualrgb-roles-") as tmp:
        table = read_roles(write_roles(Path(tmp) / "roles.csv", header, rows), default_mode=default_mode,
                           out_dir=out_dir)
    named = source
    table.problems = [p.replace(f"{table.source} row", f"{named} row", 1).replace(f"{table.source}:", f"{named}:", 1)
                      for p in table.problems]
    table.notes = [n.replace(table.source, named, 1) for n in table.notes]
    table.source = named
    return table


def write_roles(path: Path, header: Sequence[str], rows: Sequence[Sequence[str]]) -> Path:
    """A roles file with ``header`` and ``rows`` (UTF-8, comma-separated): the template, the window's table."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(list(header))
    writer.writerows([list(r) for r in rows])
    Path(path).write_text(out.getvalue(), encoding="utf-8")
    return Path(path)


__all__ = ["COLUMNS", "INFORMATION", "ROLES", "RoleRow", "RolesTable", "read_records", "read_roles",
           "roles_from_table", "write_roles"]
