"""Reading and writing spectral CSV files (resources and user-supplied measurements), with validation.

Format: optional ``# key: value`` comment lines (units, source, how it was made), one header row
``wavelength_nm,<name>,<name>,...`` and one data row per wavelength, strictly increasing.
Every problem raises :class:`SpectralDataError` with a one-line message naming file, line and problem.
"""
from __future__ import annotations

import csv
import logging
import math
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dualrgb.common.atomic_files import atomic_output

log = logging.getLogger(__name__)

MAX_CSV_BYTES = 64 * 2**20         # a 1 nm table of hundreds of patches is a few MB


class SpectralDataError(ValueError):
    """A spectral CSV is malformed; the message is one line: ``file:line: problem``."""


@dataclass
class SpectralTable:
    """Tabulated spectra: ``values`` has shape (n_wavelengths, n_columns)."""

    wavelengths: np.ndarray
    values: np.ndarray
    columns: list[str]
    meta: dict[str, str] = field(default_factory=dict)
    source: str = ""
    warnings: list[str] = field(default_factory=list)    # the reader's warning lines (already logged)


def read_spectral_csv(
    path: str | Path,
    *,
    expected_columns: int | None = None,
    allow_negative: bool = False,
    max_value: float | None = None,
    wavelength_range: tuple[float, float] = (200.0, 2500.0),
) -> SpectralTable:
    """Read and validate a spectral CSV. ``max_value`` bounds the data (1.0 for reflectance/transmittance)."""
    path = Path(path)
    name = str(path)
    text = read_text_file(path, "CSV", SpectralDataError, MAX_CSV_BYTES)
    return parse_spectral_csv(
        text, name, expected_columns=expected_columns, allow_negative=allow_negative,
        max_value=max_value, wavelength_range=wavelength_range,
    )


def read_text_file(path: Path, what: str, error: type, max_bytes: int) -> str:
    """The UTF-8 text of a user's file, or ``error`` with one line naming it: only regular files (a FIFO or
    a device would block), at most ``max_bytes``, no binary or UTF-16 content."""
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode):
            kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file"
            raise error(f"{path}: {kind}; expected a UTF-8 text {what} file")
        if st.st_size > max_bytes:
            raise error(f"{path}: {st.st_size / 2**20:.1f} MiB is too large for a {what} file "
                        f"(limit {max_bytes / 2**20:.0f} MiB)")
        data = path.read_bytes()
    except OSError as exc:
        raise error(f"{path}: cannot read file ({exc.strerror or exc})") from None
    try:
        if b"\x00" in data:
            raise UnicodeDecodeError("utf-8", data[:1], 0, 1, "NUL byte")
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise error(f"{path}: binary or not UTF-8 (UTF-16?); expected a UTF-8 text {what} file") from None


def _header_row(cells: list[str], where: str, expected_columns: int | None) -> list[str]:
    """The header row (wavelength column, then the data columns' names); ``where`` is "file:line"."""
    if len(cells) < 2:
        raise SpectralDataError(f"{where}: header needs a wavelength column and at least one data column")
    try:
        float(cells[0])
    except ValueError:
        pass
    else:
        raise SpectralDataError(f"{where}: expected a header row (wavelength_nm,<names>...), found numbers")
    if expected_columns is not None and len(cells) - 1 != expected_columns:
        raise SpectralDataError(
            f"{where}: expected {expected_columns} data columns after the wavelength, found {len(cells) - 1}"
        )
    return cells


def _numbers(cells: list[str], header: list[str], where: str) -> list[float]:
    """A data row as finite numbers, one per header column."""
    if len(cells) != len(header):
        raise SpectralDataError(f"{where}: expected {len(header)} columns as in the header, found {len(cells)}")
    values: list[float] = []
    for col, cell in zip(header, cells, strict=True):
        try:
            v = float(cell)
        except ValueError:
            raise SpectralDataError(f"{where}: column {col!r}: {cell!r} is not a number") from None
        if math.isnan(v) or math.isinf(v):
            raise SpectralDataError(f"{where}: column {col!r}: {cell} is not a finite number")
        values.append(v)
    return values


def _check_row(values: list[float], header: list[str], where: str, previous_wl: float | None, *,
               allow_negative: bool, max_value: float | None, wavelength_range: tuple[float, float]) -> None:
    """The row's wavelength in range and above the previous row's; its values within the allowed range."""
    wl = values[0]
    if not wavelength_range[0] <= wl <= wavelength_range[1]:
        raise SpectralDataError(
            f"{where}: wavelength {wl:g} nm is outside {wavelength_range[0]:g}-{wavelength_range[1]:g} nm"
            " (is the first column in nm?)"
        )
    if previous_wl is not None and wl <= previous_wl:
        raise SpectralDataError(f"{where}: wavelengths must increase strictly; {wl:g} nm follows {previous_wl:g} nm")
    for col, v in zip(header[1:], values[1:], strict=True):
        if v < 0 and not allow_negative:
            raise SpectralDataError(f"{where}: column {col!r}: negative value {v:g}")
        if max_value is not None and v > max_value * (1 + 1e-9):
            raise SpectralDataError(f"{where}: column {col!r}: value {v:g} exceeds {max_value:g}")


def parse_spectral_csv(
    text: str,
    name: str = "<text>",
    *,
    expected_columns: int | None = None,
    allow_negative: bool = False,
    max_value: float | None = None,
    wavelength_range: tuple[float, float] = (200.0, 2500.0),
) -> SpectralTable:
    meta: dict[str, str] = {}
    header: list[str] | None = None
    rows: list[list[float]] = []
    wavelengths: list[float] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            key, sep, value = line.lstrip("#").partition(":")
            if sep:
                meta[key.strip().lower()] = value.strip()
            continue
        where = f"{name}:{lineno}"
        try:
            cells = [c.strip() for c in next(csv.reader([line]))]
        except csv.Error as exc:
            raise SpectralDataError(f"{where}: not a CSV row ({exc})") from None
        if header is None:
            header = _header_row(cells, where, expected_columns)
            continue
        values = _numbers(cells, header, where)
        _check_row(values, header, where, wavelengths[-1] if wavelengths else None, allow_negative=allow_negative,
                   max_value=max_value, wavelength_range=wavelength_range)
        wavelengths.append(values[0])
        rows.append(values[1:])
    if header is None:
        raise SpectralDataError(f"{name}:1: no header row and no data")
    if len(rows) < 2:
        raise SpectralDataError(f"{name}:{len(text.splitlines())}: need at least two wavelength rows, "
                                f"found {len(rows)}")
    table = SpectralTable(np.array(wavelengths), np.array(rows, dtype=float), header[1:], meta, name)
    log.debug("read %s: %d wavelengths x %d columns", name, *table.values.shape)
    return table


def write_spectral_csv(
    path: str | Path, wavelengths: np.ndarray, values: np.ndarray, columns: list[str], meta: dict[str, str],
    fmt: str = "%.8g",
) -> None:
    """Write a spectral CSV with ``# key: value`` header lines (units, source, generated-by...)."""
    path = Path(path)
    values = np.asarray(values, dtype=float).reshape(len(wavelengths), -1)
    if values.shape[1] != len(columns):
        raise ValueError(f"{path}: {values.shape[1]} value columns but {len(columns)} names")
    with atomic_output(path, "w", newline="") as fh:
        for key, value in meta.items():
            fh.write(f"# {key}: {value}\n")
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(["wavelength_nm", *columns])
        for wl, row in zip(wavelengths, values, strict=True):
            writer.writerow([f"{wl:g}", *(fmt % v for v in row)])
