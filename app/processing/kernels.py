"""Fused per-pixel kernels for the mosaic-size steps (numba, parallel over rows, cached on disk).

Why hand-written: each step is a handful of per-pixel operations over 24 M pixels. In numpy every operation is
a separate pass over memory with its own temporaries (the eq 8.9 weight alone is ~6 passes, the HDR update
~15), which made processing a 24 MP dual-RGB HDR set take ~2.5x the time of merely decoding its raw files
(bench/processing_bench.py). One fused pass per frame reads each input once and writes each accumulator once.
Semantics are identical to the numpy formulation documented in calibration.py and hdr.py (float32 arithmetic);
the tests check the results against known truth and the numpy references (simulation.hdr_estimators for the
HDR merge). The kernels release the GIL (nogil), so the next raw file
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
def hdr_store(raw, dark, dark_value, use_dark_array, limit, white, k, sums, counts, first):  # pragma: no cover
    """One frame into exposure-time slot ``k``: sums[k] (float32) accumulates the dark-subtracted signal of the
    slot's usable frames (raw value at most the linear ``limit`` and below the ``white`` level), or of all its
    frames while none was usable; counts[k] (uint8) holds usable frames in its low nibble and all frames in its
    high nibble (at most 15 frames per slot). ``first``: initialise the slot."""
    H, W = raw.shape
    low = np.uint8(15)
    for i in prange(H):
        for j in range(W):
            x = raw[i, j]
            d = dark[i, j] if use_dark_array else dark_value
            v = np.float32(x) - np.float32(d)
            u = np.uint8(1) if (x <= limit and x < white) else np.uint8(0)
            if first:
                sums[k, i, j] = v
                counts[k, i, j] = np.uint8(16) | u
            else:
                c = counts[k, i, j]
                nu = c & low
                sm = sums[k, i, j]
                if u:
                    sums[k, i, j] = sm + v if nu > 0 else v
                elif nu == 0:
                    sums[k, i, j] = sm + v
                counts[k, i, j] = c + np.uint8(16) + u


@njit(inline="always")
def _merge_row(sums, counts, i, order, ts, inv_ts, method, inv_span, inv_gain, var_read, out):  # pragma: no cover
    """Row ``i`` of the merge into ``out`` (W,) (simulation.hdr_estimators: same methods and rules); ``order``
    lists the exposure-time slots shortest first, ``ts`` / ``inv_ts`` their times in that order. Slot by slot
    over the whole row with branch-free selects, so every loop over j vectorises. Returns the clipped count."""
    W = out.shape[0]
    zero = np.float32(0.0)
    one = np.float32(1.0)
    num = np.zeros(W, np.float32)
    den = np.zeros(W, np.float32)
    seen = np.zeros(W, np.float32)                   # 1 where some frame was usable
    longest = np.empty(W, np.float32)                # mean of the longest usable slot (else all of the shortest)
    k0 = order[0]
    for j in range(W):
        c = counts[k0, i, j]
        n = np.float32(c & 15) if (c & 15) > 0 else np.float32(c >> 4)
        longest[j] = sums[k0, i, j] / n * inv_ts[0]
    if method == 0:                                  # eq 8.9 on each exposure time's mean frame, n frames' weight
        for q in range(order.shape[0]):
            k = order[q]
            it = inv_ts[q]
            for j in range(W):
                n = np.float32(counts[k, i, j] & 15)
                x = sums[k, i, j] / max(n, one)
                u = x * inv_span
                w = max(min(u, one - u), zero) * n
                r = x * it
                num[j] += w * r
                den[j] += w
                longest[j] = r if n > zero else longest[j]
                seen[j] = max(seen[j], min(n, one))
    else:                                            # variance-optimal (Granados et al. 2010)
        sx = np.zeros(W, np.float32)
        st = np.zeros(W, np.float32)
        for q in range(order.shape[0]):
            k = order[q]
            t = ts[q]
            for j in range(W):
                n = np.float32(counts[k, i, j] & 15)
                sx[j] += sums[k, i, j] if n > zero else zero
                st[j] += n * t
        for j in range(W):
            sx[j] = max(sx[j] / st[j], zero) if st[j] > zero else zero      # the pooled estimate E0
            seen[j] = one if st[j] > zero else zero
        for q in range(order.shape[0]):
            k = order[q]
            t = ts[q]
            for j in range(W):
                n = np.float32(counts[k, i, j] & 15)
                w = one / (sx[j] * t * inv_gain + var_read)
                num[j] += (w * t * sums[k, i, j]) if n > zero else zero
                den[j] += w * n * t * t
    c = 0
    for j in range(W):
        out[j] = num[j] / den[j] if den[j] > zero else longest[j]
        c += 1 if seen[j] == zero else 0
    return c


@njit(parallel=True, cache=True, nogil=True)
def hdr_merge(sums, counts, order, ts, inv_ts, method, inv_span, inv_gain, var_read, out):  # pragma: no cover
    """out = the merged radiance (DN/s) of the stored exposures; returns the number of clipped pixels (no usable
    exposure: the shortest exposure's value); dark pixels take the longest usable exposure's value."""
    H = out.shape[0]
    clipped = np.zeros(H, dtype=np.int64)
    for i in prange(H):
        clipped[i] = _merge_row(sums, counts, i, order, ts, inv_ts, method, inv_span, inv_gain, var_read, out[i])
    return clipped.sum()


@njit(parallel=True, cache=True, nogil=True)
def hdr_merge_flat_superpixel(sums, counts, order, ts, inv_ts, method, inv_span, inv_gain, var_read, white,
                              threshold, cfa, out):  # pragma: no cover - compiled
    """Merge, flat-field by ``white`` (eq 7.1; NaN where white <= threshold) and reduce each 2x2 cell to R,
    mean(G1, G2), B in ``out`` (H/2, W/2, 3). ``cfa`` (2, 2): 0 = R, 1 = G, 2 = B. Returns the number of
    clipped pixels (no usable exposure)."""
    H2, W2 = out.shape[0], out.shape[1]
    W = sums.shape[2]
    clipped = np.zeros(H2, dtype=np.int64)
    nan = np.float32(np.nan)
    half = np.float32(0.5)
    for ci in prange(H2):
        rows = np.empty((2, W), np.float32)
        c = 0
        for di in range(2):
            i = 2 * ci + di
            c += _merge_row(sums, counts, i, order, ts, inv_ts, method, inv_span, inv_gain, var_read, rows[di])
            for j in range(W):
                wv = white[i, j]
                rows[di, j] = rows[di, j] / wv if wv > threshold else nan
        for cj in range(W2):
            g = np.float32(0.0)
            for di in range(2):
                for dj in range(2):
                    f = rows[di, 2 * cj + dj]
                    ch = cfa[di, dj]
                    if ch == 1:
                        g += f
                    else:
                        out[ci, cj, ch] = f
            out[ci, cj, 1] = g * half
        clipped[ci] = c
    return clipped.sum()


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
    xs = np.empty((2, 4, 4), np.float32)
    usable = np.empty((2, 4, 4), np.uint8)
    for k in range(2):
        hdr_store(x, out, np.float32(0), True, 11000.0, 15520.0, k, xs, usable, True)
        hdr_store(x, out, np.float32(0), True, 11000.0, 15520.0, k, xs, usable, False)
    order = np.array([0, 1], np.int64)
    ts = np.array([0.1, 1.0], np.float32)
    merged = np.empty((4, 4), np.float32)
    sp = np.empty((2, 2, 6), np.float32)
    for method in (0, 1):
        hdr_merge(xs, usable, order, ts, np.float32(1) / ts, method, np.float32(1e-4), np.float32(0.125),
                  np.float32(6.3), merged)
        hdr_merge_flat_superpixel(xs, usable, order, ts, np.float32(1) / ts, method, np.float32(1e-4),
                                  np.float32(0.125), np.float32(6.3), merged, np.float32(0.01),
                                  np.array([[0, 1], [1, 2]], np.int8), sp[..., :3])
