"""The root-polynomial models applied to one row of pixels, for the delivery's one-pass encoder (numba).

Why hand-written: the delivery applies the calibration's model to every pixel of a 24 MP original inside the
row kernels of app.processing.encode, which read each row's channel planes once while they are in the cache; a
numpy expansion would be a separate pass with a temporary per term (71 for degree 3 of 6 channels). Here each
channel's square and cube root is taken once per pixel (the cube root without a library call: :func:`_cube_roots`)
and every term is a product of those roots (sqrt(c_i c_j) = sqrt(c_i) sqrt(c_j)), made two terms at a time over the
row and added at once into X, Y and Z (a loop over the row per pair of terms that vectorises; a loop per pixel over
71 terms did not: 4x slower; one term per loop, through a row of its own, was 1.4x (degree 2) to 1.6x (degree 3)
slower for the same bits: each pixel's sums take the terms in the same order). The terms and their order are
simulation.colour_models' (its ``term_table``); the tests check the result against that numpy expansion, itself
checked against colour-science's ``polynomial_expansion_Finlayson2015``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from dualrgb.simulation.colour_models import term_table

LINEAR_TERMS = np.empty((0, 3), dtype=np.int64)      # no expansion: the model maps the channels themselves


def terms_for(n_channels: int, degree: int) -> np.ndarray:
    """The kernel's (T, 3) term table for a model of ``degree`` (:data:`LINEAR_TERMS` for degree 1)."""
    return LINEAR_TERMS if degree == 1 else term_table(n_channels, degree)


@njit(nogil=True, cache=True, error_model="numpy")
def expansion_scratch(terms, C, W):  # pragma: no cover - compiled
    """The rows :func:`root_polynomial_xyz_row` works in: one table (3 C + 1, W) of the channels with NaN as 0,
    their square roots, their cube roots and a row of ones (one array, so that the loops over the row have one
    source to check against their outputs, and vectorise); the roots' part as (2, C, W); an int32 row for the cube
    roots' starting values (minimal when the model is linear)."""
    n = W if terms.shape[0] else 1
    c = C if terms.shape[0] else 1
    table = np.empty((3 * c + 1, n), np.float32)
    return table, table[c: 3 * c].reshape((2, c, n)), np.empty(n, np.int32)


@njit(nogil=True, cache=True, error_model="numpy")
def _cube_roots(s, out, seed):  # pragma: no cover - compiled
    """out = cbrt(max(s, 0)) in float32 without a library call, so the loops vectorise (libm's cbrtf per pixel
    made the degree-3 expansion ~4x slower): Kahan's starting value from the float's bits (the exponent divided by
    3: within ~5 %), then three Newton steps y <- (2 y + p / y^2) / 3 (each squares the relative error: < 1e-7,
    float32's own precision, far below a 16-bit code); 0 for p <= 0 and NaN. ``seed``: an int32 scratch row."""
    zero = np.float32(0.0)
    third = np.float32(1.0 / 3.0)
    two = np.float32(2.0)
    for j in range(s.shape[0]):
        v = s[j]
        out[j] = v if v > zero else zero
    bits = out.view(np.int32)
    for j in range(s.shape[0]):
        seed[j] = bits[j] // np.int32(3) + np.int32(709921077)
    y0 = seed.view(np.float32)
    for j in range(s.shape[0]):
        p = out[j]
        y = y0[j]
        y = (two * y + p / (y * y)) * third
        y = (two * y + p / (y * y)) * third
        y = (two * y + p / (y * y)) * third
        out[j] = y if p > zero else zero


@njit(nogil=True, cache=True, error_model="numpy")
def _roots(S, terms, roots, seed):  # pragma: no cover - compiled
    """roots[0, c] = sqrt(max(S[c], 0)), and roots[1, c] = its cube root when a term of degree 3 needs it."""
    zero = np.float32(0.0)
    cubes = False
    for t in range(terms.shape[0]):
        cubes |= terms[t, 2] >= 0
    for c in range(S.shape[0]):
        s = S[c]
        r2 = roots[0, c]
        for j in range(S.shape[1]):
            v = s[j]
            r2[j] = np.sqrt(v if v > zero else zero)
        if cubes:
            _cube_roots(s, roots[1, c], seed)


@njit(nogil=True, cache=True, error_model="numpy")
def term_row(S, terms, t, roots, e):  # pragma: no cover - compiled
    """e = term ``t`` over the row: the channel itself (NaN -> 0, as the linear encoder takes it), sqrt(c_a c_b)
    or cbrt(c_a c_b c_c) from the channels' roots (clipped at 0)."""
    zero = np.float32(0.0)
    a = terms[t, 0]
    b = terms[t, 1]
    k = terms[t, 2]
    if b < 0:
        s = S[a]
        for j in range(e.shape[0]):
            v = s[j]
            e[j] = zero if v != v else v
    elif k < 0:
        ra = roots[0, a]
        rb = roots[0, b]
        for j in range(e.shape[0]):
            e[j] = ra[j] * rb[j]
    else:
        ra = roots[1, a]
        rb = roots[1, b]
        rc = roots[1, k]
        for j in range(e.shape[0]):
            e[j] = ra[j] * rb[j] * rc[j]


@njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _factors(terms, t, C):  # pragma: no cover - compiled
    """Rows of :func:`expansion_scratch`'s table whose product is term ``t``: the channel (NaN as 0) x 1 x 1,
    sqrt(c_a) sqrt(c_b) x 1 or cbrt(c_a) cbrt(c_b) cbrt(c_c) (x 1 is exact: the products are :func:`term_row`'s,
    in its order)."""
    a = terms[t, 0]
    b = terms[t, 1]
    k = terms[t, 2]
    if b < 0:
        return a, 3 * C, 3 * C
    if k < 0:
        return C + a, C + b, 3 * C
    return 2 * C + a, 2 * C + b, 2 * C + k


@njit(nogil=True, cache=True, error_model="numpy")
def root_polynomial_xyz_row(S, terms, A, ex, x, y, z):  # pragma: no cover - compiled
    """x, y, z of one row (``S`` (C, W): one plane per channel) through the root-polynomial ``terms`` (T, 3) and
    its matrix ``A`` (T, 3) float32; ``ex``: :func:`expansion_scratch`'s rows. Returns the pixels with a NaN
    channel (taken as 0), as the linear encoder counts them."""
    table, roots, seed = ex
    C, W = S.shape
    zero = np.float32(0.0)
    _roots(S, terms, roots, seed)
    for c in range(C):
        s = S[c]
        cl = table[c]
        for j in range(W):
            v = s[j]
            cl[j] = zero if v != v else v
    ones = table[3 * C]
    for j in range(W):
        ones[j] = np.float32(1.0)
        x[j] = zero
        y[j] = zero
        z[j] = zero
    T = terms.shape[0]
    for t in range(0, T - 1, 2):                      # two terms per pass over the row, added in term order
        i1, j1, k1 = _factors(terms, t, C)
        i2, j2, k2 = _factors(terms, t + 1, C)
        p1, q1, r1, p2, q2, r2 = table[i1], table[j1], table[k1], table[i2], table[j2], table[k2]
        a0, a1, a2 = A[t, 0], A[t, 1], A[t, 2]
        b0, b1, b2 = A[t + 1, 0], A[t + 1, 1], A[t + 1, 2]
        for j in range(W):
            e1 = p1[j] * q1[j] * r1[j]
            e2 = p2[j] * q2[j] * r2[j]
            x[j] = x[j] + e1 * a0 + e2 * b0
            y[j] = y[j] + e1 * a1 + e2 * b1
            z[j] = z[j] + e1 * a2 + e2 * b2
    if T % 2:
        i1, j1, k1 = _factors(terms, T - 1, C)
        p1, q1, r1 = table[i1], table[j1], table[k1]
        a0, a1, a2 = A[T - 1, 0], A[T - 1, 1], A[T - 1, 2]
        for j in range(W):
            e1 = p1[j] * q1[j] * r1[j]
            x[j] = x[j] + e1 * a0
            y[j] = y[j] + e1 * a1
            z[j] = z[j] + e1 * a2
    bad = 0
    for j in range(W):
        nan = False
        for c in range(C):
            nan |= S[c, j] != S[c, j]
        bad += nan
    return bad


@njit(nogil=True, cache=True, error_model="numpy")
def expand_row(S, terms, roots, seed, E):  # pragma: no cover - compiled
    """E[t] = every term of the row (the same terms :func:`root_polynomial_xyz_row` adds; a check and a tool)."""
    _roots(S, terms, roots, seed)
    for t in range(terms.shape[0]):
        term_row(S, terms, t, roots, E[t])
