"""Ground truth (eq 4.2), CIELAB and a vectorised CIEDE2000.

The CIEDE2000 kernel is written by hand because the optimisers evaluate it ~2.6e8 times per thesis-scale
PSO sweep: colour-science's ``delta_E`` (checked against in tests) allocates and converts domains on every
call, which is ~100x too slow for that. Two algebraic shortcuts avoid trigonometry where the standard
(Sharma 2005) formulation uses it, with identical results:
  * dH' = 2 sqrt(C1'C2') sin(dh'/2) = sign(a1'b2 - b1a2') * sqrt(C1'C2') * |u1 - u2| (u: unit hue vectors);
  * the mean hue h' is the direction of m = (u1 + u2) + s * rot(u2 - u1), rot turning by -90 degrees and s the
    sign of dh'. Both terms point along h1' + dh'/2 with lengths 2 cos(dh'/2) and 2 |sin(dh'/2)|, so |m| >= 2
    and the direction is well conditioned everywhere, including exactly opposite hues where u1 + u2 = 0 (the
    earlier form, the direction of u1 + u2 alone, was undefined there). This is exactly the CIE rule "average,
    +-180 when |h1 - h2| > 180" with |dh'| = 180 counted as "<= 180" (Sharma et al. 2005, pairs 10 and 14).
  * at exactly opposite hues (cross product 0) the sign of dh' is the rule's: h2' - h1' = +180 when
    h1' < 180, -180 otherwise (see ``opposite_hue_sign``).
"""
from __future__ import annotations

import numpy as np

_DELTA = 6.0 / 29.0
_DELTA3 = _DELTA**3
_25_7 = 25.0**7


def tristimulus(spectra: np.ndarray, illuminant: np.ndarray, cmfs: np.ndarray) -> np.ndarray:
    """Eq 4.2: XYZ of reflectances/transmittances (n, n_wl) under ``illuminant``; a perfect white has Y = 100."""
    k = 100.0 / float(illuminant @ cmfs[:, 1])
    return k * (np.asarray(spectra) * illuminant) @ cmfs


def white_point(illuminant: np.ndarray, cmfs: np.ndarray) -> np.ndarray:
    """XYZ of the perfect reflector under ``illuminant`` (Y = 100): the Lab reference white."""
    return tristimulus(np.ones((1, len(illuminant))), illuminant, cmfs)[0]


def _f(t: np.ndarray) -> np.ndarray:
    # cbrt above delta^3, the tangent line below it, written without a branch:
    # f(t) = cbrt(max(t, d^3)) + min(t - d^3, 0) / (3 d^2)
    return np.cbrt(np.maximum(t, _DELTA3)) + np.minimum(t - _DELTA3, 0.0) / (3 * _DELTA**2)


def xyz_to_lab(xyz: np.ndarray, white: np.ndarray) -> np.ndarray:
    """CIELAB from XYZ (same scale as ``white``), along the last axis."""
    xyz = np.asarray(xyz, dtype=float)
    fx, fy, fz = (_f(xyz[..., i] / white[i]) for i in range(3))
    return np.stack([116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz)], axis=-1)


def delta_e_2000(lab1: np.ndarray, lab2: np.ndarray) -> np.ndarray:
    """CIEDE2000 (kL = kC = kH = 1, as thesis 6.2.3) between Lab arrays with the last axis L, a, b."""
    lab1 = np.asarray(lab1, dtype=float)
    lab2 = np.asarray(lab2, dtype=float)
    return delta_e_2000_components(lab1[..., 0], lab1[..., 1], lab1[..., 2], lab2[..., 0], lab2[..., 1], lab2[..., 2])


def delta_e_2000_components(L1, a1, b1, L2, a2, b2) -> np.ndarray:
    """CIEDE2000 on separate L, a, b arrays (any broadcastable shapes, float32 or float64).

    Written with few passes over memory (in-place operations, powers by multiplication) because it is the
    optimisers' inner loop; callers keep blocks small (~10^4 elements) so the temporaries stay in cache.

    References
    ----------
    Sharma, Wu & Dalal (2005), The CIEDE2000 color-difference formula: implementation notes, supplementary test
    data, and mathematical observations; the module docstring gives the two shortcuts taken.
    """
    dt = np.result_type(L1, L2, np.float32)
    one = dt.type(1.0)
    shape = np.broadcast_shapes(*(np.shape(x) for x in (L1, a1, b1, L2, a2, b2)))
    L1, a1, b1, L2, a2, b2 = (np.atleast_1d(np.asarray(x, dtype=dt)) for x in (L1, a1, b1, L2, a2, b2))
    a1p, a2p, C1p, C2p = _compensated_chroma(a1, b1, a2, b2, dt)
    dC = C2p - C1p
    dH, h = _hue_difference(a1p, b1, a2p, b2, C1p, C2p, dt)
    Cpm = C1p + C2p
    Cpm *= 0.5
    T = _hue_weighting(h, dt)
    RT = _rotation(h, Cpm, dt)
    Lm50 = L1 + L2
    Lm50 *= 0.5
    Lm50 -= 50.0
    Lm50 *= Lm50
    SL = 0.015 * Lm50
    SL /= np.sqrt(Lm50 + 20.0)
    SL += one
    SH = Cpm * T
    SH *= 0.015
    SH += one
    Cpm *= 0.045
    Cpm += one                                     # SC
    tL = L2 - L1
    tL /= SL
    dC /= Cpm
    dH /= SH
    out = tL * tL
    out += dC * dC
    out += dH * dH
    RT *= dC
    RT *= dH
    out += RT
    np.maximum(out, 0, out=out)
    return np.sqrt(out, out=out).reshape(shape)


def _compensated_chroma(a1, b1, a2, b2, dt) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """a1', a2' (a scaled by 1 + G, G from the mean chroma) and the chromas C1', C2'."""
    C1 = np.sqrt(a1 * a1 + b1 * b1)   # (np.hypot is ~6x slower and overflow is impossible here)
    Cm = np.sqrt(a2 * a2 + b2 * b2)
    Cm += C1
    Cm *= 0.5
    np.maximum(Cm, 1e-4, out=Cm)   # keeps Cm^7 out of float32 denormals; changes G by < 1e-14
    Cm7 = Cm * Cm
    Cm7 *= Cm7            # ^4
    Cm7 *= Cm * Cm * Cm   # ^7
    g1 = Cm7 / (Cm7 + dt.type(_25_7))
    np.sqrt(g1, out=g1)
    g1 *= -0.5
    g1 += 1.5             # 1 + G
    a1p = a1 * g1
    a2p = a2 * g1
    return a1p, a2p, np.sqrt(a1p * a1p + b1 * b1), np.sqrt(a2p * a2p + b2 * b2)


def _hue_difference(a1p, b1, a2p, b2, C1p, C2p, dt) -> tuple[np.ndarray, np.ndarray]:
    """dH' (signed) and the mean hue h' in radians [0, 2 pi), by the unit hue vectors (module docstring)."""
    # |dH'| = 2 sqrt(C1'C2') sin(|dh'|/2) = sqrt(C1'C2') |u1 - u2| with u the unit hue vectors: no angles and no
    # cancellation of large terms (so float32 stays accurate); the sign of dh' is the sign of the cross product
    prod = C1p * C2p
    zero = prod == 0
    inv1 = np.divide(1.0, C1p, out=np.zeros_like(C1p), where=C1p > 0)     # u = 0 for a zero chroma
    inv2 = np.divide(1.0, C2p, out=np.zeros_like(C2p), where=C2p > 0)
    u1x, u1y, u2x, u2y = a1p * inv1, b1 * inv1, a2p * inv2, b2 * inv2
    dx = u2x - u1x
    dy = u2y - u1y
    sign = opposite_hue_sign(a1p * b2 - b1 * a2p, a1p, b1)
    dH = dx * dx
    dH += dy * dy
    dH *= prod
    np.sqrt(dH, out=dH)
    dH *= sign
    # mean hue direction (module docstring); where one chroma is zero the CIE rule h' = h1' + h2' gives the other
    # sample's hue: u of a zero chroma is 0, so u1 + u2 alone is that hue, and the rotated term must be dropped
    sign *= ~zero
    hx = u1x + u2x
    hx += sign * dy
    hy = u1y + u2y
    hy -= sign * dx
    h = np.arctan2(hy, hx)                        # radians in (-pi, pi]
    h += dt.type(2 * np.pi) * (h < 0)
    return dH, h


def _hue_weighting(h, dt) -> np.ndarray:
    """T of the hue weighting S_H, with the angles in radians (30, 6 and 63 degrees converted)."""
    T = np.cos(h - dt.type(np.pi / 6))
    T *= -0.17
    T += dt.type(1.0)
    T += 0.24 * np.cos(2 * h)
    T += 0.32 * np.cos(3 * h + dt.type(np.pi / 30))
    T -= 0.20 * np.cos(4 * h - dt.type(63 * np.pi / 180))
    return T


def _rotation(h, Cpm, dt) -> np.ndarray:
    """R_T / (dC' dH' / (S_C S_H)): the rotation term's factor -sin(2 d_theta) R_C, from h' and the mean C'."""
    x = h - dt.type(275 * np.pi / 180)
    x *= dt.type(180 / np.pi / 25)
    x *= x
    np.negative(x, out=x)
    # exp(-20) ~ 2e-9: changes dE by < 1e-8 but keeps sin() on its fast SIMD path (tiny float32
    # arguments fall back to a ~30x slower scalar path in numpy)
    np.maximum(x, -20.0, out=x)
    d_theta = np.exp(x)                           # /30 degrees
    d_theta *= dt.type(np.pi / 3)                 # 2 * dtheta in radians = 2*30*exp(..)*pi/180
    RT = np.sin(d_theta)
    Cpc = np.maximum(Cpm, 1e-4)
    Cpm7 = Cpc * Cpc
    Cpm7 *= Cpm7
    Cpm7 *= Cpc * Cpc * Cpc
    RC = Cpm7 / (Cpm7 + dt.type(_25_7))
    np.sqrt(RC, out=RC)
    RT *= RC
    RT *= -2.0
    return RT


def opposite_hue_sign(cross, a1p, b1):
    """Sign of dh' = h2' - h1' per the CIE rule, from the cross product a1'b2 - b1a2' (= C1'C2' sin dh').

    Where the cross product is exactly 0 (equal or exactly opposite hues) the rule counts |h2' - h1'| = 180 as
    "<= 180", so dh' = +180 when h1' is in [0, 180) (b1 > 0, or b1 = 0 and a1' > 0) and -180 otherwise.
    """
    upper = (b1 > 0) | ((b1 == 0) & (a1p > 0))
    tie = np.where(upper, 1.0, -1.0).astype(np.result_type(cross), copy=False)
    return np.where(cross > 0, 1.0, np.where(cross < 0, -1.0, tie)).astype(np.result_type(cross), copy=False)
