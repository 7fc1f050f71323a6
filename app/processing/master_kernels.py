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


@njit(nogil=True, cache=True, inline="always")
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


@njit(nogil=True, cache=True, inline="always")
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


@njit(nogil=True, cache=True, inline="always")
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


@njit(nogil=True, cache=True)
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
