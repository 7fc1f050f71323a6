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

_SEGMENT = 128


@njit(error_model="numpy", parallel=True, cache=True)
def fit_light_sets(idx, w, G, H, ridge, M_out, A_out, extra):
    """Characterise a batch of light sets from precomputed Gram matrices, in one pass per item.

    idx (P, L, m) int: LED indices (0-based) used by each light (pad with any index and weight 0);
    w (P, L, m): their levels; G (K, 3, K, 3) = R^T R and H (K, 3, 3) = R^T XYZ over the training patches;
    extra (P, 3L): added to the diagonal of each item's normal equations before equilibration (zeros: least
    squares; the expected noise variance of each channel: the attenuated fit of simulation.expected_error).
    Writes A_out (P, 3L, 3), the least-squares matrix (columns equilibrated, ridge ``ridge`` on the unit
    diagonal, zero channels get zero rows), and M_out (3, K*3, P) = the same map expressed on the per-LED
    responses: X'[p] = M_out[0, :, p] @ R_flat.T (and Y', Z'), laid out for simulation.fast_de.
    """
    P, L, m = w.shape
    n = 3 * L
    # runs of items sharing one LED index array (a light set's particles) are fitted vectorised across items
    # (split every _SEGMENT items so the (n, n, items) scratch stays in cache and both cores get work)
    bounds = [0]
    for p in range(1, P):
        same = p - bounds[-1] < _SEGMENT
        for li in range(L):
            for i in range(m):
                if idx[p, li, i] != idx[p - 1, li, i]:
                    same = False
        if not same:
            bounds.append(p)
    bounds.append(P)
    edges = np.array(bounds)
    for seg in prange(len(edges) - 1):
        lo, hi = edges[seg], edges[seg + 1]
        if hi - lo >= 8:
            _fit_segment(idx[lo], w, G, H, ridge, M_out, A_out, extra, lo, hi)
            continue
        CtC = np.empty((n, n))
        CtB = np.empty((n, 3))
        s = np.empty(n)
        Lc = np.zeros((n, n))
        y = np.empty(n)
        for p in range(lo, hi):
            _fit_one(idx[p], w[p], G, H, ridge, CtC, CtB, s, Lc, y, M_out, A_out, extra[p], p)


@njit(error_model="numpy", inline="always")
def _fit_one(idx, w, G, H, ridge, CtC, CtB, s, Lc, y, M_out, A_out, extra, p):
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
        CtC[i, i] += extra[i]
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


@njit(error_model="numpy", inline="always")
def _fit_segment(idx, w, G, H, ridge, M_out, A_out, extra, lo, hi):
    """fit_light_sets for items lo..hi-1 that share one LED index array ``idx`` (L, m) — every particle of one
    light set in PSO/GA — vectorised across the items: each step is a loop over the items, which LLVM turns into
    SIMD code, instead of one scalar 6x6 fit per item (~15x faster per item)."""
    L, m = idx.shape
    n = 3 * L
    B = hi - lo
    q = L * m * 3
    wq = np.empty((L * m, B))
    for p in range(B):
        for li in range(L):
            for i in range(m):
                wq[li * m + i, p] = w[lo + p, li, i]
    CtC = np.zeros((n, n, B))
    CtB = np.zeros((n, 3, B))
    for a in range(q):
        l1 = a // (m * 3)
        i1 = (a // 3) % m
        c1 = a % 3
        ja = l1 * m + i1
        k1 = idx[l1, i1]
        r1 = 3 * l1 + c1
        for o in range(3):
            h = H[k1, c1, o]
            for p in range(B):
                CtB[r1, o, p] += wq[ja, p] * h
        for b in range(q):
            l2 = b // (m * 3)
            i2 = (b // 3) % m
            c2 = b % 3
            r2 = 3 * l2 + c2
            if r2 > r1:
                continue                          # lower triangle only; mirrored below
            g = G[k1, c1, idx[l2, i2], c2]
            jb = l2 * m + i2
            for p in range(B):
                CtC[r1, r2, p] += wq[ja, p] * wq[jb, p] * g
    s = np.empty((n, B))
    for i in range(n):
        for p in range(B):
            CtC[i, i, p] += extra[lo + p, i]
            d = CtC[i, i, p]
            s[i, p] = 1.0 / math.sqrt(d) if d > 0.0 else 0.0
    for i in range(n):
        for j in range(i + 1):
            for p in range(B):
                CtC[i, j, p] *= s[i, p] * s[j, p]
        for p in range(B):
            CtC[i, i, p] += ridge if s[i, p] > 0.0 else 1.0
        for o in range(3):
            for p in range(B):
                CtB[i, o, p] *= s[i, p]
    Lc = np.zeros((n, n, B))
    acc = np.empty(B)
    for i in range(n):
        for j in range(i + 1):
            for p in range(B):
                acc[p] = CtC[i, j, p]
            for k in range(j):
                for p in range(B):
                    acc[p] -= Lc[i, k, p] * Lc[j, k, p]
            if i == j:
                for p in range(B):
                    Lc[i, i, p] = math.sqrt(acc[p]) if acc[p] > 0.0 else 1e-300
            else:
                for p in range(B):
                    Lc[i, j, p] = acc[p] / Lc[j, j, p]
    y = np.empty((n, B))
    x = np.empty((n, B))
    for o in range(3):
        for i in range(n):
            for p in range(B):
                acc[p] = CtB[i, o, p]
            for k in range(i):
                for p in range(B):
                    acc[p] -= Lc[i, k, p] * y[k, p]
            for p in range(B):
                y[i, p] = acc[p] / Lc[i, i, p]
        for i in range(n - 1, -1, -1):
            for p in range(B):
                acc[p] = y[i, p]
            for k in range(i + 1, n):
                for p in range(B):
                    acc[p] -= Lc[k, i, p] * x[k, p]
            for p in range(B):
                x[i, p] = acc[p] / Lc[i, i, p]
        for i in range(n):
            for p in range(B):
                A_out[lo + p, i, o] = x[i, p] * s[i, p]
    for r in range(M_out.shape[1]):
        for o in range(3):
            for p in range(B):
                M_out[o, r, lo + p] = 0.0
    for li in range(L):
        for i in range(m):
            k = idx[li, i]
            for c in range(3):
                for o in range(3):
                    for p in range(B):
                        M_out[o, 3 * k + c, lo + p] += wq[li * m + i, p] * A_out[lo + p, 3 * li + c, o]
