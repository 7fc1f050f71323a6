"""Fused per-pixel kernels for the mosaic-size steps (numba, parallel over rows, cached on disk).

Why hand-written: each step is a handful of per-pixel operations over 24 M pixels. In numpy every operation is
a separate pass over memory with its own temporaries (the eq 8.9 weight alone is ~6 passes, the HDR update
~15), which made processing a 24 MP dual-RGB HDR set take ~2.5x the time of merely decoding its raw files
(bench/processing_bench.py). One fused pass per frame reads each input once and writes each accumulator once.
Semantics are identical to the numpy formulation documented in calibration.py and hdr.py (float32 arithmetic);
the tests check the results against known truth. The kernels release the GIL (nogil), so the next raw file
can be decoded in a background thread meanwhile (mosaic.iter_open_raw).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(parallel=True, cache=True, nogil=True)
def dark_accumulate_11(x, total, hi, lo, first):  # pragma: no cover - compiled
    """The common case (reject one high, one low): total += x, hi = max(hi, x), lo = min(lo, x); 2-D arrays
    (``first``: initialise instead, so no separate zero-fill pass). Written without the k loop of the
    general kernel, which keeps numba from vectorising (~8x slower)."""
    H, W = x.shape
    for i in prange(H):
        xr = x[i]
        tr = total[i]
        hr = hi[i]
        lr = lo[i]
        if first:
            for j in range(W):
                v = xr[j]
                tr[j] = v
                hr[j] = v
                lr[j] = v
        else:
            for j in range(W):
                v = xr[j]
                tr[j] += v
                hr[j] = max(hr[j], v)
                lr[j] = min(lr[j], v)


@njit(parallel=True, cache=True, nogil=True)
def dark_accumulate_k(x, total, hi, lo):  # pragma: no cover - compiled
    """total += x; keep the hi.shape[0] largest (descending) and lo.shape[0] smallest (ascending) per pixel."""
    H, W = x.shape
    kh = hi.shape[0]
    kl = lo.shape[0]
    for i in prange(H):
        for j in range(W):
            v = x[i, j]
            total[i, j] += v
            a = v
            for k in range(kh):
                h = hi[k, i, j]
                hi[k, i, j] = max(a, h)
                a = min(a, h)
            b = v
            for k in range(kl):
                m = lo[k, i, j]
                lo[k, i, j] = min(b, m)
                b = max(b, m)


def dark_accumulate(x, total, hi, lo, first=False):
    """Dispatch: hi (k_hi, H, W), lo (k_lo, H, W). ``first`` (fast path only): initialise from x; the general
    path expects total = 0, hi = lowest and lo = highest values already."""
    if hi.shape[0] == 1 and lo.shape[0] == 1:
        dark_accumulate_11(x, total, hi[0], lo[0], first)
    else:
        if first:
            total.fill(0)
            hi.fill(-np.inf if hi.dtype.kind == "f" else 0)
            lo.fill(np.inf if lo.dtype.kind == "f" else np.iinfo(lo.dtype).max)
        dark_accumulate_k(x, total, hi, lo)


@njit(parallel=True, cache=True, nogil=True)
def dark_finish_k(total, hi, lo, k_hi, k_lo, n_used, out):  # pragma: no cover - compiled
    """out = (total - sum of the k_hi largest - sum of the k_lo smallest) / n_used, as float32."""
    H, W = total.shape
    inv = 1.0 / n_used
    for i in prange(H):
        for j in range(W):
            acc = np.float64(total[i, j])
            for k in range(k_hi):
                acc -= hi[k, i, j]
            for k in range(k_lo):
                acc -= lo[k, i, j]
            out[i, j] = np.float32(acc * inv)


@njit(parallel=True, cache=True, nogil=True)
def dark_finish_11(total, hi, lo, n_used, out):  # pragma: no cover - compiled
    H, W = total.shape
    inv = 1.0 / n_used
    for i in prange(H):
        tr = total[i]
        hr = hi[i]
        lr = lo[i]
        orow = out[i]
        for j in range(W):
            orow[j] = np.float32((np.float64(tr[j]) - hr[j] - lr[j]) * inv)


def dark_finish(total, hi, lo, k_hi, k_lo, n_used, out):
    """Dispatch (k_hi = k_lo = 1 is the fast path)."""
    if k_hi == 1 and k_lo == 1:
        dark_finish_11(total, hi[0], lo[0], n_used, out)
    else:
        dark_finish_k(total, hi, lo, k_hi, k_lo, n_used, out)


@njit(parallel=True, cache=True, nogil=True)
def hdr_accumulate(raw, dark, dark_value, use_dark_array, inv_t, inv_span, limit, white, num, den, fallback,
                   write_fallback, first):  # pragma: no cover - compiled
    """One exposure into the HDR accumulators (eq 8.9 weight on the dark-subtracted signal, zero above the
    linear limit or at clipping); ``fallback`` takes the per-second value when ``write_fallback``; ``first``
    initialises num and den instead of adding (no zero-fill pass)."""
    H, W = raw.shape
    one = np.float32(1.0)
    zero = np.float32(0.0)
    for i in prange(H):
        for j in range(W):
            x = raw[i, j]
            d = dark[i, j] if use_dark_array else dark_value
            v = np.float32(x) - np.float32(d)
            u = v * inv_span
            w = min(u, one - u)
            if w < zero or x > limit or x >= white:
                w = zero
            r = v * inv_t
            if write_fallback:
                fallback[i, j] = r
            if first:
                num[i, j] = w * r
                den[i, j] = w
            else:
                num[i, j] += w * r
                den[i, j] += w


@njit(parallel=True, cache=True, nogil=True)
def hdr_finish(num, den, fallback):  # pragma: no cover - compiled
    """num <- num / den where den > 0, else the fallback value; returns the number of fallback pixels."""
    H, W = num.shape
    counts = np.zeros(H, dtype=np.int64)
    for i in prange(H):
        c = 0
        for j in range(W):
            if den[i, j] > 0:
                num[i, j] = num[i, j] / den[i, j]
            else:
                num[i, j] = fallback[i, j]
                c += 1
        counts[i] = c
    return counts.sum()


@njit(parallel=True, cache=True, nogil=True)
def hdr_flat_superpixel(num, den, fallback, white, threshold, cfa, out):  # pragma: no cover - compiled
    """Finish the merge, flat-field by ``white`` (eq 7.1; NaN where white <= threshold) and reduce each 2x2
    cell to R, mean(G1, G2), B in ``out`` (H/2, W/2, 3). ``cfa`` (2, 2): 0 = R, 1 = G, 2 = B. Returns the
    number of fallback (clipped in every exposure) pixels."""
    H2, W2 = out.shape[0], out.shape[1]
    counts = np.zeros(H2, dtype=np.int64)
    nan = np.float32(np.nan)
    half = np.float32(0.5)
    for ci in prange(H2):
        c = 0
        for cj in range(W2):
            g = np.float32(0.0)
            for di in range(2):
                for dj in range(2):
                    i = 2 * ci + di
                    j = 2 * cj + dj
                    if den[i, j] > 0:
                        v = num[i, j] / den[i, j]
                    else:
                        v = fallback[i, j]
                        c += 1
                    wv = white[i, j]
                    f = v / wv if wv > threshold else nan
                    ch = cfa[di, dj]
                    if ch == 1:
                        g += f
                    else:
                        out[ci, cj, ch] = f
            out[ci, cj, 1] = g * half
        counts[ci] = c
    return counts.sum()


def warm_up() -> None:
    """Compile (first run) or load from the on-disk cache every kernel for the dtypes the pipeline uses, on
    tiny arrays. Takes ~1-3 s once per process; call it early (e.g. in a worker thread at start-up) so the
    first real frame does not pay it."""
    x = np.full((4, 4), 700, dtype=np.uint16)
    total = np.zeros((4, 4), np.uint32)
    hi = np.zeros((1, 4, 4), np.uint16)
    lo = np.full((1, 4, 4), 65535, np.uint16)
    dark_accumulate(x, total, hi, lo, True)
    dark_accumulate(x, total, hi, lo, False)
    out = np.empty((4, 4), np.float32)
    dark_finish(total, hi, lo, 1, 1, 1.0, out)
    num = np.zeros((4, 4), np.float32)
    den = np.zeros((4, 4), np.float32)
    fb = np.zeros((4, 4), np.float32)
    hdr_accumulate(x, out, np.float32(0), True, np.float32(1), np.float32(1e-4), 11000.0, 15520.0, num, den, fb, True,
                   True)
    sp = np.empty((2, 2, 6), np.float32)
    hdr_flat_superpixel(num, den, fb, out, np.float32(0.01), np.array([[0, 1], [1, 2]], np.int8), sp[..., :3])
    hdr_finish(num, den, fb)
