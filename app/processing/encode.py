"""The delivery encodings of an N-channel stack in one pass, row band by row band: XYZ, sRGB and ProPhoto RGB
(16-bit, display-encoded) and the N channels themselves (16-bit), plus the QA counts.

Why hand-written: the deliverables of a 24 MP original are four 16-bit images (~360 MB) computed from a 12 MP
x 6 float32 stack. In numpy each step (matrix, adaptation, clip, the piecewise power of the colour space's
encoding, rounding, casting) is a separate pass with temporaries, and colour-science's encoding functions alone
took longer than decoding the raw files (bench/digitise_bench.py). One numba pass reads the stack once and writes
each output once, a row at a time in short loops over the pixels that vectorise (0.15 CPU-s for 24 MP where a
loop per pixel took 0.5 s; same bits), into row bands that app.workflow.delivery.delivery streams to the files while
the next band is encoded (:class:`DeliveryEncoder`). A full-resolution original's rows are demosaiced in the same
pass (:meth:`DeliveryEncoder.encode_mosaic`): each row's channel planes are made and encoded while in the cache,
so no N-channel float band is written and read (24 MP: the demosaic and encodings 0.51 CPU-s, against 0.23 +
0.67 as two passes; docs/notes/issue-31.md). The non-linear encodings come from 65 536-entry tables of
colour-science's own ``cctf_encoding`` with linear interpolation (error < 0.01 of a 16-bit code; checked in the
tests against colour-science), so the colour maths stays colour-science's.

Scales. RGB: a perfect white (the reference white's XYZ) encodes to 65535 in every channel, values outside
[0, 1] are clipped. XYZ is X / Xn, Y / Yn, Z / Zn (the reference white's Xn, Yn, Zn; CIELAB's normalisation)
with ``XYZ_ONE`` (65535) for 1.0, so its ICC profile is one LittleCMS keeps exact (app.processing.outputs.xyz_icc
says why); values above the white clip, as in the RGB masters. The N channels are linear with ``LINEAR_ONE``
(32768) for 1.0, as flat-fielded (1.0 = the white / open gate): a 2x headroom above white, so the camera-RGB
masters keep what the others clip. NaN (no usable flat field) becomes 0.
"""
from __future__ import annotations

import logging
import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import lru_cache

import numba
import numpy as np
from numba import njit, prange

from dualrgb.app.processing.colour_kernels import expansion_scratch, root_polynomial_xyz_row, terms_for
from dualrgb.app.processing.demosaic import HALO, mhc_planes, row_colours

log = logging.getLogger(__name__)

LINEAR_ONE = 32768.0          # 16-bit code of 1.0 in the linear channel images (2x headroom)
XYZ_ONE = 65535.0             # 16-bit code of X / Xn = Y / Yn = Z / Zn = 1 in the XYZ image
LUT_SIZE = 65536
RGB_SPACES = ("sRGB", "ProPhoto RGB")


@lru_cache(maxsize=4)
def encoding_table(space: str) -> np.ndarray:
    """(LUT_SIZE,) float32: colour-science's ``cctf_encoding`` of the space at LUT_SIZE points of [0, 1], x 65535."""
    import colour

    x = np.linspace(0.0, 1.0, LUT_SIZE)
    enc = np.asarray(colour.RGB_COLOURSPACES[space].cctf_encoding(x), dtype=np.float64)
    return (np.clip(enc, 0.0, 1.0) * 65535.0).astype(np.float32)


@lru_cache(maxsize=4)
def encoding_slopes(space: str) -> np.ndarray:
    """(LUT_SIZE,) float32: the steps ``lut[i + 1] - lut[i]`` of :func:`encoding_table` (0 after the last), exact
    in float32 (neighbouring entries are within a factor 2 of each other: Sterbenz), so the kernels' float64
    interpolation gives the same value as from the two entries."""
    lut = encoding_table(space)
    steps = lut[1:].astype(np.float64) - lut[:-1]
    out = np.append(steps.astype(np.float32), np.float32(0.0))
    if not np.array_equal(out[:-1].astype(np.float64), steps):       # a guard: holds for every space's curve
        raise ValueError(f"{space}: the encoding table's steps are not exact in float32")
    return out


def xyz_from_codes(codes: np.ndarray, white_xyz: Sequence[float]) -> np.ndarray:
    """The XYZ (on the reference white's scale) of the XYZ master's 16-bit codes."""
    return np.asarray(codes, dtype=np.float64) / XYZ_ONE * np.asarray(white_xyz, dtype=np.float64)


@dataclass
class EncodedImages:
    """The 16-bit deliverable arrays of one original and what the QA line needs."""

    xyz: np.ndarray               # (H, W, 3) uint16, linear, X / Xn, Y / Yn, Z / Zn, XYZ_ONE = 1
    rgb: dict[str, np.ndarray]    # space -> (H, W, 3) uint16 display-encoded
    channels: np.ndarray          # (H, W, N) uint16, linear, LINEAR_ONE = 1.0
    invalid_fraction: float       # pixels with NaN (no usable flat field)
    over_white_fraction: float    # pixels whose Y reaches the white's or more (clipped in the XYZ image)


@njit(nogil=True, cache=True, error_model="numpy")
def _channels_row(S, c0, out):  # pragma: no cover - compiled
    """Planes ``c0`` .. ``c0 + 2`` of one row (``S`` (N, W): one plane per channel) into ``out`` (W * 3): one
    light's camera RGB, 16-bit, LINEAR_ONE = 1.0, NaN -> 0 (three statements per pixel, which vectorise)."""
    zero = np.float32(0.0)
    half = np.float32(0.5)
    one = np.float32(LINEAR_ONE)
    p0 = S[c0]
    p1 = S[c0 + 1]
    p2 = S[c0 + 2]
    for j in range(out.shape[0] // 3):
        v = p0[j]
        q = (zero if v != v else v) * one + half
        out[3 * j] = 0 if q <= half else (65535 if q >= 65535.0 else np.uint16(q))
        v = p1[j]
        q = (zero if v != v else v) * one + half
        out[3 * j + 1] = 0 if q <= half else (65535 if q >= 65535.0 else np.uint16(q))
        v = p2[j]
        q = (zero if v != v else v) * one + half
        out[3 * j + 2] = 0 if q <= half else (65535 if q >= 65535.0 else np.uint16(q))


@njit(nogil=True, cache=True, error_model="numpy")
def _xyz_row(S, A, x, y, z):  # pragma: no cover - compiled
    """x, y, z of one row (``S`` (N, W): one plane per channel; ``A`` the matrix as a tuple of N (X, Y, Z) rows,
    so that N is a compile-time constant and the pixel loop vectorises); returns the pixels with a NaN channel
    (taken as 0)."""
    C = len(A)
    zero = np.float32(0.0)
    bad = 0
    for j in range(x.shape[0]):
        xa = zero
        ya = zero
        za = zero
        nan = False
        for c in range(C):
            v = S[c, j]
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


@njit(nogil=True, cache=True, error_model="numpy")
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


@lru_cache(maxsize=4)
def encoding_pairs(space: str) -> np.ndarray:
    """(LUT_SIZE,) uint64: entry i holds the float32 pair (:func:`encoding_table` [i], :func:`encoding_slopes` [i])
    in memory order, so :func:`rgb_row` fetches both with one load."""
    pairs = np.empty((LUT_SIZE, 2), np.float32)
    pairs[:, 0] = encoding_table(space)
    pairs[:, 1] = encoding_slopes(space)
    return pairs.view(np.uint64).reshape(LUT_SIZE)


@njit(nogil=True, cache=True)
def rgb_scratch(W):  # pragma: no cover - compiled
    """:func:`rgb_row`'s scratch rows: lin (W,) float64, idx (W,) int64, the fetched pairs (W,) uint64, the codes
    (3, W) uint16."""
    return np.empty(W, np.float64), np.empty(W, np.int64), np.empty(W, np.uint64), np.empty((3, W), np.uint16)


@njit(nogil=True, cache=True, error_model="numpy")
def rgb_row(x, y, z, m, pairs, rs, out):  # pragma: no cover - compiled
    """One display-encoded RGB space of one row into ``out`` (W * 3): linear RGB = ``m`` (3, 3) @ XYZ, clipped
    to [0, 1], through the table with linear interpolation: ``pairs`` (:func:`encoding_pairs`: each entry's value
    and its exact step to the next, one gather less per value than ``lut[i + 1] - lut[i]``), ``rs``:
    :func:`rgb_scratch`. Four loops per channel, so that all but the one that fetches the table's pairs (one 8-byte
    load per value) vectorise: 1.6x faster than fetching and interpolating in one loop (which stayed scalar),
    the same arithmetic in float64, the same bits."""
    lin, idx, got, codes = rs
    both = got.view(np.float32)                         # (2 W,): value, step of each fetched pair
    zero = np.float32(0.0)
    half = np.float32(0.5)
    last = pairs.shape[0] - 1
    W = x.shape[0]
    for k in range(3):
        m0 = m[k, 0]
        m1 = m[k, 1]
        m2 = m[k, 2]
        for j in range(W):
            v = m0 * x[j] + m1 * y[j] + m2 * z[j]
            v = min(max(v, zero), np.float32(1.0)) * last
            lin[j] = v
            idx[j] = min(int(v), last - 1)
        for j in range(W):
            got[j] = pairs[idx[j]]
        ck = codes[k]
        for j in range(W):
            e = both[2 * j] + (lin[j] - idx[j]) * both[2 * j + 1]
            ck[j] = np.uint16(e + half)
    for j in range(W):
        out[3 * j] = codes[0, j]
        out[3 * j + 1] = codes[1, j]
        out[3 * j + 2] = codes[2, j]


@njit(nogil=True, cache=True, error_model="numpy")
def _encode_planes(S, A, rp, ex, M, luts, scale_xyz, r, xyz16, rgb16, ch16, x, y, z, rs):  # pragma: no cover
    """Row ``r`` of the output bands from the row's channel planes ``S`` (N, W) (x, y, z, rs: scratch rows); the
    model: the linear matrix ``A`` (a tuple of N rows), or, when ``rp`` = (terms (T, 3), matrix (T, 3) float32)
    has terms, that root-polynomial (app.processing.colour_kernels, in ``ex``: its scratch rows); ``luts``: one
    :func:`encoding_pairs` table per space of ``M``; returns (pixels with NaN, pixels whose Y clips)."""
    W = S.shape[1]
    for q in range(len(ch16)):
        _channels_row(S, 3 * q, ch16[q][r].reshape(W * 3))
    if rp[0].shape[0] == 0:
        bad = _xyz_row(S, A, x, y, z)
    else:
        bad = root_polynomial_xyz_row(S, rp[0], rp[1], ex, x, y, z)
    over = _xyz16_row(x, y, z, scale_xyz, xyz16[r].reshape(W * 3))
    for q in range(len(rgb16)):
        rgb_row(x, y, z, M[q], luts[q], rs, rgb16[q][r].reshape(W * 3))
    return bad, over


@njit(nogil=True, cache=True)
def _row_scratch(C, W):  # pragma: no cover - compiled
    """The encoders' rows: the channel planes (C, W), x, y, z, and rgb_row's (:func:`rgb_scratch`)."""
    return (np.empty((C, W), np.float32), np.empty(W, np.float32), np.empty(W, np.float32), np.empty(W, np.float32),
            rgb_scratch(W))


@njit(nogil=True, cache=True, error_model="numpy")
def _encode_rows(stack, r0, A, rp, M, luts, scale_xyz, xyz16, rgb16, ch16, lo, hi):  # pragma: no cover
    """Band rows ``lo`` .. ``hi`` (stack rows ``r0 + lo`` ..) into the row band ``xyz16`` (rows, W, 3), the tuple
    ``rgb16`` of (rows, W, 3) arrays (one per space of ``M`` / ``luts``) and the tuple ``ch16`` of (rows, W, 3)
    arrays (one per light: channels 3 l .. 3 l + 2). Row by row: the row's channels into planes, then short loops
    over the pixels that LLVM vectorises (one loop per pixel with inner loops over runtime counts did not: 3x
    slower; reading the pixel-interleaved channels in those loops did not either). Not ``parallel``: numba's
    parfors cannot take the tuples; DeliveryEncoder runs bands in threads (nogil). Returns (pixels with NaN,
    pixels whose Y clips)."""
    W = stack.shape[1]
    C = stack.shape[2]
    S, x, y, z, rs = _row_scratch(C, W)
    ex = expansion_scratch(rp[0], C, W)
    bad = 0
    over = 0
    for r in range(lo, hi):
        s = stack[r0 + r]
        for j in range(W):
            for c in range(C):
                S[c, j] = s[j, c]
        b, o = _encode_planes(S, A, rp, ex, M, luts, scale_xyz, r, xyz16, rgb16, ch16, x, y, z, rs)
        bad += b
        over += o
    return bad, over


@njit(nogil=True, cache=True, error_model="numpy")
def _encode_mosaic_rows(P, p0, y0, cfa, A, rp, M, luts, scale_xyz, xyz16, rgb16, ch16, lo, hi):  # pragma: no cover
    """:func:`_encode_rows` fused with the demosaic: band rows ``lo`` .. ``hi`` (image rows ``y0 + lo`` ..) from
    ``P`` (L, rows + 2 HALO, W + 2 HALO), each light's flat-fielded mosaic band with HALO mirrored rows and
    columns around (app.processing.masters), whose row ``p0 + r`` holds band row r; ``cfa`` (2, 2) channel
    indices of the image's top-left cell. Each row is demosaiced into the planes the encodings read (in cache),
    so no N-channel float band is written or read: the same arithmetic, the same bits."""
    L = P.shape[0]
    S, x, y, z, rs = _row_scratch(3 * L, P.shape[2] - 2 * HALO)
    ex = expansion_scratch(rp[0], 3 * L, P.shape[2] - 2 * HALO)
    bad = 0
    over = 0
    for r in range(lo, hi):
        even_green, here = row_colours(cfa, y0 + r)
        for li in range(L):
            mhc_planes(P[li], p0 + r, even_green, here, S[3 * li: 3 * li + 3])
        b, o = _encode_planes(S, A, rp, ex, M, luts, scale_xyz, r, xyz16, rgb16, ch16, x, y, z, rs)
        bad += b
        over += o
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


def stack_or_shape(stack: np.ndarray | tuple[int, int, int]) -> tuple[np.ndarray | None, tuple[int, int, int]]:
    """An encoder's image: a whole (H, W, N) float32 stack (contiguous), or only its shape when the bands come
    with each ``encode`` call (a full-resolution original: app.processing.masters)."""
    if isinstance(stack, tuple):
        if len(stack) != 3:
            raise ValueError(f"image shape {stack}: expected (H, W, N)")
        return None, (int(stack[0]), int(stack[1]), int(stack[2]))
    arr = np.ascontiguousarray(stack, dtype=np.float32)
    if arr.ndim != 3:
        raise ValueError(f"image {arr.shape}: expected (H, W, N)")
    return arr, (int(arr.shape[0]), int(arr.shape[1]), int(arr.shape[2]))


def band_source(stack: np.ndarray | None, r0: int, rows: int, band: np.ndarray | None, width: int,
                channels: int) -> tuple[np.ndarray, int]:
    """(array, its row offset) that an encoder's kernels read rows ``r0`` .. from: the whole stack, or the
    (rows, W, N) ``band`` given with the call (offset -r0: its first row is row r0)."""
    if band is None:
        if stack is None:
            raise ValueError("an encoder made from a shape needs the band with each call")
        return stack, 0
    if band.shape != (rows, width, channels) or band.dtype != np.float32 or not band.flags.c_contiguous:
        raise ValueError(f"band {band.shape} {band.dtype}: expected a contiguous ({rows}, {width}, {channels}) "
                         "float32 band")
    return band, -r0


class DeliveryEncoder:
    """The delivery encodings of one (H, W, N) float32 image with the characterisation model, row band by row
    band (app.workflow.delivery.delivery streams each band to the files while the next one is encoded); the QA counts
    add
    up over the bands. ``stack``: the whole image, or its (H, W, N) shape when each ``encode`` call brings its
    band. ``matrix``: (N, 3) for a linear model (``degree`` 1), (T, 3) for the T root-polynomial terms of
    ``degree`` 2 or 3 (simulation.colour_models), applied to every pixel."""

    def __init__(self, stack: np.ndarray | tuple[int, int, int], matrix: np.ndarray, white_xyz: Sequence[float],
                 spaces: Sequence[str] = RGB_SPACES, threads: int | None = None, degree: int = 1):
        from dualrgb.app.processing.outputs import xyz_to_rgb_matrix

        self.stack, self._shape = stack_or_shape(stack)
        A = np.asarray(matrix, dtype=np.float32)
        N = self._shape[2]
        terms = terms_for(N, degree) if N else terms_for(1, 1)
        rows = len(terms) or N
        if A.ndim != 2 or A.shape[1] != 3 or rows != A.shape[0] or N % 3:
            raise ValueError(f"image {self._shape} and matrix {A.shape} of degree {degree}: expected (H, W, N) and "
                             f"({rows}, 3), N = 3 per light")
        # a root-polynomial goes in as arrays (rp), the linear matrix as a tuple of N rows: the kernels' types are the
        # same for every model of N channels (one compile), the linear pixel loop keeps N a compile-time constant
        white = np.asarray(white_xyz, dtype=np.float64)
        # (the root-polynomial's columns divided by the white too: the kernels' x, y, z are X / Xn, Y / Yn, Z / Zn)
        self._rp = (terms, np.ascontiguousarray((A / white).astype(np.float32) if len(terms)
                                                else np.zeros((0, 3), np.float32)))
        A = A if not len(terms) else np.zeros((N, 3), np.float32)
        self.spaces = tuple(spaces)
        # the kernels' x, y, z are X / Xn, Y / Yn, Z / Zn: the matrix's columns divided by the white, and the RGB
        # matrices (of XYZ / Yn) multiplied by it, so the RGB values are the same
        self._A = tuple(tuple(np.float32(v) for v in row)                           # N: a compile-time constant
                        for row in np.asarray(matrix, dtype=np.float64) / white)
        self._M = np.stack([xyz_to_rgb_matrix(s, white_xyz) * (white / white[1]) for s in self.spaces]
                           ).astype(np.float32)
        self._luts = np.stack([encoding_pairs(s) for s in self.spaces])
        self._scale = np.float32(XYZ_ONE)
        self.invalid = 0
        self.over_white = 0
        self.lit = False                # any encoded XYZ above 0 (an all-zero delivery is refused: app.workflow)
        self.threads = max(1, threads or numba.get_num_threads())
        self.chunks_per_thread = 4      # smaller pieces balance the threads when other processes take a core
        self._executor: ThreadPoolExecutor | None = None
        self._lock = threading.Lock()   # the QA counts, when several threads encode bands at once

    @property
    def shape(self) -> tuple[int, int, int]:
        return self._shape

    def encode(self, r0: int, xyz16: np.ndarray, rgb16: Sequence[np.ndarray], ch16: Sequence[np.ndarray], *,
               band: np.ndarray | None = None) -> None:
        """Rows ``r0`` .. ``r0 + len(xyz16)`` into the uint16 bands ``xyz16`` (rows, W, 3), ``rgb16`` (one
        (rows, W, 3) per space, in ``spaces`` order) and ``ch16`` (one (rows, W, 3) per light: its camera RGB),
        each C-contiguous; from ``band`` (those rows, (rows, W, N) float32) when the encoder has no stack."""
        rows = xyz16.shape[0]
        H, W, N = self._check(r0, rows, rgb16, ch16)
        src, off = band_source(self.stack, r0, rows, band, W, N)
        self._run(_encode_rows, (src, r0 + off, self._A, self._rp, self._M, self._luts, self._scale, xyz16,
                                 tuple(rgb16), tuple(ch16)), rows)
        self.lit = self.lit or bool(xyz16.any())

    def encode_mosaic(self, r0: int, xyz16: np.ndarray, rgb16: Sequence[np.ndarray], ch16: Sequence[np.ndarray], *,
                      mosaic: np.ndarray, p0: int, cfa: np.ndarray, in_thread: bool = False) -> None:
        """:meth:`encode` of rows ``r0`` .. demosaiced on the fly (Malvar-He-Cutler, app.processing.demosaic)
        from ``mosaic`` (L, rows + 2 HALO, W + 2 HALO) float32: each light's flat-fielded mosaic band, its row
        ``p0 + r`` image row ``r0 + r``, HALO mirrored rows and columns around (app.processing.masters.MasterStack
        .mosaic_band); ``cfa`` (2, 2) channel indices of the image's top-left cell. The same values as
        :meth:`encode` of the demosaiced band, without writing and reading it. ``in_thread``: the whole band in
        the calling thread (several threads may then encode bands at once: app.processing.band_pipeline)."""
        rows = xyz16.shape[0]
        H, W, N = self._check(r0, rows, rgb16, ch16)
        if (mosaic.dtype != np.float32 or mosaic.ndim != 3 or mosaic.shape[0] * 3 != N
                or mosaic.shape[2] != W + 2 * HALO or not 0 <= p0 - HALO <= mosaic.shape[1] - rows - 2 * HALO):
            raise ValueError(f"mosaic band {mosaic.shape} {mosaic.dtype}, pixel rows from {p0}: expected "
                             f"({N // 3}, >= {rows + 2 * HALO}, {W + 2 * HALO}) float32")
        self._run(_encode_mosaic_rows, (mosaic, p0, r0, cfa, self._A, self._rp, self._M, self._luts,
                                        self._scale, xyz16, tuple(rgb16), tuple(ch16)), rows, in_thread)
        if not self.lit and xyz16.any():
            self.lit = True

    def _check(self, r0: int, rows: int, rgb16: Sequence[np.ndarray], ch16: Sequence[np.ndarray]
               ) -> tuple[int, int, int]:
        H, W, N = self.shape
        if r0 < 0 or r0 + rows > H or len(rgb16) != len(self.spaces) or len(ch16) * 3 != N:
            raise ValueError(f"rows {r0}..{r0 + rows} of {H}, {len(rgb16)} RGB bands, {len(ch16)} channel bands")
        return H, W, N

    def _run(self, kernel, args: tuple, rows: int, in_thread: bool = False) -> None:
        """``kernel(*args, lo, hi)`` over the band's rows, in pieces on the threads (``in_thread``: all in the
        calling thread); adds up the QA counts."""
        cuts = np.linspace(0, rows, min(self.threads * self.chunks_per_thread, max(rows, 1)) + 1).astype(int)
        if len(cuts) <= 2 or in_thread:
            counts = [kernel(*args, 0, rows)]
        else:
            counts = list(self._pool().map(lambda k: kernel(*args, cuts[k], cuts[k + 1]), range(len(cuts) - 1)))
        with self._lock:
            self.invalid += sum(int(b) for b, _ in counts)
            self.over_white += sum(int(o) for _, o in counts)

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
                        spaces: Sequence[str] = RGB_SPACES, degree: int = 1) -> EncodedImages:
    """All 16-bit deliverable arrays of a (H, W, N) float32 stack with the characterisation model (``matrix`` of
    ``degree``: :class:`DeliveryEncoder`), in memory (delivery streams them instead)."""
    with DeliveryEncoder(stack, matrix, white_xyz, spaces, degree=degree) as enc:
        H, W, C = enc.shape
        xyz16 = np.empty((H, W, 3), np.uint16)
        rgb16 = np.empty((len(enc.spaces), H, W, 3), np.uint16)
        ch16 = np.empty((C // 3, H, W, 3), np.uint16)
        enc.encode(0, xyz16, list(rgb16), list(ch16))
    return EncodedImages(xyz16, {s: rgb16[i] for i, s in enumerate(enc.spaces)}, np.concatenate(list(ch16), axis=2),
                         enc.invalid_fraction, enc.over_white_fraction)


def warm_up() -> None:
    """Compile (or load from the on-disk cache) the kernels on a tiny image (6 channels: dual-RGB, linear and the
    root-polynomials of degree 2 and 3; 3: one light), the full-resolution one-pass encoding included."""
    from dualrgb.app.processing.mosaic import cfa_channel_index
    from dualrgb.simulation.colour_models import n_terms

    for n, degree in ((6, 1), (3, 1), (6, 3)):     # a root-polynomial: the same kernels, its own branch
        A = np.zeros((n_terms(n, degree), 3))
        encode_deliverables(np.zeros((2, 2, n), np.float32), A, [95.047, 100.0, 108.883], degree=degree)
        with DeliveryEncoder((2, 2, n), A, [95.047, 100.0, 108.883], threads=1, degree=degree) as enc:
            out = [np.empty((2, 2, 3), np.uint16) for _ in range(3 + n // 3)]        # XYZ, 2 RGB, per light
            enc.encode_mosaic(0, out[0], out[1:3], out[3:], mosaic=np.zeros((n // 3, 2 + 2 * HALO, 2 + 2 * HALO),
                              np.float32), p0=HALO, cfa=cfa_channel_index("RGGB"))
    weak_cells(np.zeros((1, 4, 4), np.float32), np.ones((1, 4, 4), np.uint8), np.float32(100.0),
               np.zeros((2, 2), np.bool_), True)
