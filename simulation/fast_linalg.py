"""Batched characterisation of many light sets at once (numba): normal equations from Gram matrices,
equilibration + ridge, Cholesky, and the map back onto per-LED responses, fused per item.

Why hand-written: the optimisers fit one 6x6 characterisation per particle, ~1.4e6 per thesis-scale PSO
sweep; ``numpy.linalg.solve`` on a (P, 6, 6) stack costs ~0.9 us per system in LAPACK call overhead alone,
this kernel ~0.6 us for the whole fit. The systems are ridge-regularised and equilibrated, so they are SPD.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(error_model="numpy", parallel=True, cache=True)
def fit_light_sets(idx, w, G, H, ridge, M_out, A_out):
    """Characterise a batch of light sets from precomputed Gram matrices, in one pass per item.

    idx (P, L, m) int: LED indices (0-based) used by each light (pad with any index and weight 0);
    w (P, L, m): their levels; G (K, 3, K, 3) = R^T R and H (K, 3, 3) = R^T XYZ over the training patches.
    Writes A_out (P, 3L, 3), the least-squares matrix (columns equilibrated, ridge ``ridge`` on the unit
    diagonal, zero channels get zero rows), and M_out (3, K*3, P) = the same map expressed on the per-LED
    responses: X'[p] = M_out[0, :, p] @ R_flat.T (and Y', Z'), laid out for simulation.fast_de.
    """
    P, L, m = w.shape
    n = 3 * L
    nblocks = (P + 63) // 64
    for blk in prange(nblocks):
        # scratch allocated once per block of 64 items, not per item
        CtC = np.empty((n, n))
        CtB = np.empty((n, 3))
        s = np.empty(n)
        Lc = np.zeros((n, n))
        y = np.empty(n)
        for p in range(blk * 64, min(P, blk * 64 + 64)):
            _fit_one(idx[p], w[p], G, H, ridge, CtC, CtB, s, Lc, y, M_out, A_out, p)


@njit(error_model="numpy", inline="always")
def _fit_one(idx, w, G, H, ridge, CtC, CtB, s, Lc, y, M_out, A_out, p):
    """One item of fit_light_sets: normal equations, equilibration + ridge, Cholesky, then M_out[:, :, p]."""
    L, m = w.shape
    n = 3 * L
    CtC[:, :] = 0.0
    CtB[:, :] = 0.0
    for l1 in range(L):
        for i1 in range(m):
            w1 = w[l1, i1]
            if w1 == 0.0:
                continue
            k1 = idx[l1, i1]
            for c1 in range(3):
                r = 3 * l1 + c1
                for o in range(3):
                    CtB[r, o] += w1 * H[k1, c1, o]
                for l2 in range(L):
                    for i2 in range(m):
                        w2 = w[l2, i2]
                        if w2 == 0.0:
                            continue
                        k2 = idx[l2, i2]
                        for c2 in range(3):
                            CtC[r, 3 * l2 + c2] += w1 * w2 * G[k1, c1, k2, c2]
    for i in range(n):
        s[i] = 1.0 / math.sqrt(CtC[i, i]) if CtC[i, i] > 0.0 else 0.0
    for i in range(n):
        for j in range(n):
            CtC[i, j] *= s[i] * s[j]
        CtC[i, i] += ridge if s[i] > 0.0 else 1.0
        for o in range(3):
            CtB[i, o] *= s[i]
    # Cholesky solve
    for i in range(n):
        for j in range(i + 1):
            acc = CtC[i, j]
            for k in range(j):
                acc -= Lc[i, k] * Lc[j, k]
            if i == j:
                Lc[i, i] = math.sqrt(acc) if acc > 0.0 else 1e-300
            else:
                Lc[i, j] = acc / Lc[j, j]
    for o in range(3):
        for i in range(n):
            acc = CtB[i, o]
            for k in range(i):
                acc -= Lc[i, k] * y[k]
            y[i] = acc / Lc[i, i]
        for i in range(n - 1, -1, -1):
            acc = y[i]
            for k in range(i + 1, n):
                acc -= Lc[k, i] * A_out[p, k, o]
            A_out[p, i, o] = acc / Lc[i, i]
        for i in range(n):
            A_out[p, i, o] *= s[i]
    for r in range(M_out.shape[1]):
        for o in range(3):
            M_out[o, r, p] = 0.0
    for l1 in range(L):
        for i1 in range(m):
            w1 = w[l1, i1]
            k1 = idx[l1, i1]
            for c1 in range(3):
                for o in range(3):
                    M_out[o, 3 * k1 + c1, p] += w1 * A_out[p, 3 * l1 + c1, o]
