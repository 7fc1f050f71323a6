"""Live view aids (issue 42), Qt-free: focus peaking, a framing grid and the zoom box's magnification.

Focus peaking marks the live picture's sharpest edges: the magnitude of the Laplacian of its grey levels (of a
Gaussian of 1 px, scipy.ndimage.gaussian_laplace, so pixel noise is not taken for an edge), where it is in the
top :data:`PEAK_SHARE` of the frame and above a floor relative to the frame's mean (a dark, flat picture is not
marked). As the focus ring turns, the marks crowd on the edges in focus and thin out elsewhere - what Capture One
and camera makers call focus peaking. The grid is thirds (or N x N) lines drawn into the same overlay. Computed on
the GUI thread: a live frame is at most a D610's 640 x 424 (a few milliseconds).
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

PEAK_SHARE = 0.04                # the share of pixels marked at most (the sharpest ones)
PEAK_FLOOR = 0.08                # ... and only where |Laplacian| is above this fraction of the mean grey level
PEAK_SIGMA = 1.0                 # px: the Laplacian of a Gaussian this wide (sensor noise is not an edge)
PEAK_RGBA = (0, 255, 60, 255)
GRID_RGBA = (255, 255, 255, 150)
MAGNIFICATIONS = (1, 2, 4)       # the zoom box: one live-view pixel on 1, 2 or 4 screen pixels


def peaking_mask(frame: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels focus peaking marks (see the module docstring)."""
    a = np.asarray(frame, dtype=np.float32)
    grey = a.mean(axis=2) if a.ndim == 3 else a
    if grey.size == 0 or min(grey.shape) < 3:
        return np.zeros(grey.shape, bool)
    edge = np.abs(ndimage.gaussian_laplace(grey, PEAK_SIGMA))
    floor = PEAK_FLOOR * max(float(grey.mean()), 1.0)
    cut = max(float(np.quantile(edge, 1.0 - PEAK_SHARE)), floor)
    return edge > cut


def live_overlay(frame: np.ndarray, *, peaking: bool, grid: int) -> np.ndarray:
    """(H, W, 4) uint8 over the live picture: focus peaking marks and a ``grid`` x ``grid`` grid (0: none)."""
    h, w = int(frame.shape[0]), int(frame.shape[1])
    out = np.zeros((h, w, 4), np.uint8)
    if grid > 1:
        for i in range(1, grid):
            out[(h * i) // grid, :] = GRID_RGBA
            out[:, (w * i) // grid] = GRID_RGBA
    if peaking:
        out[peaking_mask(frame)] = PEAK_RGBA
    return out


def magnified(crop: np.ndarray, factor: int) -> np.ndarray:
    """``crop`` with each pixel repeated ``factor`` x ``factor`` times (nearest neighbour: nothing invented)."""
    if factor <= 1:
        return crop
    return np.repeat(np.repeat(crop, factor, axis=0), factor, axis=1)
