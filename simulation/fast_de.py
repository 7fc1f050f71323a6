"""Fused XYZ -> CIELAB -> CIEDE2000 -> mean kernel for the optimisers' inner loop (numba, float32).

Why hand-written: a thesis-scale PSO sweep needs ~2.6e8 CIEDE2000 evaluations. colour-science's ``delta_E``
and even a careful numpy formulation (``simulation.colorimetry``) cost 40-80 ns per colour pair because each
of ~100 array passes goes through memory; numba without Intel SVML calls scalar libm for cos/atan2/exp,
which is slower still. So this kernel uses only arithmetic and ``sqrt`` and lets LLVM vectorise it
(``error_model="numpy"`` matters: Python's ZeroDivisionError check on every division blocks vectorisation):
  * cube root: range reduction by powers of 8 and two Halley steps (relative error < 3e-7 up to X/Xn = 8^8);
  * T(h'): cosines of h', 2h', 3h', 4h' from the unit hue vector by the multiple-angle formulas;
  * h' - 275 deg: a cephes-style atanf on the hue vector rotated by 275 deg;
  * exp and sin: short Taylor series on bounded ranges (exp(-z) as (exp(-z/32))^32).
It agrees with colour-science to < 1e-4 dE00 (tests/simulation/test_ciede2000.py: all 34 Sharma et al. pairs and
random pairs with exactly and nearly opposite hues), far below the 0.01 that rankings could feel.
Final reported errors always come from the float64 reference implementation.
"""
from __future__ import annotations

import math

import numpy as np
from numba import float32 as f32
from numba import njit, prange

_PI = f32(math.pi)
_ONE = f32(1.0)
_HALF = f32(0.5)
_ZERO = f32(0.0)
_K7 = f32(25.0**7)
_C30, _S30 = f32(math.cos(math.pi / 6)), f32(0.5)
_C6, _S6 = f32(math.cos(math.pi / 30)), f32(math.sin(math.pi / 30))
_C63, _S63 = f32(math.cos(63 * math.pi / 180)), f32(math.sin(63 * math.pi / 180))
_C275, _S275 = f32(math.cos(275 * math.pi / 180)), f32(math.sin(275 * math.pi / 180))
_TAN_PI8 = f32(math.tan(math.pi / 8))
_TAN_3PI8 = f32(math.tan(3 * math.pi / 8))
_PIO2 = f32(math.pi / 2)
_PIO4 = f32(math.pi / 4)
_R2D = f32(180 / math.pi)
_DELTA = 6.0 / 29.0
_DELTA3 = f32(_DELTA**3)
_LIN_SLOPE = f32(1.0 / (3 * _DELTA**2))
CBRT_MAX = f32(8.0**8)                # _cbrt's range; clamped above (a guard, see _cbrt)

# fastmath without "contract", "reassoc", "arcp" and "afn": with them LLVM fuses multiply-adds and uses approximate
# reciprocals in the vectorised loop body but not in its scalar remainder, so an item's result depended on its
# position in the batch (chunking changed costs by ~1e-6). Measured: the thesis PSO sweep is as fast without them.
_FASTMATH = {"nnan", "ninf", "nsz"}


@njit(fastmath=_FASTMATH, error_model="numpy", inline="always")
def _cbrt(t):
    """Cube root for delta^3 <= t <= CBRT_MAX = 8^8 (CIELAB's cube-root branch, t = X/Xn; X/Xn > 1 in HDR
    highlights and speculars), relative error < 3e-7; t above CBRT_MAX is clamped to it (guard: L* would exceed
    29 000 there, a prediction that far off costs > 10^4 dE00 either way). Tested over the whole range.

    Range reduction to [1, 8] by powers of 8 (exact in binary): /8^4, /8^2, /8 where t exceeds them, then *8^2
    below 1/8 and *8 below 1 (delta^3 > 8^-3); a linear start (relative error < 5.8e-2 on [1, 8]) and two Halley
    steps (cubic convergence: 1.4e-4, then 2e-12). Compares and selects only, so it vectorises.
    """
    t = min(t, CBRT_MAX)
    hit = t > f32(4096.0)
    t = t * f32(1.0 / 4096.0) if hit else t
    s = f32(16.0) if hit else _ONE
    hit = t > f32(64.0)
    t = t * f32(1.0 / 64.0) if hit else t
    s = s * f32(4.0) if hit else s
    hit = t > f32(8.0)
    t = t * f32(0.125) if hit else t
    s = s * f32(2.0) if hit else s
    small = t < f32(0.125)
    t = t * f32(64.0) if small else t
    s = s * f32(0.25) if small else s
    small = t < _ONE
    t = t * f32(8.0) if small else t
    s = s * _HALF if small else s
    y = f32(0.9063272) + f32(0.15105453) * t     # minimax line for cbrt on [1, 8]
    y3 = y * y * y
    y = y * (y3 + f32(2.0) * t) / (f32(2.0) * y3 + t)
    y3 = y * y * y
    y = y * (y3 + f32(2.0) * t) / (f32(2.0) * y3 + t)
    return y * s


@njit(fastmath=_FASTMATH, error_model="numpy", inline="always")
def _f_lab(t):
    """CIELAB's f: the cube root above delta^3 (its argument clamped there, so the discarded side of the select
    never sees a negative value), the linear segment below."""
    return _cbrt(max(t, _DELTA3)) if t > _DELTA3 else t * _LIN_SLOPE + f32(4.0 / 29.0)


@njit(fastmath=_FASTMATH, error_model="numpy", inline="always")
def _atan2(y, x):
    """cephes atanf with range reduction; |error| < 2e-7 rad."""
    ax = abs(x)
    ay = abs(y)
    r = ay / ax if ax > _ZERO else f32(1e30)
    big = r > _TAN_3PI8
    mid = r > _TAN_PI8
    xr = -_ONE / r if big else ((r - _ONE) / (r + _ONE) if mid else r)
    y0 = _PIO2 if big else (_PIO4 if mid else _ZERO)
    z = xr * xr
    a = y0 + ((((f32(8.05374449538e-2) * z - f32(1.38776856032e-1)) * z + f32(1.99777106478e-1)) * z
               - f32(3.33329491539e-1)) * z * xr + xr)
    a = _PI - a if x < _ZERO else a
    return -a if y < _ZERO else a


@njit(fastmath=_FASTMATH, error_model="numpy", inline="always")
def _de2000(L1, a1, b1, L2, a2, b2):
    C1 = math.sqrt(a1 * a1 + b1 * b1)
    C2 = math.sqrt(a2 * a2 + b2 * b2)
    Cm = max(_HALF * (C1 + C2), f32(1e-4))
    Cm2 = Cm * Cm
    Cm7 = Cm2 * Cm2 * Cm2 * Cm
    g1 = f32(1.5) - _HALF * math.sqrt(Cm7 / (Cm7 + _K7))
    a1p = a1 * g1
    a2p = a2 * g1
    C1p = math.sqrt(a1p * a1p + b1 * b1)
    C2p = math.sqrt(a2p * a2p + b2 * b2)
    prod = C1p * C2p
    zero = prod == _ZERO
    inv1 = _ONE / C1p if C1p > _ZERO else _ZERO
    inv2 = _ONE / C2p if C2p > _ZERO else _ZERO
    u1x = a1p * inv1
    u1y = b1 * inv1
    u2x = a2p * inv2
    u2y = b2 * inv2
    dx = u2x - u1x
    dy = u2y - u1y
    # sign of dh' (colorimetry.opposite_hue_sign): the cross product's, or the CIE rule's at exactly opposite hues
    cross = a1p * b2 - b1 * a2p
    upper = (b1 > _ZERO) or ((b1 == _ZERO) and (a1p > _ZERO))
    sg = _ONE if cross > _ZERO else (-_ONE if cross < _ZERO else (_ONE if upper else -_ONE))
    dH = sg * math.sqrt(prod * (dx * dx + dy * dy))
    dC = C2p - C1p
    # mean hue direction (u1 + u2) + sg * rot(u2 - u1), |.| >= 2 (colorimetry's docstring); one zero chroma: u1 + u2
    sg = _ZERO if zero else sg
    hx = u1x + u2x + sg * dy
    hy = u1y + u2y - sg * dx
    r = math.sqrt(hx * hx + hy * hy)
    c = hx / r if r > _ZERO else _ONE
    s = hy / r if r > _ZERO else _ZERO
    c2 = c * c - s * s
    s2 = f32(2.0) * c * s
    c3 = c * c2 - s * s2
    s3 = s * c2 + c * s2
    c4 = c2 * c2 - s2 * s2
    s4 = f32(2.0) * s2 * c2
    T = (_ONE - f32(0.17) * (c * _C30 + s * _S30) + f32(0.24) * c2 + f32(0.32) * (c3 * _C6 - s3 * _S6)
         - f32(0.20) * (c4 * _C63 + s4 * _S63))
    # mean hue minus 275 degrees, in (-180, 180]; beyond +85 the true difference is < -275 and exp() is 0
    d = _atan2(s * _C275 - c * _S275, c * _C275 + s * _S275) * _R2D
    u = d * f32(1.0 / 25.0)
    z = u * u
    w = z * f32(1.0 / 32.0)
    e = _ONE + w * (-_ONE + w * (_HALF + w * (f32(-1 / 6.0) + w * (f32(1 / 24.0) + w * (f32(-1 / 120.0) + w * (
        f32(1 / 720.0) + w * (f32(-1 / 5040.0) + w * (f32(1 / 40320.0) + w * f32(-1 / 362880.0)))))))))
    e = e * e
    e = e * e
    e = e * e
    e = e * e
    e = e * e
    e = _ZERO if (d > f32(85.0)) or (z > f32(20.0)) else e
    t = e * (_PI / f32(3.0))             # 2 * dtheta in radians (dtheta = 30 deg * e)
    t2 = t * t
    sn = t * (_ONE + t2 * (f32(-1 / 6.0) + t2 * (f32(1 / 120.0) + t2 * (f32(-1 / 5040.0) + t2 * f32(1 / 362880.0)))))
    Cpm = _HALF * (C1p + C2p)
    Cc = max(Cpm, f32(1e-4))
    Cc2 = Cc * Cc
    C7 = Cc2 * Cc2 * Cc2 * Cc
    RT = f32(-2.0) * sn * math.sqrt(C7 / (C7 + _K7))
    Lm = _HALF * (L1 + L2) - f32(50.0)
    Lm = Lm * Lm
    SL = _ONE + f32(0.015) * Lm / math.sqrt(f32(20.0) + Lm)
    SC = _ONE + f32(0.045) * Cpm
    SH = _ONE + f32(0.015) * Cpm * T
    tL = (L2 - L1) / SL
    tC = dC / SC
    tH = dH / SH
    return math.sqrt(max(tL * tL + tC * tC + tH * tH + RT * tC * tH, _ZERO))


@njit(fastmath=_FASTMATH, error_model="numpy", parallel=True, cache=True)
def xyz_to_lab_f32(X, Y, Z, white, L, A, B):
    """CIELAB of (P, n) float64 XYZ into float32 (P, n) arrays L, A, B (a pure map, so it vectorises)."""
    P, n = X.shape
    wx = f32(1.0 / white[0])
    wy = f32(1.0 / white[1])
    wz = f32(1.0 / white[2])
    for p in prange(P):
        for j in range(n):
            fx = _f_lab(f32(X[p, j]) * wx)
            fy = _f_lab(f32(Y[p, j]) * wy)
            fz = _f_lab(f32(Z[p, j]) * wz)
            L[p, j] = f32(116.0) * fy - f32(16.0)
            A[p, j] = f32(500.0) * (fx - fy)
            B[p, j] = f32(200.0) * (fy - fz)


@njit(fastmath=_FASTMATH, error_model="numpy", parallel=True, cache=True)
def mean_de2000_rows(L1, a1, b1, L2, a2, b2, out):
    """out[p] = mean_j dE00((L1, a1, b1)[j], (L2, a2, b2)[p, j]); ground truth (n,), predictions (P, n)."""
    P, n = L2.shape
    for p in prange(P):
        acc = f32(0.0)
        for j in range(n):
            acc += _de2000(L1[j], a1[j], b1[j], L2[p, j], a2[p, j], b2[p, j])
        out[p] = acc / f32(n)


def mean_de2000_xyz(X, Y, Z, white, L1, a1, b1, out):
    """out[p] = mean_j dE00(Lab(X[p, j], Y[p, j], Z[p, j]), (L1[j], a1[j], b1[j])).

    X, Y, Z: (P, n) float64 predictions; white: (3,) float64; L1, a1, b1: (n,) float32 ground truth Lab.
    """
    if not (X.ndim == 2 and X.shape == Y.shape == Z.shape and L1.shape == a1.shape == b1.shape == (X.shape[1],)
            and out.shape == (X.shape[0],) and np.shape(white) == (3,)):   # the kernels index without checks
        raise ValueError(f"mean_de2000_xyz: predictions {X.shape}, ground truth {L1.shape}, out {out.shape}: "
                         "expected (P, n), (n,), (P,)")
    L = np.empty(X.shape, np.float32)
    A = np.empty(X.shape, np.float32)
    B = np.empty(X.shape, np.float32)
    xyz_to_lab_f32(X, Y, Z, white, L, A, B)
    mean_de2000_rows(L1, a1, b1, L, A, B, out)


@njit(fastmath=_FASTMATH, error_model="numpy", parallel=True, cache=True)
def de2000_lab(L1, a1, b1, L2, a2, b2, out):
    """Element-wise fast CIEDE2000 on flat float32 arrays (used to test the kernel against colour-science)."""
    for i in prange(L1.shape[0]):
        out[i] = _de2000(L1[i], a1[i], b1[i], L2[i], a2[i], b2[i])


def mean_de2000(xyz_pred: np.ndarray, white: np.ndarray, lab_true: np.ndarray) -> np.ndarray:
    """Mean CIEDE2000 per batch item: ``xyz_pred`` (P, n, 3) or three (P, n) arrays; ``lab_true`` (n, 3)."""
    X, Y, Z = (np.ascontiguousarray(xyz_pred[..., i], dtype=np.float64) for i in range(3))
    out = np.empty(X.shape[0], dtype=np.float32)
    lab = np.asarray(lab_true, dtype=np.float32)
    mean_de2000_xyz(X, Y, Z, np.asarray(white, dtype=np.float64), np.ascontiguousarray(lab[:, 0]),
                    np.ascontiguousarray(lab[:, 1]), np.ascontiguousarray(lab[:, 2]), out)
    return out.astype(np.float64)


_BLOCK = 256  # particles per block: the block's X, Y, Z, Lab scratch (8 x 256 values) stays in L1 cache


@njit(fastmath=_FASTMATH, error_model="numpy", parallel=True, cache=True)
def mean_de2000_mapped(M, RT, white, L1, a1, b1, out):
    """Fused predict -> Lab -> dE00 -> mean for a batch, vectorised across the batch.

    M (3, R, P): per-item maps from the R per-LED responses to X, Y, Z; RT (R, n): the training patches'
    per-LED responses (R = 3 * n_leds); out[p] = mean_j dE00(prediction, ground truth Lab[j]).
    No BLAS call (its worker threads fight numba's for the two cores) and no (P, n) temporaries.
    """
    R, n = RT.shape
    P = M.shape[2]
    nblocks = (P + _BLOCK - 1) // _BLOCK
    wx = f32(1.0 / white[0])
    wy = f32(1.0 / white[1])
    wz = f32(1.0 / white[2])
    for blk in prange(nblocks):
        lo = blk * _BLOCK
        hi = min(P, lo + _BLOCK)
        B = hi - lo
        Mb = M[:, :, lo:hi].astype(np.float32)    # float32 from here on: the whole block vectorises
        # rows of M that are zero for the whole block (LEDs no light in the block uses) are skipped
        active = np.empty(R, dtype=np.int64)
        n_active = 0
        for r in range(R):
            nz = False
            for i in range(B):
                if Mb[0, r, i] != 0.0 or Mb[1, r, i] != 0.0 or Mb[2, r, i] != 0.0:
                    nz = True
                    break
            if nz:
                active[n_active] = r
                n_active += 1
        X = np.empty(B, dtype=np.float32)
        Y = np.empty(B, dtype=np.float32)
        Z = np.empty(B, dtype=np.float32)
        L2 = np.empty(B, dtype=np.float32)
        A2 = np.empty(B, dtype=np.float32)
        B2 = np.empty(B, dtype=np.float32)
        acc = np.zeros(B, dtype=np.float32)
        for j in range(n):
            for i in range(B):
                X[i] = _ZERO
                Y[i] = _ZERO
                Z[i] = _ZERO
            for q in range(n_active):
                r = active[q]
                v = f32(RT[r, j])
                for i in range(B):
                    X[i] += Mb[0, r, i] * v
                for i in range(B):
                    Y[i] += Mb[1, r, i] * v
                for i in range(B):
                    Z[i] += Mb[2, r, i] * v
            for i in range(B):
                fx = _f_lab(X[i] * wx)
                fy = _f_lab(Y[i] * wy)
                fz = _f_lab(Z[i] * wz)
                L2[i] = f32(116.0) * fy - f32(16.0)
                A2[i] = f32(500.0) * (fx - fy)
                B2[i] = f32(200.0) * (fy - fz)
            Lj = L1[j]
            aj = a1[j]
            bj = b1[j]
            for i in range(B):
                acc[i] += _de2000(Lj, aj, bj, L2[i], A2[i], B2[i])
        for i in range(B):
            out[lo + i] = acc[i] / f32(n)
