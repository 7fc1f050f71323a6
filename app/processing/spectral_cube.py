"""The spectral deliverables of a stack, row band by row band: the estimated spectral cube (ENVI, BIL, 16-bit;
app.processing.envi) and the rendering under a chosen light (16-bit ProPhoto RGB; app.processing.render), both
from one pass over the stack.

Per pixel, the calibration's spectral estimator (simulation.spectral_estimation.SpectralEstimator: one linear
map of the N channels, its offset where it is affine, and a clip to the physical range) gives the factor at every
wavelength; it is stored x the cube's scale factor, and the clipped spectrum is seen under the rendering light
(eq 4.2 weights) and encoded like the other RGB deliverables (app.processing.encode's tables).

Why hand-written: the cube of a 24 MP original is 6 M pixels x 38 wavelengths (465 MB at 16 bits). In numpy the
matrix product alone writes a 930 MB float32 temporary (in bands: one per band), then the clip, the scale, the
rounding, the cast and the transpose to band-interleaved-by-line each read and write it again. One numba pass per
row keeps the row's spectra in the cache: the row's channels as planes, then per wavelength one short loop over
the pixels (the map's N products, the clip, the rendering's three sums, the rounding) that LLVM vectorises, writing
the cube's row in its file order. Checked against :meth:`SpectralEstimator.apply` and :class:`Rendering` in the
tests (same values within the rounding).
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from numba import njit

from dualrgb.app.processing.encode import band_source, encoding_pairs, rgb_row, rgb_scratch, stack_or_shape
from dualrgb.app.processing.envi import IGNORE_VALUE, SCALE_FACTOR
from dualrgb.app.processing.render import Rendering

log = logging.getLogger(__name__)


@njit(nogil=True, cache=True)
def _planes(s, planes, valid):  # pragma: no cover - compiled
    """The row ``s`` (W * C, pixel-interleaved) as C planes (NaN -> 0); ``valid`` False where a channel is NaN.
    Returns the number of invalid pixels."""
    C, W = planes.shape
    for j in range(W):
        valid[j] = True
    for c in range(C):
        for j in range(W):
            v = s[j * C + c]
            nan = v != v
            planes[c, j] = np.float32(0.0) if nan else v
            valid[j] = valid[j] and not nan
    bad = 0
    for j in range(W):
        bad += 0 if valid[j] else 1
    return bad


@njit(nogil=True, cache=True)
def _cube_row(planes, valid, M, off, lo, hi, scale, ignore, wts, acc, x, y, z, cube, store):  # pragma: no cover
    """One row: per wavelength b the estimate off[b] + sum_c M[b, c] plane_c clipped to [lo, hi], stored x ``scale`` in
    ``cube[b]`` (``ignore`` where not ``valid``; nothing stored unless ``store``) and added into x, y, z with the
    rendering weights ``wts[b]``."""
    B, C = M.shape
    W = planes.shape[1]
    half = np.float32(0.5)
    zero = np.float32(0.0)
    for j in range(W):
        x[j] = zero
        y[j] = zero
        z[j] = zero
    for b in range(B):
        m0 = M[b, 0]
        ob = off[b]
        for j in range(W):
            acc[j] = ob + m0 * planes[0, j]
        for c in range(1, C):
            mc = M[b, c]
            for j in range(W):
                acc[j] += mc * planes[c, j]
        wx = wts[b, 0]
        wy = wts[b, 1]
        wz = wts[b, 2]
        for j in range(W):
            v = min(max(acc[j], lo), hi)
            acc[j] = v
            x[j] += wx * v
            y[j] += wy * v
            z[j] += wz * v
        if store:
            out = cube[b]
            for j in range(W):
                q = np.uint16(acc[j] * scale + half)
                out[j] = q if valid[j] else ignore
    for j in range(W):
        if not valid[j]:
            x[j] = zero
            y[j] = zero
            z[j] = zero


@njit(nogil=True, cache=True)
def _spectral_rows(stack, r0, M, off, lo, hi, scale, ignore, wts, m_rgb, lut, cube, rgb, a, b):  # pragma: no cover
    """Band rows ``a`` .. ``b`` (stack rows ``r0 + a`` ..) into ``cube`` (rows, B, W) uint16 and ``rgb`` (rows, W, 3)
    uint16, each when it has rows (a cube made on demand: none at delivery). Returns the invalid pixels."""
    W = stack.shape[1]
    C = stack.shape[2]
    planes = np.empty((C, W), np.float32)
    valid = np.empty(W, np.bool_)
    acc = np.empty(W, np.float32)
    x = np.empty(W, np.float32)
    y = np.empty(W, np.float32)
    z = np.empty(W, np.float32)
    rs = rgb_scratch(W)
    none = np.empty((M.shape[0], 0), np.uint16)
    store = cube.shape[0] > 0
    bad = 0
    for r in range(a, b):
        bad += _planes(stack[r0 + r].reshape(W * C), planes, valid)
        _cube_row(planes, valid, M, off, lo, hi, scale, ignore, wts, acc, x, y, z, cube[r] if store else none, store)
        if rgb.shape[0] > 0:
            rgb_row(x, y, z, m_rgb, lut, rs, rgb[r].reshape(W * 3))
    return bad


class SpectralEncoder:
    """The cube and the rendering of one (H, W, N) float32 stack, row band by row band (app.workflow.delivery.delivery
    streams each band while the next is encoded).

    ``matrix`` (n_wl, N), ``offset`` (n_wl,; None: none) and ``bounds``: the spectral estimator's map and clip;
    ``rendering``: the light and RGB space of the rendered image (None: the cube only)."""

    def __init__(self, stack: np.ndarray | tuple[int, int, int], matrix: np.ndarray, bounds: Sequence[float],
                 rendering: Rendering | None = None, *, offset: np.ndarray | None = None, scale: float = SCALE_FACTOR,
                 ignore: int = IGNORE_VALUE, threads: int | None = None):
        self.stack, self._shape = stack_or_shape(stack)
        M = np.ascontiguousarray(matrix, dtype=np.float32)
        if M.ndim != 2 or M.shape[1] != self._shape[2]:
            raise ValueError(f"image {self._shape} and spectral map {M.shape}: expected (H, W, N) and (n_wl, N)")
        lo, hi = (float(v) for v in bounds)
        if not (0.0 <= lo < hi and hi * scale + 0.5 < ignore):
            raise ValueError(f"spectral range {lo:g}..{hi:g} x scale {scale:g} does not fit below {ignore}")
        if rendering is not None and len(rendering.wavelengths) != M.shape[0]:
            raise ValueError(f"rendering on {len(rendering.wavelengths)} wavelengths, estimate on {M.shape[0]}")
        self.off = np.zeros(M.shape[0], np.float32) if offset is None else np.ascontiguousarray(offset, np.float32)
        if self.off.shape != (M.shape[0],):
            raise ValueError(f"spectral offset {self.off.shape} for a map of {M.shape[0]} wavelengths")
        self.M, self.lo, self.hi = M, np.float32(lo), np.float32(hi)
        self.scale, self.ignore = np.float32(scale), np.uint16(ignore)
        self.rendering = rendering
        self._wts = (np.zeros((M.shape[0], 3), np.float32) if rendering is None
                     else np.ascontiguousarray(rendering.weights, dtype=np.float32))
        self._m_rgb = (np.eye(3, dtype=np.float32) if rendering is None
                       else np.ascontiguousarray(rendering.rgb_matrix, dtype=np.float32))
        space = rendering.space if rendering is not None else "sRGB"
        self._lut = encoding_pairs(space)                       # values and steps (rgb_row)
        self.invalid = 0
        self.threads = max(1, threads or numba.get_num_threads())
        self.chunks_per_thread = 4
        self._executor: ThreadPoolExecutor | None = None

    @property
    def shape(self) -> tuple[int, int, int]:
        """(H, W, n_wl): the cube's lines, samples and bands."""
        return self._shape[0], self._shape[1], self.M.shape[0]

    def encode(self, r0: int, cube: np.ndarray | None, rgb: np.ndarray | None = None, *,
               band: np.ndarray | None = None) -> None:
        """Rows ``r0`` .. into ``cube`` (rows, n_wl, W) uint16 (band-interleaved by line; None: the cube is not
        kept, only rendered) and ``rgb`` (rows, W, 3) uint16 (needed when there is a rendering), each C-contiguous;
        from ``band`` (those rows, (rows, W, N) float32) when the encoder has no stack."""
        first = cube if cube is not None else rgb
        if first is None:
            raise ValueError("neither a cube nor a rendering band to encode")
        rows = first.shape[0]
        H, W, B = self.shape
        if (r0 < 0 or r0 + rows > H or (cube is not None and cube.shape != (rows, B, W))
                or (rgb is None) != (self.rendering is None) or (rgb is not None and rgb.shape != (rows, W, 3))):
            raise ValueError(f"rows {r0}..{r0 + rows} of {H}, cube band {None if cube is None else cube.shape}, "
                             f"rendering band {None if rgb is None else rgb.shape}")
        out_cube = cube if cube is not None else np.empty((0, B, W), np.uint16)
        out_rgb = rgb if rgb is not None else np.empty((0, W, 3), np.uint16)
        src, off = band_source(self.stack, r0, rows, band, W, self._shape[2])
        args = (src, r0 + off, self.M, self.off, self.lo, self.hi, self.scale, self.ignore, self._wts, self._m_rgb,
                self._lut, out_cube, out_rgb)
        cuts = np.linspace(0, rows, min(self.threads * self.chunks_per_thread, max(rows, 1)) + 1).astype(int)
        if len(cuts) <= 2:
            counts = [_spectral_rows(*args, 0, rows)]
        else:
            counts = list(self._pool().map(lambda k: _spectral_rows(*args, cuts[k], cuts[k + 1]),
                                           range(len(cuts) - 1)))
        self.invalid += sum(int(c) for c in counts)

    def _pool(self) -> ThreadPoolExecutor:
        if self._executor is None:
            self._executor = ThreadPoolExecutor(self.threads, thread_name_prefix="spectral")
        return self._executor

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown()
            self._executor = None

    def __enter__(self) -> SpectralEncoder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def encode_spectral(stack: np.ndarray, matrix: np.ndarray, bounds: Sequence[float],
                    rendering: Rendering | None = None, offset: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray | None]:
    """The whole cube (H, n_wl, W) and rendering (H, W, 3) in memory (delivery streams them instead)."""
    with SpectralEncoder(stack, matrix, bounds, rendering, offset=offset) as enc:
        H, W, B = enc.shape
        cube = np.empty((H, B, W), np.uint16)
        rgb = np.empty((H, W, 3), np.uint16) if rendering is not None else None
        enc.encode(0, cube, rgb)
    return cube, rgb


def warm_up() -> None:
    """Compile (or load from the on-disk cache) the kernels on a tiny stack."""
    from dualrgb.app.processing.render import rendering

    wl = np.arange(410.0, 790.0, 10.0)
    for n in (6, 3):
        encode_spectral(np.zeros((2, 2, n), np.float32), np.zeros((len(wl), n)), (0.0, 1.0), rendering("D65", wl))
