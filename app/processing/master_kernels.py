"""Fused per-row kernel of the full-resolution path: a row band of one light's raw exposures -> dark-subtracted,
HDR-merged (eq 8.9 or variance-optimal), flat-fielded (eq 7.1) mosaic rows, mirrored at the columns for the 5x5
demosaic (app.processing.demosaic).

Why hand-written: the half-resolution path (app.processing.kernels) accumulates each exposure into frame-size
float32 slots as it lands (5 bytes per pixel and exposure time), which at 150 MP is 1.5 GB per light before the
flat field. Here the exposures of a light stay as decoded (LibRaw's 16-bit buffers, 2 bytes per pixel) and each
row is merged from them when its band is delivered: the slots are one row long and live in the cache, and the
master darks and whites are read one band at a time (app.processing.masters). The rules are the half-resolution
kernels' own: :func:`store_row` is ``kernels.hdr_store`` for one row, the merge is ``kernels._merge_row`` itself,
the flat field eq 7.1 with NaN where the white is at or below its threshold (app.processing.calibration); the
tests check the rows against the half-resolution path's HdrMerge + FlatField on the same frames.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from dualrgb.app.processing.demosaic import HALO
from dualrgb.app.processing.kernels import _merge_row


@njit(nogil=True, cache=True, inline="always", error_model="numpy")
def store_row(raw, dark, dark_value, use_dark, limit, white, k, sums, counts, first):  # pragma: no cover
    """``kernels.hdr_store`` for one row: ``raw`` (W,) into slot ``k`` of ``sums`` / ``counts`` (K, 1, W)."""
    low = np.uint8(15)
    for j in range(raw.shape[0]):
        x = raw[j]
        d = dark[j] if use_dark else dark_value
        v = np.float32(x) - np.float32(d)
        u = np.uint8(1) if (x <= limit and x < white) else np.uint8(0)
        if first:
            sums[k, 0, j] = v
            counts[k, 0, j] = np.uint8(16) | u
        else:
            c = counts[k, 0, j]
            nu = c & low
            sm = sums[k, 0, j]
            if u:
                sums[k, 0, j] = sm + v if nu > 0 else v
            elif nu == 0:
                sums[k, 0, j] = sm + v
            counts[k, 0, j] = c + np.uint8(16) + u


@njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _weak_row(sums, counts, floor_dn, weak, first):  # pragma: no cover - compiled
    """``weak`` (W,): no usable exposure time's mean signal reached ``floor_dn``, AND-ed with the lights before
    (``first``: initialise)."""
    low = np.uint8(15)
    for j in range(weak.shape[0]):
        best = np.float32(-1e30)
        for k in range(sums.shape[0]):
            nu = counts[k, 0, j] & low
            if nu > 0:
                best = max(best, sums[k, 0, j] / np.float32(nu))
        w = best < floor_dn
        weak[j] = w if first else (weak[j] and w)


@njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _flat_row(merged, white, threshold, out):  # pragma: no cover - compiled
    """``out`` (W + 2 HALO,) = merged / white (NaN where white <= threshold), mirrored at both ends."""
    W = merged.shape[0]
    nan = np.float32(np.nan)
    for j in range(W):
        wv = white[j]
        out[HALO + j] = merged[j] / wv if wv > threshold else nan
    for h in range(1, HALO + 1):
        out[HALO - h] = out[HALO + h]
        out[HALO + W - 1 + h] = out[HALO + W - 1 - h]


@njit(nogil=True, cache=True, error_model="numpy")
def flat_rows(raws, darks, dark_values, use_dark, slots, first_in_slot, n_slots, order, ts, inv_ts, method,
              inv_span, inv_gain, var_read, limit, white_level, white, threshold, floor_dn, out, weak, first_light,
              a, b, core_a, core_b):  # pragma: no cover - compiled
    """Band rows ``a`` .. ``b`` of one light into ``out`` (rows, W + 2 HALO): ``raws`` / ``darks`` are tuples of
    the exposures' (rows, W) band views (a dark (1, W) placeholder where ``use_dark`` is False: ``dark_values``
    then), ``slots`` each exposure's exposure-time slot and ``first_in_slot`` whether it opens it; ``white`` the
    light's (rows, W) white band. ``weak`` (rows, W) gathers the under-exposed photosites over the lights. Returns
    the photosites of rows ``core_a`` .. ``core_b`` with no usable exposure (clipped)."""
    W = white.shape[1]
    sums = np.empty((n_slots, 1, W), np.float32)
    counts = np.empty((n_slots, 1, W), np.uint8)
    merged = np.empty(W, np.float32)
    clipped = 0
    for i in range(a, b):
        for f in range(len(raws)):
            d = darks[f][i] if use_dark[f] else darks[f][0]
            store_row(raws[f][i], d, dark_values[f], use_dark[f], limit, white_level, slots[f], sums, counts,
                      first_in_slot[f])
        c = _merge_row(sums, counts, 0, order, ts, inv_ts, method, inv_span, inv_gain, var_read, merged)
        if core_a <= i < core_b:
            clipped += c
            _weak_row(sums, counts, floor_dn, weak[i], first_light)
        _flat_row(merged, white[i], threshold, out[i])
    return clipped


@njit(nogil=True, cache=True, error_model="numpy")
def flat_rows_variance(raws, darks, dark_values, use_dark, ts, inv_gain, var_read, limit, white_level, white,
                       threshold, floor_dn, out, weak, first_light, a, b, core_a, core_b):  # pragma: no cover
    """:func:`flat_rows` for its common case, fused: the variance-optimal merge of exposures of distinct times
    (one frame each, ``raws`` shortest first, ``ts`` their times). The same arithmetic, in the same order, as
    store_row + kernels._merge_row (the tests check the two bit for bit), in one pass per exposure over loops that
    vectorise, without the slots' counts: 2.5x faster."""
    K = len(raws)
    W = white.shape[1]
    x = np.empty((K, W), np.float32)
    u = np.empty((K, W), np.float32)
    sx = np.empty(W, np.float32)
    st = np.empty(W, np.float32)
    num = np.empty(W, np.float32)
    den = np.empty(W, np.float32)
    best = np.empty(W, np.float32)
    zero = np.float32(0.0)
    one = np.float32(1.0)
    nan = np.float32(np.nan)
    clipped = 0
    for i in range(a, b):
        for j in range(W):
            sx[j] = zero
            st[j] = zero
            num[j] = zero
            den[j] = zero
            best[j] = np.float32(-1e30)
        for k in range(K):
            r = raws[k][i]
            d = darks[k][i] if use_dark[k] else darks[k][0]
            dv = dark_values[k]
            dk = use_dark[k]
            t = ts[k]
            xk = x[k]
            uk = u[k]
            for j in range(W):
                v = r[j]
                xk[j] = np.float32(v) - (d[j] if dk else dv)
                ok = v <= limit and v < white_level
                uk[j] = one if ok else zero
                sx[j] += xk[j] if ok else zero
                st[j] += t if ok else zero
                best[j] = max(best[j], xk[j]) if ok else best[j]
        for j in range(W):
            sx[j] = max(sx[j] / st[j], zero) if st[j] > zero else zero
        for k in range(K):
            t = ts[k]
            xk = x[k]
            uk = u[k]
            for j in range(W):
                w = one / (sx[j] * t * inv_gain + var_read)
                ok = uk[j] > zero
                num[j] += (w * t * xk[j]) if ok else zero
                den[j] += w * uk[j] * t * t
        o = out[i]
        wr = white[i]
        inv_t0 = one / ts[0]
        x0 = x[0]
        for j in range(W):
            e = num[j] / den[j] if den[j] > zero else x0[j] * inv_t0
            wv = wr[j]
            o[HALO + j] = e / wv if wv > threshold else nan
        for h in range(1, HALO + 1):
            o[HALO - h] = o[HALO + h]
            o[HALO + W - 1 + h] = o[HALO + W - 1 - h]
        if core_a <= i < core_b:
            wk = weak[i]
            for j in range(W):
                clipped += 1 if st[j] == zero else 0
                w8 = best[j] < floor_dn
                wk[j] = w8 if first_light else (wk[j] and w8)
    return clipped


def warm_up(exposures: tuple[int, ...] = (1, 2, 3)) -> None:
    """Load (or compile) the row kernels for lights of ``exposures`` frames each, on tiny arrays: a kernel's first
    call in a process reads it from numba's cache (~0.25 CPU-s each), which would otherwise fall on the first
    delivery."""
    f32 = np.float32
    for k in exposures:
        raws = tuple(np.zeros((2, 4), np.uint16) for _ in range(k))
        darks = tuple(np.zeros((2, 4), f32) for _ in range(k))
        ts = np.arange(1, k + 1, dtype=f32)
        out, weak, white = np.zeros((2, 4 + 2 * HALO), f32), np.zeros((2, 4), np.bool_), np.ones((2, 4), f32)
        flat_rows_variance(raws, darks, np.zeros(k, f32), np.ones(k, np.bool_), ts, f32(1), f32(1), f32(1e4),
                           f32(1.5e4), white, f32(0), f32(1), out, weak, True, 0, 2, 0, 2)
        slots = np.arange(k, dtype=np.int64)
        flat_rows(raws, darks, np.zeros(k, f32), np.ones(k, np.bool_), slots, np.ones(k, np.bool_), k, slots, ts,
                  f32(1) / ts, 0, f32(1e-4), f32(1), f32(1), f32(1e4), f32(1.5e4), white, f32(0), f32(1), out, weak,
                  True, 0, 2, 0, 2)
