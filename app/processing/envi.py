"""ENVI spectral cubes: the header (the text format the spectral-imaging ecosystem reads: ENVI, Spectral Python,
GDAL's ENVI driver ...), the data file streamed band by band, and reading a delivered cube back.

The layout written here (the one place it is decided):

* the data file ``<stem>.img``: headerless (``header offset = 0``), unsigned 16-bit (``data type = 12``),
  little-endian (``byte order = 0``), band-interleaved by line (``interleave = bil``): line after line, each
  line the first band's samples, then the second's ... So a row band of the image is one contiguous run of the
  file: the cube is written by app.processing.tiff_stream.RawStream exactly like the TIFFs, while the next band
  is computed (band sequential would put each band of a row band in another part of the file: 38 seeks per row
  band, or a file per wavelength; band-interleaved by pixel would need a transpose per pixel, not per row);
* the value is the reflectance (transmittance) factor x ``reflectance scale factor`` (10000: 1.0 -> 10000, a
  step of 0.0001, far below the estimate's noise; ENVI's own convention), rounded; pixels without a usable
  estimate hold ``data ignore value`` (65535);
* ``wavelength = {...}`` and ``wavelength units = Nanometers``: the band centres; ``description`` names the
  original and the calibration; ``dualrgb ...`` fields say the same for programs.

Spectral Python: ``img = spectral.envi.open("ACC-1_spectral.hdr")``; ``img.bands.centers`` are the wavelengths,
``img.load()`` and ``img.read_pixel(row, col)`` divide by the scale factor (reflectance factors; a pixel without
an estimate reads 6.5535 there: compare with ``data ignore value`` / scale).

References
----------
ENVI Header Format (NV5 Geospatial / L3Harris, ENVI documentation: "ENVI Header Format"; data type codes,
interleave, byte order, reflectance scale factor, data ignore value, wavelength units).
"""
from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dualrgb.common.atomic_files import atomic_write

log = logging.getLogger(__name__)

DATA_TYPE_UINT16 = 12                 # ENVI data type codes: 1 byte, 2 int16, 4 float32, 12 uint16 ...
BYTE_ORDER = 0                        # 0: little-endian (ENVI), 1: big-endian
DTYPE = np.dtype("<u2")               # the stored samples: little-endian uint16, whatever the host
INTERLEAVE = "bil"
SCALE_FACTOR = 10000.0                # stored value = factor x 10000 (ENVI's usual reflectance scale)
IGNORE_VALUE = 65535                  # pixels without a usable estimate
_DTYPES = {1: "u1", 2: "i2", 3: "i4", 4: "f4", 5: "f8", 12: "u2", 13: "u4"}
_FIELD = re.compile(r"^\s*([^=]+?)\s*=\s*(.*)$")


@dataclass
class EnviHeader:
    """An ENVI header of a ``lines`` x ``samples`` x ``bands`` cube stored as :data:`DTYPE`, BIL."""

    lines: int
    samples: int
    bands: int
    wavelengths: Sequence[float]
    description: str = ""
    scale_factor: float = SCALE_FACTOR
    ignore_value: int = IGNORE_VALUE
    extra: dict[str, str] = field(default_factory=dict)      # more "key = value" fields (e.g. 'dualrgb method')

    def text(self) -> str:
        """The header file's text (ASCII; braces and line breaks in free text are replaced)."""
        waves = ", ".join(f"{float(w):g}" for w in self.wavelengths)
        lines = ["ENVI", f"description = {{{_free(self.description)}}}", f"samples = {self.samples}",
                 f"lines = {self.lines}", f"bands = {self.bands}", "header offset = 0",
                 "file type = ENVI Standard", f"data type = {DATA_TYPE_UINT16}", f"interleave = {INTERLEAVE}",
                 f"byte order = {BYTE_ORDER}", f"reflectance scale factor = {self.scale_factor:g}",
                 f"data ignore value = {self.ignore_value}", "wavelength units = Nanometers",
                 f"wavelength = {{{waves}}}"]
        lines += [f"{_free(k)} = {_free(v)}" for k, v in self.extra.items()]
        return "\n".join(lines) + "\n"

    def write(self, path: Path) -> Path:
        """The header file, written atomically (common.atomic_files)."""
        if len(self.wavelengths) != self.bands:
            raise ValueError(f"{path}: {len(self.wavelengths)} wavelengths for {self.bands} bands")
        return atomic_write(Path(path), self.text().encode("ascii"))


def _free(text: object) -> str:
    """Free text for a header field: ASCII, one line, no braces (they delimit ENVI lists)."""
    s = re.sub(r"\s+", " ", str(text)).replace("{", "(").replace("}", ")")
    return s.encode("ascii", "replace").decode("ascii").strip()


def read_header(path: Path) -> dict[str, str]:
    """The fields of an ENVI header (keys lower case, values as text; ``{...}`` lists joined onto one line);
    a file that is not one is a one-line ValueError."""
    text = Path(path).read_text(encoding="ascii", errors="replace")
    if not text.startswith("ENVI"):
        raise ValueError(f"{path}: not an ENVI header (expected 'ENVI' on its first line)")
    fields: dict[str, str] = {}
    pending = ""
    for line in text.splitlines()[1:]:
        pending = f"{pending} {line.strip()}" if pending else line
        if pending.count("{") > pending.count("}"):
            continue                                   # a list continues on the next line
        m = _FIELD.match(pending)
        pending = ""
        if m:
            fields[m.group(1).strip().lower()] = m.group(2).strip()
    return fields


def _list(value: str) -> list[str]:
    return [v.strip() for v in value.strip().strip("{}").split(",") if v.strip()]


@dataclass
class CubeFile:
    """A delivered ENVI cube opened for reading (memory-mapped: nothing is read until asked)."""

    header_path: Path
    data_path: Path
    data: np.ndarray                 # (lines, bands, samples) for BIL: the stored integers
    wavelengths: np.ndarray
    scale_factor: float
    ignore_value: float | None

    @property
    def shape(self) -> tuple[int, int, int]:
        """(lines, samples, bands)."""
        return self.data.shape[0], self.data.shape[2], self.data.shape[1]

    def pixel(self, row: int, col: int) -> np.ndarray:
        """The factor spectrum (bands,) of one pixel (NaN where the cube holds the ignore value)."""
        if not (0 <= row < self.shape[0] and 0 <= col < self.shape[1]):
            raise ValueError(f"{self.data_path.name}: pixel ({row}, {col}) outside {self.shape[1]} x {self.shape[0]}")
        return self._factors(np.asarray(self.data[row, :, col]))

    def rows(self, r0: int, r1: int, step: int = 1) -> np.ndarray:
        """Factor spectra (rows, samples / step, bands) of rows r0 .. r1 (every ``step``-th row and column)."""
        block = np.asarray(self.data[r0:r1:step, :, ::step])
        return self._factors(np.moveaxis(block, 1, -1))

    def _factors(self, stored: np.ndarray) -> np.ndarray:
        out = stored.astype(np.float32) / np.float32(self.scale_factor)
        if self.ignore_value is not None:
            out[stored == self.ignore_value] = np.nan
        return out


def open_cube(header_path: Path) -> CubeFile:
    """Open the ENVI cube of ``header_path`` (its data file: the header's name with ``.img``, or the same name
    without extension); only what this module writes and its BIL / BSQ / BIP relatives are understood."""
    path = Path(header_path)
    h = read_header(path)
    try:
        lines, samples, bands = (int(h[k]) for k in ("lines", "samples", "bands"))
        dtype = np.dtype(_DTYPES[int(h.get("data type", "12"))]).newbyteorder("<" if h.get("byte order", "0") == "0"
                                                                                else ">")
        interleave = h.get("interleave", "bsq").lower()
        offset = int(h.get("header offset", "0"))
        waves = np.array([float(v) for v in _list(h.get("wavelength", ""))])
    except (KeyError, ValueError) as exc:
        raise ValueError(f"{path}: incomplete or unreadable ENVI header ({exc})") from None
    data_path = next((p for p in (path.with_suffix(".img"), path.with_suffix("")) if p.is_file()), None)
    if data_path is None:
        raise ValueError(f"{path}: its data file {path.with_suffix('.img').name} is missing")
    shapes = {"bil": (lines, bands, samples), "bsq": (bands, lines, samples), "bip": (lines, samples, bands)}
    if interleave not in shapes:
        raise ValueError(f"{path}: interleave {interleave!r}, expected bil, bsq or bip")
    mm = np.memmap(data_path, dtype=dtype, mode="r", offset=offset, shape=shapes[interleave])
    data = {"bil": mm, "bsq": np.transpose(mm, (1, 0, 2)), "bip": np.transpose(mm, (0, 2, 1))}[interleave]
    ignore = float(h["data ignore value"]) if "data ignore value" in h else None
    return CubeFile(path, data_path, data, waves, float(h.get("reflectance scale factor", "1")), ignore)
