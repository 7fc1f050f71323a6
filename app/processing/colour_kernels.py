"""The root-polynomial terms of one row of pixels, for the delivery's one-pass encoder (numba).

Why hand-written: the delivery applies the calibration's model to every pixel of a 24 MP original inside the
row kernels of app.processing.encode, which read each row's channel planes once while they are in the cache; a
numpy expansion would be a separate pass with a temporary per term (71 for degree 3 of 6 channels). Here each
channel's square and cube root is taken once per pixel and every term is a product of those roots
(sqrt(c_i c_j) = sqrt(c_i) sqrt(c_j)), in loops over the row that vectorise. The terms and their order are
simulation.colour_models' (its ``term_table``); the tests check the result against that numpy expansion and,
for 3 channels, colour-science's ``polynomial_expansion_Finlayson2015``.
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
    """The rows :func:`expand_row` writes: the terms (T, W), the channels' square and cube roots (2, C, W) and
    an int32 row for the cube roots' starting values."""
    return (np.empty((max(terms.shape[0], 1), W), np.float32), np.empty((2, C, W), np.float32),
            np.empty(W, np.int32))


@njit(nogil=True, cache=True, error_model="numpy")
def expand_row(S, terms, roots, seed, E):  # pragma: no cover - compiled
    """E[t] = the root-polynomial term t of the row's channel planes ``S`` (C, W): ``terms`` (T, 3) channel
    indices (-1: none); one index: the channel itself (NaN kept, as the linear model sees it), two: sqrt(c_a c_b),
    three: cbrt(c_a c_b c_c), roots of the channels clipped at 0 (NaN -> 0; the encoder counts the pixel as NaN
    from its linear terms); ``roots``, ``seed``: :func:`expansion_scratch`'s rows."""
    C, W = S.shape
    zero = np.float32(0.0)
    cubes = False
    for t in range(terms.shape[0]):
        cubes |= terms[t, 2] >= 0
    for c in range(C):
        s = S[c]
        r2 = roots[0, c]
        for j in range(W):
            v = s[j]
            r2[j] = np.sqrt(v if v > zero else zero)
        if cubes:
            _cube_roots(s, roots[1, c], seed)
    for t in range(terms.shape[0]):
        a = terms[t, 0]
        b = terms[t, 1]
        k = terms[t, 2]
        e = E[t]
        if b < 0:
            s = S[a]
            for j in range(W):
                e[j] = s[j]
        elif k < 0:
            ra = roots[0, a]
            rb = roots[0, b]
            for j in range(W):
                e[j] = ra[j] * rb[j]
        else:
            ra = roots[1, a]
            rb = roots[1, b]
            rc = roots[1, k]
            for j in range(W):
                e[j] = ra[j] * rb[j] * rc[j]



@njit(nogil=True, cache=True, error_model="numpy")
def _cube_roots(s, out, seed):  # pragma: no cover - compiled
    """out = cbrt(max(s, 0)) in float32 without a library call, so the loops vectorise (libm's cbrtf per pixel
    made the degree-3 expansion ~4x slower): Kahan's starting value from the float's bits (the exponent divided by
    3: within ~5 %), then three Newton steps y <- (2 y + p / y^2) / 3 (each squares the relative error: < 1e-7,
    float32's own precision, far below a 16-bit code); 0 for p <= 0. ``seed``: an int32 scratch row."""
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
