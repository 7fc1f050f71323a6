"""Fused kernel of the expected-captured objective (numba, float32): per particle and patch, the attenuated
fit's prediction, its exact CIEDE2000 (the fast_de kernel's formula), the prediction error covariance from
camera noise and reference uncertainty, and the expected |error| in the local dE00 metric; mean over patches.

Why hand-written: the optimisers evaluate ~1e6 particles per search; the float64 reference
(:class:`simulation.expected_error.ExpectedErrorModel`) spends ~50 us per particle in numpy temporaries, this
kernel 1.5-2x the noise-free kernel. The layout follows ``simulation.fast_de.mean_de2000_mapped``: blocks of
particles, patches outer, particles inner, so every step is a loop over the block that LLVM vectorises.
"""
from __future__ import annotations

import math

import numpy as np
from numba import float32 as f32
from numba import njit, prange

from dualrgb.simulation.fast_de import _FASTMATH, _de2000, _f_lab  # one CIEDE2000 implementation for both objectives

_BLOCK = 256


@njit(fastmath=_FASTMATH, error_model="numpy", inline="always")
def _active_rows(Mb, rows):
    """Indices r where any Mb[k, r, :] is non-zero (rows no particle of the block uses are skipped)."""
    n_active = 0
    for r in range(Mb.shape[1]):
        nz = False
        for k in range(Mb.shape[0]):
            for i in range(Mb.shape[2]):
                if Mb[k, r, i] != 0.0:
                    nz = True
                    break
            if nz:
                break
        if nz:
            rows[n_active] = r
            n_active += 1
    return n_active


@njit(fastmath=_FASTMATH, error_model="numpy", parallel=True, cache=True)
def mean_expected_de2000(M, Cm, A, coef, RT, white, L1, a1, b1, xyz_ref, Qm, Rc, spread, out):
    """out[p] = mean_j E|dE00| of particle p's captured training prediction of patch j.

    M (3, R, P): per-particle maps from the R per-LED responses to predicted X, Y, Z (the attenuated fit);
    Cm (C, R, P): the same for the C camera channels' values; A (C, 3, P): the fitted matrix (channel -> XYZ);
    coef (3, C, P): channel variance sigma^2 = c0 + c1 v + c2 v^2; RT (R, n): per-LED responses of the patches;
    L1, a1, b1 (n,): reference Lab; xyz_ref (3, n); Qm (6, n): the dE00 metric in XYZ (00, 01, 02, 11, 12, 22);
    Rc (6, n): the reference XYZ covariance, same order; ``spread``: the camera noise's variance in the
    prediction relative to that of the fit's (1: a patch mean; the patch's pixels: one pixel of it, the fit
    still on the patch means).
    """
    R, n = RT.shape
    C = Cm.shape[0]
    P = M.shape[2]
    nblocks = (P + _BLOCK - 1) // _BLOCK
    wx = f32(1.0 / white[0])
    wy = f32(1.0 / white[1])
    wz = f32(1.0 / white[2])
    sp = f32(spread)
    for blk in prange(nblocks):
        lo = blk * _BLOCK
        hi = min(P, lo + _BLOCK)
        B = hi - lo
        Mb = M[:, :, lo:hi].astype(np.float32)
        Cb = Cm[:, :, lo:hi].astype(np.float32)
        Ab = A[:, :, lo:hi].astype(np.float32)
        cb = coef[:, :, lo:hi].astype(np.float32)
        rows = np.empty(R, dtype=np.int64)
        n_rows = _active_rows(Mb, rows)
        crows = np.empty((C, R), dtype=np.int64)
        n_crows = np.empty(C, dtype=np.int64)
        for c in range(C):
            n_crows[c] = _active_rows(Cb[c:c + 1], crows[c])
        X = np.empty(B, dtype=np.float32)
        Y = np.empty(B, dtype=np.float32)
        Z = np.empty(B, dtype=np.float32)
        V = np.empty((C, B), dtype=np.float32)
        S = np.empty((6, B), dtype=np.float32)
        acc = np.zeros(B, dtype=np.float32)
        for j in range(n):
            for i in range(B):
                X[i] = f32(0.0)
                Y[i] = f32(0.0)
                Z[i] = f32(0.0)
            for q in range(n_rows):
                r = rows[q]
                v = f32(RT[r, j])
                for i in range(B):
                    X[i] += Mb[0, r, i] * v
                    Y[i] += Mb[1, r, i] * v
                    Z[i] += Mb[2, r, i] * v
            for c in range(C):
                for i in range(B):
                    V[c, i] = f32(0.0)
                for q in range(n_crows[c]):
                    r = crows[c, q]
                    v = f32(RT[r, j])
                    for i in range(B):
                        V[c, i] += Cb[c, r, i] * v
            for k in range(6):
                rk = Rc[k, j]
                for i in range(B):
                    S[k, i] = rk
            for c in range(C):
                for i in range(B):
                    s2 = (cb[0, c, i] + V[c, i] * (cb[1, c, i] + cb[2, c, i] * V[c, i])) * sp
                    ax = Ab[c, 0, i]
                    ay = Ab[c, 1, i]
                    az = Ab[c, 2, i]
                    S[0, i] += s2 * ax * ax
                    S[1, i] += s2 * ax * ay
                    S[2, i] += s2 * ax * az
                    S[3, i] += s2 * ay * ay
                    S[4, i] += s2 * ay * az
                    S[5, i] += s2 * az * az
            _accumulate(X, Y, Z, S, wx, wy, wz, L1[j], a1[j], b1[j], xyz_ref[:, j], Qm[:, j], acc)
        for i in range(B):
            out[lo + i] = acc[i] / f32(n)


@njit(fastmath=_FASTMATH, error_model="numpy", inline="always")
def _accumulate(X, Y, Z, S, wx, wy, wz, Lr, ar, br, xr, Qj, acc):
    """acc += E|x| for one patch over the block: m = dE00 of the prediction, spread from S in the metric Q."""
    q00, q01, q02, q11, q12, q22 = Qj[0], Qj[1], Qj[2], Qj[3], Qj[4], Qj[5]
    for i in range(X.shape[0]):
        fx = _f_lab(X[i] * wx)
        fy = _f_lab(Y[i] * wy)
        fz = _f_lab(Z[i] * wz)
        m = _de2000(Lr, ar, br, f32(116.0) * fy - f32(16.0), f32(500.0) * (fx - fy), f32(200.0) * (fy - fz))
        s00, s01, s02, s11, s12, s22 = S[0, i], S[1, i], S[2, i], S[3, i], S[4, i], S[5, i]
        # QS (not symmetric)
        a00 = q00 * s00 + q01 * s01 + q02 * s02
        a01 = q00 * s01 + q01 * s11 + q02 * s12
        a02 = q00 * s02 + q01 * s12 + q02 * s22
        a10 = q01 * s00 + q11 * s01 + q12 * s02
        a11 = q01 * s01 + q11 * s11 + q12 * s12
        a12 = q01 * s02 + q11 * s12 + q12 * s22
        a20 = q02 * s00 + q12 * s01 + q22 * s02
        a21 = q02 * s01 + q12 * s11 + q22 * s12
        a22 = q02 * s02 + q12 * s12 + q22 * s22
        tr = a00 + a11 + a22
        tr2 = (a00 * a00 + a11 * a11 + a22 * a22
               + f32(2.0) * (a01 * a10 + a02 * a20 + a12 * a21))
        bx = X[i] - xr[0]
        by = Y[i] - xr[1]
        bz = Z[i] - xr[2]
        gx = q00 * bx + q01 * by + q02 * bz
        gy = q01 * bx + q11 * by + q12 * bz
        gz = q02 * bx + q12 * by + q22 * bz
        quad = (gx * (s00 * gx + s01 * gy + s02 * gz) + gy * (s01 * gx + s11 * gy + s12 * gz)
                + gz * (s02 * gx + s12 * gy + s22 * gz))
        e2 = m * m + tr
        var = f32(2.0) * tr2 + f32(4.0) * quad
        e2s = e2 if e2 > f32(0.0) else f32(1.0)
        e = math.sqrt(e2s) * (f32(1.0) - var / (f32(8.0) * e2s * e2s))
        acc[i] += e if e2 > f32(0.0) else f32(0.0)


@njit(error_model="numpy", parallel=True, cache=True)
def prepare_expected(idx, w, open_, rsum, gdiag, n_patches, headroom, t_scale, noise, px, D_out, coef_out, Cm_out):
    """Per particle: the channels' noise coefficients, the fit's extra diagonal and the channel map.

    idx, w (P, L, m): LEDs and realised levels; open_ (K, 3), rsum (K, 3) (sum over the training patches) and
    gdiag (K, K, 3) (sum_j R_a,c R_b,c) in the responses' units; t_scale: exposure = headroom / (t_scale O_max);
    noise = (read_noise, electrons_per_dn, dark_current, dark_frames, flat_frames); px (3,): effective pixels per
    channel. Writes D_out (P, 3L) = sum_j sigma_jc^2, coef_out (3, 3L, P) (sigma^2 = c0 + c1 c + c2 c^2 in
    response units) and adds to Cm_out (3L, 3K, P), zeros on entry, the map from per-LED responses to channels.
    The formulas are those of ExpectedErrorModel.coefficients (float64 reference, tested against this).
    """
    P, L, m = w.shape
    read, gain, dark_i, n_dark, n_flat = noise[0], noise[1], noise[2], noise[3], noise[4]
    for p in prange(P):
        for li in range(L):
            o_max = 0.0
            for c in range(3):
                o = 0.0
                for i in range(m):
                    o += w[p, li, i] * open_[idx[p, li, i], c]
                o_max = max(o_max, o)
            t = headroom / (t_scale * o_max) if o_max > 0.0 else 0.0
            base = (read * read + t * dark_i / (gain * gain)) * (1.0 + 1.0 / n_dark) + 1.0 / 12.0
            for c in range(3):
                ch = 3 * li + c
                gate = 0.0
                s1 = 0.0
                s2 = 0.0
                for i in range(m):
                    wi = w[p, li, i]
                    k = idx[p, li, i]
                    gate += wi * open_[k, c]
                    s1 += wi * rsum[k, c]
                    Cm_out[ch, 3 * k + c, p] += wi
                    for i2 in range(m):
                        s2 += wi * w[p, li, i2] * gdiag[k, idx[p, li, i2], c]
                F = headroom * gate / o_max if o_max > 0.0 else 0.0
                a1 = 1.0 / (gain * F * px[c]) if F > 0.0 else 0.0
                a0 = base / (F * F * px[c]) if F > 0.0 else 0.0
                c0 = a0 * gate * gate
                c1 = a1 * gate
                c2 = (a1 + a0) / n_flat
                coef_out[0, ch, p] = c0
                coef_out[1, ch, p] = c1
                coef_out[2, ch, p] = c2
                D_out[p, ch] = n_patches * c0 + c1 * s1 + c2 * s2
