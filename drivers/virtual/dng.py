"""Uncompressed CFA DNGs written with tifffile: the one DNG writer of the virtual camera, the tests and the benches.

The file is a single-IFD TIFF (``NewSubfileType`` 0, one strip, ``BitsPerSample`` 16, no compression) with
``PhotometricInterpretation`` CFA and the DNG tags as tifffile ``extratags``: what LibRaw (rawpy) needs to read
it back bit-exact, and what the processing pipeline reads from a real NEF: black and white levels, CFA
pattern, exposure time, ISO, f-number, make and model, the body's CameraSerialNumber, ColorMatrix1 and
AsShotNeutral. The shooting tags
(ExposureTime, FNumber, ISOSpeedRatings, DateTimeOriginal, with ExifVersion) sit in an EXIF IFD that IFD0's
ExifIFD tag (34665) points to, as a camera writes them: ``exiftool -validate`` wants them there, and LibRaw reads
ISO and the capture time only from there (in IFD0 it reported ISO 0 and a 1970 timestamp). tifffile writes no
EXIF IFD, so :func:`write_dng` appends it after tifffile's file and points IFD0's entry at it
(:func:`_append_exif_ifd`, ~30 lines of TIFF layout). The data are 14-bit in 16-bit words, as the D610 writes them;
uncompressed because the virtual lab needs no smaller files and LibRaw decodes it fastest.

References
----------
Adobe, *Digital Negative (DNG) Specification*, version 1.4.0.0 (2012): tags 50706-50778 used below.
CIPA DC-008 (JEITA CP-3451), *Exif 2.3*: the EXIF IFD and its tags 33434, 33437, 34855, 36864, 36867.
"""
from __future__ import annotations

import io
import logging
import os
import struct
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import BinaryIO

import numpy as np

log = logging.getLogger(__name__)

# CFAPattern tag values (TIFF/EP): 0 = red, 1 = green, 2 = blue
CFA_CODES = {"R": 0, "G": 1, "B": 2}
D65_ILLUMINANT = 21                         # EXIF LightSource code for CalibrationIlluminant1

# (code, TIFF type) of the tags written; types: 1 BYTE, 2 ASCII, 3 SHORT, 4 LONG, 5 RATIONAL, 10 SRATIONAL
_MAKE, _MODEL, _ORIENTATION = (271, 2), (272, 2), (274, 3)
_CFA_REPEAT_DIM, _CFA_PATTERN = (33421, 3), (33422, 1)
_EXPOSURE_TIME, _F_NUMBER = (33434, 5), (33437, 5)
_ISO, _DATE_TIME_ORIGINAL = (34855, 3), (36867, 2)
_EXIF_VERSION = (36864, 7)
_EXIF_IFD = (34665, 4)                      # IFD0's pointer to the EXIF IFD (LONG: a file offset)
# tifffile refuses to write tag 34665 itself (it writes EXIF IFDs of its own making only): IFD0 gets this unassigned
# code, which sorts at the same place among IFD0's entries, and _append_exif_ifd renames it to 34665
_EXIF_IFD_PLACEHOLDER = (34664, 4)
_TYPE_SIZES = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 7: 1, 10: 8}
_DNG_VERSION, _DNG_BACKWARD_VERSION, _UNIQUE_CAMERA_MODEL = (50706, 1), (50707, 1), (50708, 2)
_BLACK_LEVEL_REPEAT_DIM, _BLACK_LEVEL, _WHITE_LEVEL = (50713, 3), (50714, 4), (50717, 4)
_COLOR_MATRIX_1, _AS_SHOT_NEUTRAL, _BASELINE_EXPOSURE = (50721, 10), (50728, 5), (50730, 10)
_CALIBRATION_ILLUMINANT_1 = (50778, 3)
_CAMERA_SERIAL_NUMBER = (50735, 2)


@dataclass
class DngInfo:
    """What a DNG says about its mosaic besides the pixels.

    ``cfa``: the 2x2 Bayer pattern read row by row ('RGGB', 'BGGR', 'GRBG', 'GBRG'; any 4 letters of R, G, B).
    ``model``: 'Make Model' (the first word is the make unless ``make`` is given), as the camera reports it.
    ``color_matrix``: XYZ -> camera 3x3 (ColorMatrix1, D65); ``as_shot_neutral``: camera RGB of white (3,).
    """

    black_level: int = 600
    white_level: int = 15520
    cfa: str = "RGGB"
    exposure_s: float | None = None
    iso: int | None = None
    aperture: float | None = None
    model: str = "Nikon D610"
    make: str | None = None
    color_matrix: np.ndarray | None = None
    as_shot_neutral: np.ndarray | None = None
    captured_at: float | None = field(default=None)   # epoch seconds for DateTimeOriginal; None: now
    serial: str = ""                                   # CameraSerialNumber (the body's serial); '': not written

    def make_and_model(self) -> tuple[str, str]:
        if self.make:
            return self.make, self.model
        return self.model.partition(" ")[0] or self.model, self.model


def _rational(x: float, max_den: int = 100000) -> tuple[int, int]:
    f = Fraction(float(x)).limit_denominator(max_den)
    return f.numerator, f.denominator


def _rationals(values: Iterable[float], max_den: int) -> tuple[int, ...]:
    return tuple(v for x in values for v in _rational(x, max_den))


def _cfa_codes(cfa: str) -> tuple[int, ...]:
    if len(cfa) != 4 or any(c not in CFA_CODES for c in cfa.upper()):
        raise ValueError(f"CFA pattern {cfa!r}: expected 4 letters of R, G, B read row by row, like 'RGGB'")
    return tuple(CFA_CODES[c] for c in cfa.upper())


TagValue = tuple[int, ...] | str | bytes | int    # numbers (rationals: numerator, denominator pairs), text, UNDEFINED


def _entries(tags: list[tuple[tuple[int, int], TagValue]]) -> list[tuple[int, int, int, TagValue, bool]]:
    """(code, type, count, value, writeonce) rows, sorted by code, of ``tags`` ((code, type), value)."""
    out = []
    for (code, dtype), value in sorted(tags, key=lambda t: t[0][0]):
        if isinstance(value, (str, bytes)):
            count = len(value) + (1 if isinstance(value, str) else 0)   # ASCII: the text and its NUL
        elif isinstance(value, int):
            count = 1
        elif dtype in (5, 10):
            count = len(value) // 2                 # rationals: two numbers each
        else:
            count = len(value)
        out.append((code, dtype, count, value, True))
    return out


def dng_tags(info: DngInfo) -> list[tuple[int, int, int, TagValue, bool]]:
    """IFD0's DNG/TIFF tags of ``info`` as tifffile ``extratags`` (code, type, count, value, writeonce), with a
    placeholder for the ExifIFD pointer (:func:`write_dng` makes it one when it appends :func:`exif_tags`' IFD)."""
    cm = np.eye(3) if info.color_matrix is None else np.asarray(info.color_matrix, float)
    neutral = np.ones(3) if info.as_shot_neutral is None else np.asarray(info.as_shot_neutral, float)
    if cm.shape != (3, 3) or neutral.shape != (3,):
        raise ValueError(f"color matrix {cm.shape} / as-shot neutral {neutral.shape}: expected (3, 3) and (3,)")
    make, model = info.make_and_model()
    return _entries([
        (_MAKE, make), (_MODEL, model), (_ORIENTATION, 1),
        (_CFA_REPEAT_DIM, (2, 2)), (_CFA_PATTERN, _cfa_codes(info.cfa)), (_EXIF_IFD_PLACEHOLDER, 0),
        (_DNG_VERSION, (1, 4, 0, 0)), (_DNG_BACKWARD_VERSION, (1, 2, 0, 0)), (_UNIQUE_CAMERA_MODEL, info.model),
        (_BLACK_LEVEL_REPEAT_DIM, (1, 1)), (_BLACK_LEVEL, (int(info.black_level),)),
        (_WHITE_LEVEL, (int(info.white_level),)),
        (_COLOR_MATRIX_1, _rationals(cm.reshape(-1), 10000)), (_CALIBRATION_ILLUMINANT_1, D65_ILLUMINANT),
        (_AS_SHOT_NEUTRAL, _rationals(neutral, 10000)), (_BASELINE_EXPOSURE, (0, 1)),
        *([(_CAMERA_SERIAL_NUMBER, info.serial)] if info.serial else []),
    ])


def exif_tags(info: DngInfo) -> list[tuple[int, int, int, TagValue, bool]]:
    """The EXIF IFD's shooting tags of ``info``: ExposureTime, FNumber, ISOSpeedRatings, ExifVersion 2.3,
    DateTimeOriginal (local time, as a camera's clock)."""
    when = time.localtime(info.captured_at) if info.captured_at is not None else time.localtime()
    tags: list[tuple[tuple[int, int], TagValue]] = [
        (_EXIF_VERSION, b"0230"), (_DATE_TIME_ORIGINAL, time.strftime("%Y:%m:%d %H:%M:%S", when))]
    if info.exposure_s is not None:
        tags.append((_EXPOSURE_TIME, _rational(info.exposure_s)))
    if info.aperture is not None:
        tags.append((_F_NUMBER, _rational(info.aperture, 100)))
    if info.iso is not None:
        tags.append((_ISO, (int(info.iso),)))
    return _entries(tags)


def _ifd_bytes(entries: list[tuple[int, int, int, TagValue, bool]], at: int) -> bytes:
    """A little-endian TIFF IFD placed at file offset ``at`` (even): its entries, a zero next-IFD offset, then the
    values longer than 4 bytes (each at an even offset)."""
    head = 2 + 12 * len(entries) + 4
    table, data = struct.pack("<H", len(entries)), b""
    for code, dtype, count, value, _ in entries:
        if isinstance(value, str):
            raw = value.encode("ascii") + b"\0"
        elif isinstance(value, bytes):
            raw = value
        else:
            nums = (value,) if isinstance(value, int) else value
            raw = struct.pack("<" + {1: "B", 3: "H", 4: "I", 5: "I", 10: "i"}[dtype] * len(nums), *nums)
        if len(raw) != _TYPE_SIZES[dtype] * count:
            raise ValueError(f"TIFF tag {code}: {len(raw)} bytes for {count} values of type {dtype}")
        if len(raw) <= 4:
            field_ = raw.ljust(4, b"\0")
        else:
            field_ = struct.pack("<I", at + head + len(data))
            data += raw + b"\0" * (len(raw) % 2)
        table += struct.pack("<HHI", code, dtype, count) + field_
    return table + b"\0\0\0\0" + data


def _append_exif_ifd(fh: BinaryIO, start: int, entries: list[tuple[int, int, int, TagValue, bool]]) -> None:
    """Append the EXIF IFD of ``entries`` to the TIFF that begins at ``start`` in ``fh`` and make IFD0's placeholder
    entry the ExifIFD tag pointing at it (offsets count from ``start``, as TIFF's do)."""
    fh.seek(start)
    order, magic, ifd0 = struct.unpack("<2sHI", fh.read(8))
    if order != b"II" or magic != 42:
        raise ValueError("expected a little-endian classic TIFF from tifffile")
    fh.seek(start + ifd0)
    (n,) = struct.unpack("<H", fh.read(2))
    table = fh.read(12 * n)
    codes = [struct.unpack_from("<H", table, 12 * i)[0] for i in range(n)]
    entry = start + ifd0 + 2 + 12 * codes.index(_EXIF_IFD_PLACEHOLDER[0])
    end = fh.seek(0, os.SEEK_END)
    at = end - start + (end - start) % 2
    fh.write(b"\0" * ((end - start) % 2) + _ifd_bytes(entries, at))
    fh.seek(entry)
    fh.write(struct.pack("<HHII", _EXIF_IFD[0], _EXIF_IFD[1], 1, at))
    fh.seek(0, os.SEEK_END)


def write_dng(target: str | Path | BinaryIO, mosaic: np.ndarray, info: DngInfo) -> None:
    """Write ``mosaic`` ((H, W) uint16, raw DN with the black level in) as an uncompressed CFA DNG (``target``: a
    path, or a seekable binary file written from its current position)."""
    import tifffile  # ~0.1 s: only captures and tests pay it

    if mosaic.dtype != np.uint16 or mosaic.ndim != 2:
        raise ValueError(f"mosaic must be a 2-D uint16 array, got {mosaic.dtype} {mosaic.shape}")
    ifd0, exif = dng_tags(info), exif_tags(info)
    if isinstance(target, (str, os.PathLike)):
        with open(target, "w+b") as fh:
            _write_dng(fh, mosaic, ifd0, exif, tifffile)
    else:
        _write_dng(target, mosaic, ifd0, exif, tifffile)


def _write_dng(fh: BinaryIO, mosaic: np.ndarray, ifd0: list, exif: list, tifffile) -> None:
    start = fh.tell()
    tifffile.imwrite(fh, np.ascontiguousarray(mosaic), photometric="cfa", subfiletype=0, byteorder="<",
                     rowsperstrip=mosaic.shape[0], compression=None, metadata=None, software=False, extratags=ifd0)
    _append_exif_ifd(fh, start, exif)


def dng_bytes(mosaic: np.ndarray, info: DngInfo) -> bytes:
    """The DNG file of ``mosaic`` as bytes (what a camera download delivers)."""
    buf = io.BytesIO()
    write_dng(buf, mosaic, info)
    return buf.getvalue()


def save_dng(path: str | Path, mosaic: np.ndarray, info: DngInfo | None = None) -> Path:
    """Write a DNG file at ``path`` (tests and benches); returns the path."""
    path = Path(path)
    write_dng(path, mosaic, info or DngInfo())
    return path
