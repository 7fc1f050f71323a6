"""Small DNG files for the raw-loader and raw-info tests, written by drivers.virtual.dng (the virtual camera's
writer): uncompressed, BitsPerSample 16, 14-bit data and WhiteLevel 15520 as the D610 writes them.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dualrgb.drivers.virtual.dng import DngInfo, save_dng

D610_WHITE = 15520
D610_BLACK = 600


def mosaic_14bit(height: int = 40, width: int = 60, seed: int = 0) -> np.ndarray:
    """Random 14-bit data between the D610's black and white levels, with one pixel at saturation."""
    rng = np.random.default_rng(seed)
    data = rng.integers(D610_BLACK, D610_WHITE, (height, width), dtype=np.uint16)
    data[0, 0] = D610_WHITE
    return data


def write_dng(path: Path, data: np.ndarray, *, cfa: str = "RGGB", black: int = D610_BLACK,
              white: int = D610_WHITE, make: str = "Nikon", model: str = "Nikon D610",
              exposure: Sequence[int] = (1, 125)) -> Path:
    """Write ``data`` (uint16 (H, W) mosaic) as an uncompressed 16-bit DNG with the app's one DNG writer."""
    num, den = exposure
    return save_dng(path, np.ascontiguousarray(data, dtype=np.uint16),
                    DngInfo(black, white, cfa=cfa, exposure_s=num / den, make=make, model=model))
