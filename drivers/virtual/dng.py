"""Uncompressed CFA DNGs written with tifffile: the one DNG writer of the virtual camera, the tests and the benches.

The file is a single-IFD TIFF (``NewSubfileType`` 0, one strip, ``BitsPerSample`` 16, no compression) with
``PhotometricInterpretation`` CFA and the DNG tags as tifffile ``extratags``: what LibRaw (rawpy) needs to read
it back bit-exact, and what the processing pipeline reads from a real NEF: black and white levels, CFA
pattern, exposure time, ISO, f-number, make and model, ColorMatrix1 and AsShotNeutral. The EXIF shooting tags
sit in IFD0 (TIFF/EP style), where LibRaw looks for them in a DNG. The data are 14-bit in 16-bit words, as the
D610 writes them; uncompressed because the virtual lab needs no smaller files and LibRaw decodes it fastest.

References
----------
Adobe, *Digital Negative (DNG) Specification*, version 1.4.0.0 (2012): tags 50706-50778 used below.
"""
from __future__ import annotations

import io
import logging
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
_DNG_VERSION, _DNG_BACKWARD_VERSION, _UNIQUE_CAMERA_MODEL = (50706, 1), (50707, 1), (50708, 2)
_BLACK_LEVEL_REPEAT_DIM, _BLACK_LEVEL, _WHITE_LEVEL = (50713, 3), (50714, 4), (50717, 4)
_COLOR_MATRIX_1, _AS_SHOT_NEUTRAL, _BASELINE_EXPOSURE = (50721, 10), (50728, 5), (50730, 10)
_CALIBRATION_ILLUMINANT_1 = (50778, 3)


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


TagValue = tuple[int, ...] | str | int     # numbers (rationals as numerator, denominator pairs), ASCII text


def dng_tags(info: DngInfo) -> list[tuple[int, int, int, TagValue, bool]]:
    """The DNG/EXIF tags of ``info`` as tifffile ``extratags`` (code, type, count, value, writeonce)."""
    cm = np.eye(3) if info.color_matrix is None else np.asarray(info.color_matrix, float)
    neutral = np.ones(3) if info.as_shot_neutral is None else np.asarray(info.as_shot_neutral, float)
    if cm.shape != (3, 3) or neutral.shape != (3,):
        raise ValueError(f"color matrix {cm.shape} / as-shot neutral {neutral.shape}: expected (3, 3) and (3,)")
    make, model = info.make_and_model()
    when = time.localtime(info.captured_at) if info.captured_at is not None else time.localtime()
    tags: list[tuple[tuple[int, int], TagValue]] = [
        (_MAKE, make), (_MODEL, model), (_ORIENTATION, 1),
        (_CFA_REPEAT_DIM, (2, 2)), (_CFA_PATTERN, _cfa_codes(info.cfa)),
        (_DATE_TIME_ORIGINAL, time.strftime("%Y:%m:%d %H:%M:%S", when)),
        (_DNG_VERSION, (1, 4, 0, 0)), (_DNG_BACKWARD_VERSION, (1, 2, 0, 0)), (_UNIQUE_CAMERA_MODEL, info.model),
        (_BLACK_LEVEL_REPEAT_DIM, (1, 1)), (_BLACK_LEVEL, (int(info.black_level),)),
        (_WHITE_LEVEL, (int(info.white_level),)),
        (_COLOR_MATRIX_1, _rationals(cm.reshape(-1), 10000)), (_CALIBRATION_ILLUMINANT_1, D65_ILLUMINANT),
        (_AS_SHOT_NEUTRAL, _rationals(neutral, 10000)), (_BASELINE_EXPOSURE, (0, 1)),
    ]
    if info.exposure_s is not None:
        tags.append((_EXPOSURE_TIME, _rational(info.exposure_s)))
    if info.aperture is not None:
        tags.append((_F_NUMBER, _rational(info.aperture, 100)))
    if info.iso is not None:
        tags.append((_ISO, (int(info.iso),)))
    out = []
    for (code, dtype), value in sorted(tags, key=lambda t: t[0][0]):
        if isinstance(value, str):
            count = len(value) + 1                  # ASCII: the text and its NUL
        elif isinstance(value, int):
            count = 1
        elif dtype in (5, 10):
            count = len(value) // 2                 # rationals: two numbers each
        else:
            count = len(value)
        out.append((code, dtype, count, value, True))
    return out


def write_dng(target: str | Path | BinaryIO, mosaic: np.ndarray, info: DngInfo) -> None:
    """Write ``mosaic`` ((H, W) uint16, raw DN with the black level in) as an uncompressed CFA DNG."""
    import tifffile  # ~0.1 s: only captures and tests pay it

    if mosaic.dtype != np.uint16 or mosaic.ndim != 2:
        raise ValueError(f"mosaic must be a 2-D uint16 array, got {mosaic.dtype} {mosaic.shape}")
    tifffile.imwrite(target, np.ascontiguousarray(mosaic), photometric="cfa", subfiletype=0,
                     rowsperstrip=mosaic.shape[0], compression=None, metadata=None, software=False,
                     extratags=dng_tags(info))


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
