"""A day's queue from the collection database: a CSV exported from a collection-management system, read and every
row validated before anything is shot (``dualrgb capture --queue``, the GUI's *Import CSV...*; both call
:func:`read_queue_csv`). An example: ``docs/queue-example.csv``.

Format
    UTF-8, with or without a byte-order mark; CRLF or LF; comma-separated (semicolon or tab when the header line
    has more of those: spreadsheets in some locales); quoted fields may hold the separator, quotes (doubled) and
    line breaks. Row 1 is the header naming the columns: ``identifier`` (required), ``title``, ``operator``,
    ``notes``, ``mode`` (matched ignoring case; another name with ``columns={"identifier": "Accession No."}``,
    ``--column identifier="Accession No."``). Every other column is an extra field of the original, kept with its
    exact name (sidecar ``original.extra``; XMP ``dualrgb:Extra_<name>``: core.metadata.xmp_property).

Unmapped columns never refuse a row (collection exports carry dozens nobody maps, and free text of thousands of
characters): any number of them is read; a value up to :data:`EXTRA_RULE`'s 1000 characters is kept as it is, a
longer one truncated with a marker (``[… 3565 characters, truncated]``), one holding a character no field may hold
(a control character ...) dropped; a column whose header cannot name a field (no name, a control character, over
100 characters) or a value beyond the header's last column is left out. Each such column gets one summary line
(:meth:`QueueImport.column_lines`). The mapped fields keep their strict checks (a bad value refuses its row).

Collections
    A row's ``collection`` column (matched ignoring case; else ``collection=``, ``--collection``) names the
    collection whose metadata preset is applied to it (app.workflow.day.collection_presets.with_collection, as the
    window's Originals form: the preset's extra fields with the row's own values winning, its creator and rights in
    the XMP); a collection without a preset file adds nothing; a bad preset file refuses the queue in one line.

Rows
    Numbered as a spreadsheet shows them: the header is row 1, a quoted field's line breaks stay within its row.
    Empty rows are skipped. Each field is normalised by core.metadata (the GUI's and the CLI's rules); an
    empty mode is the calibration's. A bad row is one line naming the row, the column and the problem
    (``row 5, column 'Title': control character U+0001 at character 4 is not allowed``); a repeated identifier is
    a bad row (the later one), as is a row whose deliverables folder holds another original's files.

Bounds
    The file is at most :data:`MAX_QUEUE_BYTES` (checked before it is read) and holds at most
    :data:`MAX_QUEUE_ROWS` originals: its records are read as a stream and counted first, a longer queue refused in
    one line before any row is checked (a 1e6-row export answers at once, holding a few rows in memory).
"""
from __future__ import annotations

import csv
import dataclasses
import logging
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dualrgb.app.workflow.delivery.delivery_folder import DeliveryFolderError, check_folder
from dualrgb.common.formatting import counted
from dualrgb.core.metadata import (
    COLUMN_RULE,
    EXTRA_RULE,
    FIELD_RULES,
    MetadataError,
    Original,
    normalise,
    normalise_identifier,
    normalise_mode,
)

log = logging.getLogger(__name__)
MAX_QUEUE_BYTES = 16 * 2 ** 20     # checked before reading: 10 000 originals with long titles are ~2 MB
#: The most originals a queue may hold (a copy stand shoots a few hundred a day): a longer file is refused in one
#: line before any row is checked, so memory and time stay bounded whatever the file holds.
MAX_QUEUE_ROWS = 10_000

FIELDS = ("identifier", "title", "operator", "notes", "mode")
DELIMITERS = (",", ";", "\t")
_UNBOUNDED_EXTRA = dataclasses.replace(EXTRA_RULE, max_chars=2**62)     # normalised first, then truncated


@dataclass
class ColumnNote:
    """What became of an unmapped column's values: one summary line (:meth:`line`)."""

    column: str                      # its header name, or its letter when it has none
    truncated: int = 0               # values over EXTRA_RULE.max_chars, kept truncated with a marker
    longest: int = 0
    dropped: int = 0                 # values holding a character no field may hold
    why: str = ""                    # the first dropped value's problem
    whole: str = ""                  # the column left out whole: why
    renamed: str = ""                # a repeated header name, kept under this column's name: what it said

    def line(self) -> str:
        if self.whole:
            return f"column {self.column}: {self.whole}; its values are not kept"
        parts = [f"the header repeats {self.renamed}: kept under this name"] if self.renamed else []
        if self.truncated:
            parts.append(f"{self.truncated} value{'s' if self.truncated > 1 else ''} over {EXTRA_RULE.max_chars} "
                         f"characters (longest {self.longest}) kept truncated, marked '[… N characters, truncated]'")
        if self.dropped:
            parts.append(f"{self.dropped} value{'s' if self.dropped > 1 else ''} dropped ({self.why})")
        return f"column {self.column!r} (extra metadata): " + "; ".join(parts)


def extra_value(cell: str, column: str, note: ColumnNote) -> str | None:
    """An unmapped column's value as kept (module docstring; None: dropped), counted in ``note``."""
    try:
        text = normalise(_UNBOUNDED_EXTRA, cell, column)
    except MetadataError as exc:
        note.dropped += 1
        note.why = note.why or exc.problem
        return None
    limit = EXTRA_RULE.max_chars
    if len(text) > limit:
        note.truncated += 1
        note.longest = max(note.longest, len(text))
        marker = f" [… {len(text)} characters, truncated]"
        text = text[:limit - len(marker)].rstrip() + marker
    return text


@dataclass(frozen=True)
class RowProblem:
    row: int             # as a spreadsheet numbers it (the header is row 1)
    column: str          # the column's name in the header
    problem: str


@dataclass(frozen=True)
class QueueEntry:
    row: int
    original: Original


@dataclass
class QueueImport:
    """What a queue CSV holds: the originals of its good rows, in order, and the problems of its bad rows."""

    path: Path
    entries: list[QueueEntry] = field(default_factory=list)
    problems: list[RowProblem] = field(default_factory=list)
    columns: dict[str, str] = field(default_factory=dict)      # field -> the column it was read from
    extra_columns: list[str] = field(default_factory=list)
    notes: dict[str, ColumnNote] = field(default_factory=dict)  # unmapped columns whose values were not all kept
    bad_identifiers: dict[int, str] = field(default_factory=dict)  # a bad row's identifier cell as it is

    def column_lines(self) -> list[str]:
        """One line per unmapped column whose values were not all kept as they are (truncated, dropped, the
        column left out or renamed)."""
        return [n.line() for n in self.notes.values() if n.whole or n.truncated or n.dropped or n.renamed]

    @property
    def originals(self) -> list[Original]:
        return [e.original for e in self.entries]

    @property
    def bad_rows(self) -> list[int]:
        return sorted({p.row for p in self.problems})

    def bad_lines(self) -> list[str]:
        """One line per bad row: ``row 5, column 'Title': ...; column 'mode': ...``."""
        out = []
        for row in self.bad_rows:
            parts = [f"column {p.column!r}: {p.problem}" for p in self.problems if p.row == row]
            out.append(f"row {row}, " + "; ".join(parts))
        return out

    def summary(self) -> str:
        """``q.csv: 20 rows, 17 valid, 3 bad (rows 6, 11, 17)``: the file's own count. What is shot is the queue
        plan's (app.workflow.day.queue_plan: to shoot, kept, refused under a calibration and a session)."""
        bad = self.bad_rows
        return (f"{self.path.name}: {counted(len(self.entries) + len(bad), 'row')}, {len(self.entries)} valid"
                + (f", {len(bad)} bad (rows {', '.join(map(str, bad))})" if bad else ""))


def column_option(text: str) -> tuple[str, str]:
    """``FIELD=COLUMN NAME`` (``--column identifier="Accession No."``) -> (field, column name)."""
    name, sep, column = text.partition("=")
    name = name.strip().lower()
    if not sep or name not in FIELDS or not column.strip():
        raise ValueError(f"{text!r}: expected FIELD=COLUMN NAME with FIELD one of {', '.join(FIELDS)}")
    return name, column.strip()


def column_options(text: str) -> dict[str, str]:
    """``identifier=Inv. Nr.; title=Titel`` (the GUI's column names) -> {field: column name}; empty: {}."""
    return dict(column_option(part) for part in text.split(";") if part.strip())


def _letter(index: int) -> str:
    """A spreadsheet's column letter: 0 -> A, 25 -> Z, 26 -> AA."""
    out = ""
    index += 1
    while index:
        index, r = divmod(index - 1, 26)
        out = chr(65 + r) + out
    return out


def _check_size(path: Path) -> None:
    """The queue's size, checked before it is read (:data:`MAX_QUEUE_BYTES`)."""
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the queue CSV ({exc.strerror or exc})") from exc
    if size > MAX_QUEUE_BYTES:
        raise ValueError(f"{path}: {size / 2 ** 20:.1f} MiB is not a day's queue (at most "
                         f"{MAX_QUEUE_BYTES // 2 ** 20} MiB); split it")


def _records(path: Path) -> Iterator[list[str]]:
    """The CSV's records one at a time, read from the file as a stream (nothing kept here); one line for a file
    that is not UTF-8 or a record that is not CSV."""
    read = 0
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            first = fh.readline()
            delimiter = max(DELIMITERS, key=first.count)
            fh.seek(0)
            for record in csv.reader(fh, delimiter=delimiter, strict=True):
                read += 1
                yield record
    except csv.Error as exc:
        raise ValueError(f"{path}: row {read + 1}: not CSV ({exc})") from None
    except UnicodeDecodeError:
        raise _not_utf8(path) from None
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the queue CSV ({exc.strerror or exc})") from exc


def _not_utf8(path: Path) -> ValueError:
    """Where the file stops being UTF-8 (its size was checked: reading it whole is bounded)."""
    raw = path.read_bytes()
    try:
        raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        return ValueError(f"{path}: not UTF-8 text (byte 0x{raw[exc.start]:02X} at offset {exc.start}); export the "
                          "CSV as UTF-8")
    return ValueError(f"{path}: not UTF-8 text; export the CSV as UTF-8")       # changed while read


def _opened(path: Path) -> tuple[list[str], Iterator[list[str]]]:
    """The queue's header and its other records as a stream, once its size and its number of originals are
    checked (:data:`MAX_QUEUE_BYTES`, :data:`MAX_QUEUE_ROWS`)."""
    _check_size(path)
    _check_row_count(path)
    records = _records(path)
    header = next(records, None)
    if header is None or not any(c.strip() for c in header):
        raise ValueError(f"{path}: no header row (row 1 names the columns: identifier, title, ...)")
    return header, records


def _check_row_count(path: Path) -> None:
    """Refuse a queue of more than :data:`MAX_QUEUE_ROWS` originals before any row is checked: the records are
    counted as a stream, and the count stops at the first one over the maximum."""
    rows = 0
    for number, cells in enumerate(_records(path), start=1):
        if number > 1 and any(c.strip() for c in cells):
            rows += 1
            if rows > MAX_QUEUE_ROWS:
                raise ValueError(f"{path}: more than {MAX_QUEUE_ROWS} originals (row {number} is the "
                                 f"{MAX_QUEUE_ROWS + 1}th): a day's queue holds at most {MAX_QUEUE_ROWS}; split it")


def _header(path: Path, cells: list[str], columns: Mapping[str, str], notes: dict[str, ColumnNote]
            ) -> list[str | None]:
    """The columns' names (None: a column left out, its reason in ``notes``); a name a field is read from must be
    unique (one line otherwise), another repeated one is kept as ``name (letter)``."""
    wanted = {str(v).casefold() for v in columns.values()} | set(FIELDS)
    names: list[str | None] = []
    for i, cell in enumerate(cells):
        try:
            names.append(normalise(COLUMN_RULE, cell, f"row 1, column {_letter(i)}") or None)
        except MetadataError as exc:
            names.append(None)
            notes[_letter(i)] = ColumnNote(_letter(i), whole=f"header: {exc.problem}")
    while names and names[-1] is None and _letter(len(names) - 1) not in notes:
        names.pop()
    for i, name in enumerate(names):
        if name is None or name not in names[:i]:
            continue
        first = _letter(names.index(name))
        if name.casefold() in wanted:
            raise ValueError(f"{path}: row 1: column {name!r} appears twice ({first} and {_letter(i)})")
        names[i] = f"{name} ({_letter(i)})"
        notes[str(names[i])] = ColumnNote(str(names[i]), renamed=f"{name!r} (also column {first})")
    if not any(names):
        raise ValueError(f"{path}: no header row (row 1 names the columns: identifier, title, ...)")
    return names


def _field_columns(path: Path, names: list[str | None], columns: Mapping[str, str]) -> dict[str, int]:
    """Field -> index of its column in the header."""
    out: dict[str, int] = {}
    for name in FIELDS:
        wanted = normalise(COLUMN_RULE, columns.get(name, name), "--column").casefold()
        hits = [i for i, n in enumerate(names) if n is not None and n.casefold() == wanted]
        if len(hits) > 1:
            raise ValueError(f"{path}: columns {', '.join(repr(names[i]) for i in hits)} all read as {name!r}; "
                             f"rename one, or choose with --column {name}=NAME")
        if hits and hits[0] in out.values():
            raise ValueError(f"{path}: column {names[hits[0]]!r} is read as two fields; check --column")
        if hits:
            out[name] = hits[0]
        elif name in columns or name == "identifier":
            raise ValueError(f"{path}: no column {columns.get(name, name)!r} for the {name} (the header has "
                             f"{', '.join(repr(n) for n in names if n)}); name it with --column {name}=NAME")
    return out


def _value(name: str, cell: str, column: str, default_mode: str) -> str:
    if name == "identifier":
        return normalise_identifier(cell, column)
    if name == "mode":
        return normalise_mode(cell, column) if cell.strip() else default_mode
    return normalise(FIELD_RULES[name], cell, column)


def _row(number: int, cells: list[str], names: list[str | None], index: dict[str, int], default_mode: str,
         notes: dict[str, ColumnNote]) -> tuple[Original | None, list[RowProblem]]:
    """A row's original, or its problems (mapped fields only: an unmapped column never refuses a row)."""
    for i in range(len(names), len(cells)):                      # values beyond the header's last column
        if cells[i].strip() and _letter(i) not in notes:
            notes[_letter(i)] = ColumnNote(_letter(i), whole="beyond the header's last named column")
    cells = cells + [""] * (len(names) - len(cells))
    fields = {j: k for k, j in index.items()}
    problems, extra, values = [], {}, dict[str, Any]()
    for i, column in enumerate(names):
        if column is None:
            if cells[i].strip() and _letter(i) not in notes:
                notes[_letter(i)] = ColumnNote(_letter(i), whole="no name in the header")
            continue
        try:
            if i in fields:
                values[fields[i]] = _value(fields[i], cells[i], column, default_mode)
            elif cells[i].strip():
                kept = extra_value(cells[i], column, notes.setdefault(column, ColumnNote(column)))
                if kept:
                    extra[column] = kept
        except MetadataError as exc:
            problems.append(RowProblem(number, column, exc.problem))
    if problems:
        return None, problems
    try:
        return Original(**values, extra=extra), []
    except MetadataError as exc:            # (every value is normalised already: a guard)
        return None, [RowProblem(number, exc.field, exc.problem)]


def read_queue_csv(path: Path, *, columns: Mapping[str, str] | None = None, default_mode: str = "reflective",
                   out_dir: Path | None = None, collection: str = "", presets: Path | None = None) -> QueueImport:
    """Read and validate a queue CSV (the module docstring says the format).

    Parameters
    ----------
    path
        The CSV file.
    columns
        Field -> column name where the header does not use the field's own name (``{"identifier": "Inv. Nr."}``).
    default_mode
        The mode of rows whose mode is empty (or of a CSV without a mode column): the calibration's.
    out_dir
        The deliverables folder: a row whose folder there holds another original's files is a bad row.
    collection, presets
        The collection of rows whose ``collection`` column is empty or missing, and the presets' folder (None: the
        default, app.workflow.day.collection_presets).

    Returns
    -------
    QueueImport
        The good rows' originals in order, and one problem per bad cell (``bad_lines``: one line per bad row); a
        file that is not a readable queue (not UTF-8, not CSV, no identifier column): ValueError, one line.
    """
    path = Path(path)
    (header, records), notes = _opened(path), dict[str, ColumnNote]()
    names = _header(path, header, dict(columns or {}), notes)
    index = _field_columns(path, names, dict(columns or {}))
    default_mode = normalise_mode(default_mode)
    out = QueueImport(path, columns={k: str(names[i]) for k, i in index.items()}, notes=notes,
                      extra_columns=[n for i, n in enumerate(names) if n is not None and i not in index.values()])
    seen: dict[str, int] = {}                   # identifier -> row
    stems: dict[str, int] = {}                  # file stem -> row
    read: dict[str, Any] = {}                   # collection -> its preset (None: none)
    id_column = str(names[index["identifier"]])
    for number, cells in enumerate(records, start=2):
        if not any(c.strip() for c in cells):
            continue
        original, problems = _row(number, cells, names, index, default_mode, notes)
        if original is not None:
            original = _in_collection(path, original, collection, presets, read)
            problems = _duplicate(number, original, seen, stems, id_column, out_dir)
        if original is None or problems:
            out.problems += problems
            cell = cells[index["identifier"]] if index["identifier"] < len(cells) else ""
            out.bad_identifiers[number] = " ".join(cell.split())[:100]
            continue
        seen[original.identifier] = stems[original.file_stem.casefold()] = number
        out.entries.append(QueueEntry(number, original))
    return _logged(out)


def _logged(out: QueueImport) -> QueueImport:
    log.info("%s", out.summary())
    for line in out.column_lines():
        log.info("%s: %s", out.path.name, line)
    return out


def _in_collection(path: Path, original: Original, default: str, presets: Path | None, read: dict[str, Any]
                   ) -> Original:
    """``original`` under its row's collection's preset (the ``collection`` column, else ``default``; each preset
    read once per queue, in ``read``)."""
    from dualrgb.app.workflow.day.collection_presets import apply_preset, find_preset

    name = next((v for k, v in original.extra.items() if k.casefold() == "collection"), "") or default
    if name.casefold() not in read:
        try:
            read[name.casefold()] = find_preset(name, presets)
        except ValueError as exc:               # a bad preset file: the queue is refused, naming the file
            raise ValueError(f"{path}: collection {name!r}: {exc}") from None
    return apply_preset(original, read[name.casefold()])


def _duplicate(number: int, original: Original, seen: dict[str, int], stems: dict[str, int], column: str,
               out_dir: Path | None) -> list[RowProblem]:
    if original.identifier in seen:
        return [RowProblem(number, column, f"{original.identifier!r} is also row {seen[original.identifier]}")]
    if original.file_stem.casefold() in stems:
        return [RowProblem(number, column, f"{original.identifier!r} would share the file name "
                                           f"{original.file_stem!r} with row {stems[original.file_stem.casefold()]}")]
    if out_dir is not None:
        try:
            check_folder(Path(out_dir), original)
        except DeliveryFolderError as exc:
            return [RowProblem(number, column, str(exc))]
    return []


__all__ = ["FIELDS", "ColumnNote", "QueueEntry", "QueueImport", "RowProblem", "column_option", "column_options",
           "extra_value", "read_queue_csv"]
