"""The delivery encodings of an N-channel stack in one pass, row band by row band: XYZ, sRGB and ProPhoto RGB
(16-bit, display-encoded) and the N channels themselves (16-bit), plus the QA counts.

Why hand-written: the deliverables of a 24 MP original are four 16-bit images (~360 MB) computed from a 12 MP
x 6 float32 stack. In numpy each step (matrix, adaptation, clip, the piecewise power of the colour space's
encoding, rounding, casting) is a separate pass with temporaries, and colour-science's encoding functions alone
took longer than decoding the raw files (bench/digitise_bench.py). One numba pass reads the stack once and writes
each output once, a row at a time in short loops over the pixels that vectorise (0.15 CPU-s for 24 MP where a
loop per pixel took 0.5 s; same bits), into row bands that app.workflow.delivery streams to the files while
the next band is encoded (:class:`DeliveryEncoder`). The non-linear encodings come from 65 536-entry tables of
colour-science's own ``cctf_encoding`` with linear interpolation (error < 0.01 of a 16-bit code; checked in the
tests against colour-science), so the colour maths stays colour-science's.

Scales. RGB: a perfect white (the reference white's XYZ) encodes to 65535 in every channel, values outside
[0, 1] are clipped. XYZ and the N channels are linear with ``LINEAR_ONE`` (32768) for 1.0: XYZ relative to the
reference white's Y (Y = 100 -> 32768), channels as flat-fielded (1.0 = the white / open gate), so both keep a
2x headroom above white. NaN (no usable flat field) becomes 0.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import lru_cache

import numba
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


@njit(nogil=True, cache=True)
def _channels_row(s, out):  # pragma: no cover - compiled
    """The N channels of one row, flattened (W * N): 16-bit, LINEAR_ONE = 1.0, NaN -> 0 (vectorises)."""
    zero = np.float32(0.0)
    half = np.float32(0.5)
    for t in range(s.shape[0]):
        v = s[t]
        v = zero if v != v else v
        q = v * np.float32(LINEAR_ONE) + half
        out[t] = 0 if q <= half else (65535 if q >= 65535.0 else np.uint16(q))


@njit(nogil=True, cache=True)
def _xyz_row(s, A, x, y, z):  # pragma: no cover - compiled
    """x, y, z of one row (``s`` flattened W * N; ``A`` the matrix as a tuple of N (X, Y, Z) rows, so that N is a
    compile-time constant and the pixel loop vectorises); returns the pixels with a NaN channel (taken as 0)."""
    C = len(A)
    zero = np.float32(0.0)
    bad = 0
    for j in range(x.shape[0]):
        xa = zero
        ya = zero
        za = zero
        nan = False
        for c in range(C):
            v = s[j * C + c]
            isnan = v != v
            v = zero if isnan else v
            nan |= isnan
            xa += v * A[c][0]
            ya += v * A[c][1]
            za += v * A[c][2]
        x[j] = xa
        y[j] = ya
        z[j] = za
        bad += nan
    return bad


@njit(nogil=True, cache=True)
def _xyz16_row(x, y, z, scale, out):  # pragma: no cover - compiled
    """The linear 16-bit XYZ of one row into ``out`` (W * 3); returns the pixels whose Y code clips at 65535."""
    half = np.float32(0.5)
    over = 0
    for j in range(x.shape[0]):
        q = x[j] * scale + half
        out[3 * j] = 0 if q <= half else (65535 if q >= 65535.0 else np.uint16(q))
        q = y[j] * scale + half
        over += 1 if q >= 65535.0 else 0
        out[3 * j + 1] = 0 if q <= half else (65535 if q >= 65535.0 else np.uint16(q))
        q = z[j] * scale + half
        out[3 * j + 2] = 0 if q <= half else (65535 if q >= 65535.0 else np.uint16(q))
    return over


@njit(nogil=True, cache=True)
def rgb_row(x, y, z, m, lut, lin, idx, out):  # pragma: no cover - compiled
    """One display-encoded RGB space of one row into ``out`` (W * 3): linear RGB = ``m`` (3, 3) @ XYZ, clipped
    to [0, 1], through ``lut`` with linear interpolation (``lin``, ``idx``: scratch rows)."""
    zero = np.float32(0.0)
    half = np.float32(0.5)
    last = lut.shape[0] - 1
    for k in range(3):
        m0 = m[k, 0]
        m1 = m[k, 1]
        m2 = m[k, 2]
        for j in range(x.shape[0]):                      # vectorises: the gathers are in the next loop
            v = m0 * x[j] + m1 * y[j] + m2 * z[j]
            v = min(max(v, zero), np.float32(1.0)) * last
            lin[j] = v
            idx[j] = min(int(v), last - 1)
        for j in range(x.shape[0]):
            i0 = idx[j]
            f = lin[j] - i0
            e = lut[i0] + f * (lut[i0 + 1] - lut[i0])
            out[3 * j + k] = np.uint16(e + half)


@njit(nogil=True, cache=True)
def _encode_rows(stack, r0, A, M, luts, scale_xyz, xyz16, rgb16, ch16, lo, hi):  # pragma: no cover - compiled
    """Band rows ``lo`` .. ``hi`` (stack rows ``r0 + lo`` ..) into the row band ``xyz16`` (rows, W, 3), the tuple
    ``rgb16`` of (rows, W, 3) arrays (one per space of ``M`` / ``luts``) and ``ch16`` (rows, W, N). Row by row
    in short loops over the pixels that LLVM vectorises (one loop per pixel with inner loops over runtime counts
    did not: 3x slower). Not ``parallel``: numba's parfors cannot take the tuples; DeliveryEncoder runs bands in
    threads (nogil). Returns (pixels with NaN, pixels whose Y clips)."""
    W = stack.shape[1]
    C = stack.shape[2]
    x = np.empty(W, np.float32)
    y = np.empty(W, np.float32)
    z = np.empty(W, np.float32)
    lin = np.empty(W, np.float64)
    idx = np.empty(W, np.int64)
    bad = 0
    over = 0
    for r in range(lo, hi):
        s = stack[r0 + r].reshape(W * C)
        _channels_row(s, ch16[r].reshape(W * C))
        bad += _xyz_row(s, A, x, y, z)
        over += _xyz16_row(x, y, z, scale_xyz, xyz16[r].reshape(W * 3))
        for q in range(len(rgb16)):
            rgb_row(x, y, z, M[q], luts[q], lin, idx, rgb16[q][r].reshape(W * 3))
    return bad, over


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


class DeliveryEncoder:
    """The delivery encodings of one (H, W, N) float32 stack with the (N, 3) characterisation matrix, row band by
    row band (app.workflow.delivery streams each band to the files while the next one is encoded); the QA
    counts add up over the bands."""

    def __init__(self, stack: np.ndarray, matrix: np.ndarray, white_xyz: Sequence[float],
                 spaces: Sequence[str] = RGB_SPACES, threads: int | None = None):
        from dualrgb.app.processing.outputs import xyz_to_rgb_matrix

        self.stack = np.ascontiguousarray(stack, dtype=np.float32)
        A = np.asarray(matrix, dtype=np.float32)
        if self.stack.ndim != 3 or A.ndim != 2 or A.shape[1] != 3 or self.stack.shape[-1] != A.shape[0]:
            raise ValueError(f"image {self.stack.shape} and matrix {A.shape}: expected (H, W, N) and (N, 3)")
        self.spaces = tuple(spaces)
        white_y = float(white_xyz[1])
        self._A = tuple(tuple(np.float32(v) for v in row) for row in A)     # N: a compile-time constant
        self._M = np.stack([xyz_to_rgb_matrix(s, white_xyz) / white_y for s in self.spaces]).astype(np.float32)
        self._luts = np.stack([encoding_table(s) for s in self.spaces])
        self._scale = np.float32(LINEAR_ONE / white_y)
        self.invalid = 0
        self.over_white = 0
        self.lit = False                # any encoded XYZ above 0 (an all-zero delivery is refused: app.workflow)
        self.threads = max(1, threads or numba.get_num_threads())
        self.chunks_per_thread = 4      # smaller pieces balance the threads when other processes take a core
        self._executor: ThreadPoolExecutor | None = None

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.stack.shape

    def encode(self, r0: int, xyz16: np.ndarray, rgb16: Sequence[np.ndarray], ch16: np.ndarray) -> None:
        """Rows ``r0`` .. ``r0 + len(xyz16)`` into the uint16 bands ``xyz16`` (rows, W, 3), ``rgb16`` (one
        (rows, W, 3) per space, in ``spaces`` order) and ``ch16`` (rows, W, N), each C-contiguous."""
        rows = xyz16.shape[0]
        if r0 < 0 or r0 + rows > self.shape[0] or len(rgb16) != len(self.spaces):
            raise ValueError(f"rows {r0}..{r0 + rows} of {self.shape[0]}, {len(rgb16)} RGB bands")
        args = (self.stack, r0, self._A, self._M, self._luts, self._scale, xyz16, tuple(rgb16), ch16)
        cuts = np.linspace(0, rows, min(self.threads * self.chunks_per_thread, max(rows, 1)) + 1).astype(int)
        if len(cuts) <= 2:
            counts = [_encode_rows(*args, 0, rows)]
        else:
            counts = list(self._pool().map(lambda k: _encode_rows(*args, cuts[k], cuts[k + 1]), range(len(cuts) - 1)))
        self.invalid += sum(int(b) for b, _ in counts)
        self.over_white += sum(int(o) for _, o in counts)
        self.lit = self.lit or bool(xyz16.any())

    def _pool(self) -> ThreadPoolExecutor:
        if self._executor is None:
            self._executor = ThreadPoolExecutor(self.threads, thread_name_prefix="encode")
        return self._executor

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown()
            self._executor = None

    def __enter__(self) -> DeliveryEncoder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def invalid_fraction(self) -> float:
        return self.invalid / max(self.shape[0] * self.shape[1], 1)

    @property
    def over_white_fraction(self) -> float:
        return self.over_white / max(self.shape[0] * self.shape[1], 1)


def encode_deliverables(stack: np.ndarray, matrix: np.ndarray, white_xyz: Sequence[float],
                        spaces: Sequence[str] = RGB_SPACES) -> EncodedImages:
    """All 16-bit deliverable arrays of a (H, W, N) float32 stack with the (N, 3) characterisation matrix, in
    memory (delivery streams them instead: :class:`DeliveryEncoder`)."""
    with DeliveryEncoder(stack, matrix, white_xyz, spaces) as enc:
        H, W, C = enc.shape
        xyz16 = np.empty((H, W, 3), np.uint16)
        rgb16 = np.empty((len(enc.spaces), H, W, 3), np.uint16)
        ch16 = np.empty((H, W, C), np.uint16)
        enc.encode(0, xyz16, list(rgb16), ch16)
    return EncodedImages(xyz16, {s: rgb16[i] for i, s in enumerate(enc.spaces)}, ch16, enc.invalid_fraction,
                         enc.over_white_fraction)


def warm_up() -> None:
    """Compile (or load from the on-disk cache) the kernels on a tiny image (6 channels: dual-RGB; 3: one light)."""
    for n in (6, 3):
        encode_deliverables(np.zeros((2, 2, n), np.float32), np.zeros((n, 3)), [95.047, 100.0, 108.883])
    weak_cells(np.zeros((1, 4, 4), np.float32), np.ones((1, 4, 4), np.uint8), np.float32(100.0),
               np.zeros((2, 2), np.bool_), True)
