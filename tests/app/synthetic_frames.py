"""Synthetic raw mosaics with known truth for the processing tests (numpy only, small frames).

A scene is a grid of patches with known per-channel reflectance; the camera sees
    raw = dark(t) + radiance * t * vignette * reflectance  (+ read noise), clipped at the white level,
with a dark frame that has a black level, a per-pixel dark-current pattern and persistent hot pixels.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from dualrgb.app.processing.mosaic import mosaic_from_rgb
from dualrgb.drivers.virtual.dng import DngInfo, save_dng

WHITE = 15520
BLACK = 600


def patch_reflectance(rows: int, cols: int, seed: int = 0) -> np.ndarray:
    """(rows*cols, 3) reflectances between 0.03 and 0.95."""
    rng = np.random.default_rng(seed)
    return rng.uniform(0.03, 0.95, (rows * cols, 3))


def patch_image(refl: np.ndarray, rows: int, cols: int, cell: int = 8, border: int = 0,
                background: float = 0.05) -> np.ndarray:
    """(rows*cell + 2*border, cols*cell + 2*border, 3) image of axis-aligned patches."""
    h, w = rows * cell + 2 * border, cols * cell + 2 * border
    img = np.full((h, w, 3), background)
    for k in range(rows * cols):
        r, c = divmod(k, cols)
        img[border + r * cell: border + (r + 1) * cell, border + c * cell: border + (c + 1) * cell] = refl[k]
    return img


def vignette(h: int, w: int, strength: float = 0.6) -> np.ndarray:
    """1 at the centre, 1 - strength at the corners (cos^4-like falloff)."""
    y, x = np.mgrid[0:h, 0:w]
    r2 = ((x - (w - 1) / 2) / (w / 2)) ** 2 + ((y - (h - 1) / 2) / (h / 2)) ** 2
    return 1.0 - strength * r2 / 2.0


def true_dark(h: int, w: int, exposure_s: float, seed: int = 1, n_hot: int = 20) -> np.ndarray:
    """Black level + dark current growing with time + persistent hot pixels (float DN)."""
    rng = np.random.default_rng(seed)
    current = rng.uniform(0.5, 2.0, (h, w)) * 40.0 * exposure_s        # DN/s pattern
    d = BLACK + current
    hot = rng.choice(h * w, n_hot, replace=False)
    d.ravel()[hot] += 800.0 + 4000.0 * exposure_s
    return d


def dark_frames(h: int, w: int, exposure_s: float, n: int = 10, noise: float = 2.0, spikes: float = 0.01,
                seed: int = 2) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """n uint16 dark frames with read noise and transient spikes (each pixel spiked in at most one frame).
    Returns (frames, true dark, mask of spiked pixels)."""
    rng = np.random.default_rng(seed)
    truth = true_dark(h, w, exposure_s)
    frames = [truth + rng.normal(0, noise, (h, w)) for _ in range(n)]
    spiked = rng.random((h, w)) < spikes
    which = rng.integers(0, n, (h, w))
    for i in range(n):
        m = spiked & (which == i)
        frames[i][m] += rng.uniform(300, 6000, int(m.sum()))
    return [np.clip(np.round(f), 0, 65535).astype(np.uint16) for f in frames], truth, spiked


def expose(radiance: np.ndarray, exposure_s: float, dark: np.ndarray, noise: float = 0.0, seed: int = 3,
           white: int = WHITE) -> np.ndarray:
    """uint16 raw mosaic: dark + radiance * t (+ noise), clipped at the white level."""
    rng = np.random.default_rng(seed)
    x = dark + radiance * exposure_s
    if noise:
        x = x + rng.normal(0, noise, x.shape)
    return np.clip(np.round(x), 0, white).astype(np.uint16)


def mosaic_scene(refl: np.ndarray, rows: int, cols: int, cell: int = 8, border: int = 0,
                 cfa: str = "RGGB") -> np.ndarray:
    """Reflectance mosaic (2x the patch image size) of a patch chart."""
    return mosaic_from_rgb(patch_image(refl, rows, cols, cell, border), cfa)


def write_dng(path: Path, data: np.ndarray, *, black: int = BLACK, white: int = WHITE, cfa: str = "RGGB",
              exposure=(1, 125)) -> Path:
    """Uncompressed 16-bit DNG through the app's one DNG writer (rawpy reads it back bit-exact)."""
    num, den = exposure
    return save_dng(path, np.ascontiguousarray(data, dtype=np.uint16),
                    DngInfo(black, white, cfa=cfa, exposure_s=num / den))
