"""Small DNG files for the raw-loader and raw-info tests, written with PiDNG.

FACTS.md: PiDNG 4.0.9 round-trips bit-exact through rawpy only when stored uncompressed with BitsPerSample 16
(14-bit data, WhiteLevel 15520, as the D610 writes); BitsPerSample 14 and LJ92 are broken in that version.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

D610_WHITE = 15520
D610_BLACK = 600

# CFAPattern tag values: 0 = red, 1 = green, 2 = blue
CFA_CODES = {"R": 0, "G": 1, "B": 2}


def mosaic_14bit(height: int = 40, width: int = 60, seed: int = 0) -> np.ndarray:
    """Random 14-bit data between the D610's black and white levels, with one pixel at saturation."""
    rng = np.random.default_rng(seed)
    data = rng.integers(D610_BLACK, D610_WHITE, (height, width), dtype=np.uint16)
    data[0, 0] = D610_WHITE
    return data


def write_dng(path: Path, data: np.ndarray, *, cfa: str = "RGGB", black: int = D610_BLACK,
              white: int = D610_WHITE, make: str = "Nikon", model: str = "Nikon D610",
              exposure: Sequence[int] = (1, 125), linear_rgb: bool = False) -> Path:
    """Write ``data`` (uint16 (H, W) mosaic, or (H, W, 3) with linear_rgb) as an uncompressed 16-bit DNG."""
    from pidng.core import RAW2DNG, DNGTags, Tag
    from pidng.defs import CalibrationIlluminant, DNGVersion, Orientation, PhotometricInterpretation

    path = Path(path)
    h, w = data.shape[:2]
    t = DNGTags()
    t.set(Tag.ImageWidth, w)
    t.set(Tag.ImageLength, h)
    t.set(Tag.TileWidth, w)
    t.set(Tag.TileLength, h)
    t.set(Tag.Orientation, Orientation.Horizontal)
    t.set(Tag.BitsPerSample, 16)
    if linear_rgb:
        t.set(Tag.PhotometricInterpretation, PhotometricInterpretation.Linear_Raw)
        t.set(Tag.SamplesPerPixel, 3)
    else:
        t.set(Tag.PhotometricInterpretation, PhotometricInterpretation.Color_Filter_Array)
        t.set(Tag.SamplesPerPixel, 1)
        t.set(Tag.CFARepeatPatternDim, [2, 2])
        t.set(Tag.CFAPattern, [CFA_CODES[c] for c in cfa])
    t.set(Tag.BlackLevel, black)
    t.set(Tag.WhiteLevel, white)
    t.set(Tag.ColorMatrix1, [[1, 1], [0, 1], [0, 1], [0, 1], [1, 1], [0, 1], [0, 1], [0, 1], [1, 1]])
    t.set(Tag.CalibrationIlluminant1, CalibrationIlluminant.D65)
    t.set(Tag.AsShotNeutral, [[1, 1], [1, 1], [1, 1]])
    t.set(Tag.Make, make)
    t.set(Tag.Model, model)
    t.set(Tag.UniqueCameraModel, model)
    t.set(Tag.ExposureTime, [tuple(exposure)])
    t.set(Tag.DNGVersion, DNGVersion.V1_4)
    t.set(Tag.DNGBackwardVersion, DNGVersion.V1_2)
    writer = RAW2DNG()
    writer.options(t, path=str(path.parent), compress=False)
    name = path.name[:-4] if path.name.lower().endswith(".dng") else path.name
    out = Path(writer.convert(np.ascontiguousarray(data, dtype=np.uint16).reshape(h, -1), filename=name))
    if out != path:
        out.rename(path)
    return path
