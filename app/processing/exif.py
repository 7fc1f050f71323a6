"""The EXIF IFD of a delivered TIFF: what the camera did for the capture (make and model stay in IFD0), written by
hand because tifffile does not write one (it refuses tag 34665, ExifIFD).

How it gets into a streamed TIFF (app.processing.tiff_stream): tifffile writes IFD0 with a placeholder LONG tag
:data:`PLACEHOLDER` (a code that sorts where 34665 does: between Copyright 33432 and the ICC profile 34675, so
IFD0 stays in ascending order); before the header is hashed and written, the placeholder's code becomes 34665 and
its value the offset of the EXIF IFD, which is appended after the pixel data (:meth:`CaptureExif.ifd`). The file
is then what a writer with EXIF support makes: IFD0 -> pixels -> EXIF IFD, every offset word-aligned.

Tags (EXIF 2.32, CIPA DC-008-2019): ExposureTime, FNumber, ExposureProgram (1: manual), PhotographicSensitivity
(ISO), SensitivityType, ExifVersion, DateTimeOriginal / DateTimeDigitized with OffsetTimeOriginal /
OffsetTimeDigitized (the capture's local time and its UTC offset), FocalLength, ColorSpace (1 for the sRGB
master, 0xFFFF "uncalibrated" for every other), BodySerialNumber, LensModel. What a field does not know is left
out rather than guessed.
"""
from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from datetime import datetime
from fractions import Fraction

EXIF_IFD = 34665
PLACEHOLDER = 34666           # a private code tifffile writes; patched to EXIF_IFD (module docstring)
COLOUR_SPACE_SRGB = 1
COLOUR_SPACE_UNCALIBRATED = 0xFFFF
_TYPES = {"B": 1, "s": 2, "H": 3, "I": 4, "R": 5, "U": 7}
_FOCAL = re.compile(r"(\d+(?:\.\d+)?)\s*mm", re.IGNORECASE)
Value = float | int | str | bytes


def focal_length_mm(lens: str) -> float | None:
    """The focal length a lens name states ('AF-S Micro 60mm f/2.8' -> 60.0); None when it states none (a zoom's
    range gives its first figure only when there is one figure)."""
    found = _FOCAL.findall(lens or "")
    return float(found[0]) if len(found) == 1 else None


def _rational(value: float) -> tuple[int, int]:
    f = Fraction(value).limit_denominator(1_000_000)
    while f.numerator >= 2 ** 32:
        f = Fraction(round(f.numerator / 2), max(1, round(f.denominator / 2)))
    return f.numerator, f.denominator


def _ascii(text: str) -> bytes:
    return text.encode("ascii", "replace") + b"\0"


@dataclass(frozen=True)
class CaptureExif:
    """What the EXIF IFD says about one capture (None / "": not known, left out)."""

    captured: datetime                       # aware: the local time and its offset are written
    exposure_s: float | None = None
    f_number: float | None = None
    iso: int | None = None
    focal_mm: float | None = None
    serial: str = ""
    lens: str = ""
    colour_space: int = COLOUR_SPACE_UNCALIBRATED

    def entries(self) -> list[tuple[int, str, Value]]:
        """(tag, type, value) in ascending tag order; rationals as floats, text as str, UNDEFINED as bytes."""
        local = self.captured.astimezone() if self.captured.tzinfo is None else self.captured
        when = local.strftime("%Y:%m:%d %H:%M:%S")
        offset = local.strftime("%z")
        offset = f"{offset[:3]}:{offset[3:]}" if offset else "+00:00"
        out: list[tuple[int, str, Value]] = []
        if self.exposure_s:
            out.append((33434, "R", float(self.exposure_s)))
        if self.f_number:
            out.append((33437, "R", float(self.f_number)))
        out.append((34850, "H", 1))                                  # ExposureProgram: manual
        if self.iso:
            out += [(34855, "H", int(self.iso)), (34864, "H", 3)]   # SensitivityType 3: ISO speed
        out += [(36864, "U", b"0232"), (36867, "s", when), (36868, "s", when), (36881, "s", offset),
                (36882, "s", offset)]
        if self.focal_mm:
            out.append((37386, "R", float(self.focal_mm)))
        out += [(40960, "U", b"0100"), (40961, "H", int(self.colour_space))]
        if self.serial:
            out.append((42033, "s", self.serial))
        if self.lens:
            out.append((42036, "s", self.lens))
        return out

    def ifd(self, offset: int, byteorder: str = "<") -> bytes:
        """The EXIF IFD as it is stored at file ``offset`` (even): entry count, 12-byte entries, a next-IFD of 0,
        then the values longer than 4 bytes (each at an even offset)."""
        if offset % 2:
            raise ValueError(f"EXIF IFD at odd offset {offset}")
        entries = self.entries()
        head = struct.pack(byteorder + "H", len(entries))
        values = b""
        base = offset + 2 + 12 * len(entries) + 4
        for tag, kind, value in entries:
            data, count = _encode(kind, value, byteorder)
            if len(data) <= 4:
                field = data.ljust(4, b"\0")
            else:
                field = struct.pack(byteorder + "I", base + len(values))
                values += data + b"\0" * (len(data) % 2)
            head += struct.pack(byteorder + "HHI", tag, _TYPES[kind], count) + field
        return head + struct.pack(byteorder + "I", 0) + values


def _encode(kind: str, value: Value, byteorder: str) -> tuple[bytes, int]:
    if kind == "R" and isinstance(value, float | int):
        num, den = _rational(float(value))
        return struct.pack(byteorder + "II", num, den), 1
    if kind == "H" and isinstance(value, int):
        return struct.pack(byteorder + "H", value), 1
    data = _ascii(value) if isinstance(value, str) else value if isinstance(value, bytes) else None
    if data is None or kind not in ("s", "U"):
        raise ValueError(f"EXIF value {value!r} of type {kind}")
    return data, len(data)


def patch_placeholder(head: bytearray, exif_offset: int) -> bool:
    """In the bytes ``head`` of a classic TIFF (its IFD0 among them), turn the :data:`PLACEHOLDER` entry into the
    ExifIFD pointer to ``exif_offset``; False when IFD0 has no placeholder (or is not in ``head``)."""
    order = {b"II": "<", b"MM": ">"}.get(bytes(head[:2]))
    if order is None or struct.unpack(order + "H", head[2:4])[0] != 42:
        raise ValueError("not a classic TIFF header (BigTIFF or another format): no EXIF IFD can be linked")
    ifd0 = struct.unpack(order + "I", head[4:8])[0]
    if ifd0 + 2 > len(head):
        return False
    n = struct.unpack(order + "H", head[ifd0: ifd0 + 2])[0]
    for i in range(n):
        at = ifd0 + 2 + 12 * i
        if at + 12 > len(head):
            return False
        tag = struct.unpack(order + "H", head[at: at + 2])[0]
        if tag == PLACEHOLDER:
            head[at: at + 12] = struct.pack(order + "HHII", EXIF_IFD, _TYPES["I"], 1, exif_offset)
            return True
    return False
