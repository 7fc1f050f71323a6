"""The delivery encodings of an N-channel stack in one pass: XYZ, sRGB and ProPhoto RGB (16-bit, display-encoded)
and the N channels themselves (16-bit), plus the QA counts.

Why hand-written: the deliverables of a 24 MP original are four 16-bit images (~360 MB) computed from a 12 MP
x 6 float32 stack. In numpy each step (matrix, adaptation, clip, the piecewise power of the colour space's
encoding, rounding, casting) is a separate pass with temporaries, and colour-science's encoding functions alone
took longer than decoding the raw files (bench/digitise_bench.py). One fused numba pass per pixel reads the stack
once and writes each output once; the non-linear encodings come from 65 536-entry tables of colour-science's own
``cctf_encoding`` with linear interpolation (error < 0.01 of a 16-bit code; checked in the tests against
colour-science), so the colour maths stays colour-science's.

Scales. RGB: a perfect white (the reference white's XYZ) encodes to 65535 in every channel, values outside
[0, 1] are clipped. XYZ and the N channels are linear with ``LINEAR_ONE`` (32768) for 1.0: XYZ relative to the
reference white's Y (Y = 100 -> 32768), channels as flat-fielded (1.0 = the white / open gate), so both keep a
2x headroom above white. NaN (no usable flat field) becomes 0.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit, prange

log = logging.getLogger(__name__)

LINEAR_ONE = 32768.0          # 16-bit code of 1.0 in the linear XYZ and channel images
LUT_SIZE = 65536
RGB_SPACES = ("sRGB", "ProPhoto RGB")


@lru_cache(maxsize=4)
def encoding_table(space: str) -> np.ndarray:
    """(LUT_SIZE,) float32: colour-science's ``cctf_encoding`` of the space at LUT_SIZE points of [0, 1], x 65535."""
    import colour

    x = np.linspace(0.0, 1.0, LUT_SIZE)
    enc = np.asarray(colour.RGB_COLOURSPACES[space].cctf_encoding(x), dtype=np.float64)
    return (np.clip(enc, 0.0, 1.0) * 65535.0).astype(np.float32)


@dataclass
class EncodedImages:
    """The 16-bit deliverable arrays of one original and what the QA line needs."""

    xyz: np.ndarray               # (H, W, 3) uint16, linear, LINEAR_ONE = reference white's Y
    rgb: dict[str, np.ndarray]    # space -> (H, W, 3) uint16 display-encoded
    channels: np.ndarray          # (H, W, N) uint16, linear, LINEAR_ONE = 1.0
    invalid_fraction: float       # pixels with NaN (no usable flat field)
    over_white_fraction: float    # pixels whose Y exceeds 2x the white (clipped in the XYZ image)


@njit(parallel=True, cache=True, nogil=True)
def _encode(stack, A, M, luts, scale_xyz, xyz16, rgb16, ch16):  # pragma: no cover - compiled
    H, W, C = stack.shape
    n_rgb = M.shape[0]
    last = luts.shape[1] - 1
    bad = np.zeros(H, np.int64)
    over = np.zeros(H, np.int64)
    for i in prange(H):
        nb = 0
        no = 0
        for j in range(W):
            x = np.float32(0.0)
            y = np.float32(0.0)
            z = np.float32(0.0)
            nan = False
            for c in range(C):
                v = stack[i, j, c]
                if v != v:
                    nan = True
                    v = np.float32(0.0)
                x += v * A[c, 0]
                y += v * A[c, 1]
                z += v * A[c, 2]
                q = v * np.float32(LINEAR_ONE) + np.float32(0.5)
                ch16[i, j, c] = 0 if q <= 0.5 else (65535 if q >= 65535.0 else np.uint16(q))
            nb += nan
            xyzv = (x, y, z)
            for k in range(3):
                val = xyzv[k]
                q = val * scale_xyz + np.float32(0.5)
                if k == 1 and q >= 65535.0:
                    no += 1
                xyz16[i, j, k] = 0 if q <= 0.5 else (65535 if q >= 65535.0 else np.uint16(q))
            for s in range(n_rgb):
                for k in range(3):
                    lin = M[s, k, 0] * x + M[s, k, 1] * y + M[s, k, 2] * z
                    lin = min(max(lin, np.float32(0.0)), np.float32(1.0)) * last
                    i0 = min(int(lin), last - 1)
                    f = lin - i0
                    e = luts[s, i0] + f * (luts[s, i0 + 1] - luts[s, i0])
                    rgb16[s, i, j, k] = np.uint16(e + np.float32(0.5))
        bad[i] = nb
        over[i] = no
    return bad.sum(), over.sum()


@njit(parallel=True, cache=True, nogil=True)
def weak_cells(sums, counts, floor_dn, so_far, first):  # pragma: no cover - compiled
    """Per 2x2 Bayer cell: True when none of its pixels reached ``floor_dn`` (dark-subtracted DN) in any usable
    frame of any exposure time (app.processing.kernels.hdr_store's slots: mean of the usable frames), AND-ed into
    ``so_far`` (a cell is under-exposed only if it is under every light; ``first``: initialise instead)."""
    H2, W2 = so_far.shape
    K = sums.shape[0]
    low = np.uint8(15)
    for i in prange(H2):
        for j in range(W2):
            best = np.float32(-1e30)
            for k in range(K):
                for di in range(2):
                    for dj in range(2):
                        nu = counts[k, 2 * i + di, 2 * j + dj] & low
                        if nu > 0:
                            v = sums[k, 2 * i + di, 2 * j + dj] / np.float32(nu)
                            if v > best:
                                best = v
            weak = best < floor_dn
            so_far[i, j] = weak if first else (so_far[i, j] and weak)


def encode_deliverables(stack: np.ndarray, matrix: np.ndarray, white_xyz: Sequence[float],
                        spaces: Sequence[str] = RGB_SPACES) -> EncodedImages:
    """All 16-bit deliverable arrays of a (H, W, N) float32 stack with the (N, 3) characterisation matrix."""
    from app.processing.outputs import xyz_to_rgb_matrix

    stack = np.ascontiguousarray(stack, dtype=np.float32)
    A = np.ascontiguousarray(matrix, dtype=np.float32)
    if stack.shape[-1] != A.shape[0]:
        raise ValueError(f"image has {stack.shape[-1]} channels, the matrix expects {A.shape[0]}")
    white_y = float(white_xyz[1])
    M = np.stack([xyz_to_rgb_matrix(s, white_xyz) / white_y for s in spaces]).astype(np.float32)
    luts = np.stack([encoding_table(s) for s in spaces])
    H, W, C = stack.shape
    xyz16 = np.empty((H, W, 3), np.uint16)
    rgb16 = np.empty((len(spaces), H, W, 3), np.uint16)
    ch16 = np.empty((H, W, C), np.uint16)
    bad, over = _encode(stack, A, M, luts, np.float32(LINEAR_ONE / white_y), xyz16, rgb16, ch16)
    n = max(H * W, 1)
    return EncodedImages(xyz16, {s: rgb16[i] for i, s in enumerate(spaces)}, ch16, bad / n, over / n)


def warm_up() -> None:
    """Compile (or load from the on-disk cache) the kernel on a tiny image."""
    encode_deliverables(np.zeros((2, 2, 6), np.float32), np.zeros((6, 3)), [95.047, 100.0, 108.883])
    weak_cells(np.zeros((1, 4, 4), np.float32), np.ones((1, 4, 4), np.uint8), np.float32(100.0),
               np.zeros((2, 2), np.bool_), True)
