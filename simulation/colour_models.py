"""Characterisation models beyond the linear matrix: root-polynomial (Finlayson, Mackiewicz & Hurlbert 2015) for N
camera channels, and the figures that say how a model treats single pixels (noise gain, conditioning).

Root-polynomial of degree D: every monomial of the channels of total degree d = 1..D raised to 1/d, leaving out
the pure powers (c_i^d)^(1/d) = c_i that repeat a linear term. For 3 channels this is exactly colour-science's
``polynomial_expansion_Finlayson2015(RGB, D, root_polynomial_expansion=True)`` (6 terms at D = 2, 13 at D = 3;
the tests check it against that function and ``matrix_colour_correction_Finlayson2015``); colour-science expands
3 channels only, hence this expansion for the 6 channels of dual-RGB: 21 terms at D = 2, 71 at D = 3. Every term is
homogeneous of degree 1, so the model is exposure-invariant like the linear matrix: k c -> k XYZ. Roots are
taken of the channels clipped at 0 (a dark pixel's noise may go below 0; colour-science would give NaN there),
the linear terms keep their sign. Terms are products of per-channel roots, sqrt(c_i c_j) = sqrt(c_i) sqrt(c_j),
so a pixel costs N square roots and N cube roots whatever D (the delivery's kernel, app.processing.colour_kernels,
computes them the same way).

Noise gain of a model: its Jacobian J (C, 3) at the flat-fielded white (every channel 1), per output
  g = ||J[:, o]||_2 sqrt(C) / |sum_c J[c, o]|,
the noise of that output from independent channels of equal noise, relative to the least-noisy combination with
the same response to the white (equal weights; Cauchy-Schwarz: g >= 1). A linear matrix's J is the matrix itself.

Condition number of a light set on a target: the 2-norm condition number of its (n_patches, C) camera values with
columns scaled to unit norm (equilibrated: invariant to each channel's gain, so flat-fielding does not change it);
infinite when two channels are proportional (a light that is another one dimmed).

References: G. D. Finlayson, M. Mackiewicz, A. Hurlbert, "Color correction using root-polynomial regression",
IEEE Trans. Image Processing 24(5), 2015; colour-science ``colour.characterisation``.
"""
from __future__ import annotations

import logging
from functools import lru_cache
from itertools import combinations_with_replacement

import numpy as np

log = logging.getLogger(__name__)

MAX_DEGREE = 3


@lru_cache(maxsize=32)
def root_polynomial_terms(n_channels: int, degree: int) -> tuple[tuple[int, ...], ...]:
    """The terms of a root-polynomial of ``degree`` in ``n_channels`` channels: one tuple of channel indices per
    term (its length is the term's degree d; the term is the product of those channels to the power 1/d)."""
    if not 1 <= degree <= MAX_DEGREE:
        raise ValueError(f"root-polynomial degree {degree}: expected 1 to {MAX_DEGREE}")
    if n_channels < 1:
        raise ValueError(f"root-polynomial of {n_channels} channels: expected at least 1")
    out: list[tuple[int, ...]] = []
    for d in range(1, degree + 1):
        out += [t for t in combinations_with_replacement(range(n_channels), d) if d == 1 or len(set(t)) > 1]
    return tuple(out)


def n_terms(n_channels: int, degree: int) -> int:
    return len(root_polynomial_terms(n_channels, degree))


def term_table(n_channels: int, degree: int) -> np.ndarray:
    """(T, 3) int64: each term's channel indices, -1 where the term has fewer than 3 (the delivery kernel's
    layout)."""
    terms = root_polynomial_terms(n_channels, degree)
    table = np.full((len(terms), 3), -1, dtype=np.int64)
    for k, t in enumerate(terms):
        table[k, :len(t)] = t
    return table


def term_names(channels: list[str], degree: int) -> list[str]:
    """Readable names: 'R1', 'sqrt(R1*G1)', 'cbrt(R1*R1*G2)'."""
    names = []
    for t in root_polynomial_terms(len(channels), degree):
        inner = "*".join(channels[i] for i in t)
        names.append(inner if len(t) == 1 else f"{'sqrt' if len(t) == 2 else 'cbrt'}({inner})")
    return names


def expand(values: np.ndarray, degree: int) -> np.ndarray:
    """(..., C) channel values -> (..., T) root-polynomial terms (float64); degree 1 returns the values."""
    v = np.asarray(values, dtype=float)
    if degree == 1:
        return v
    pos = np.clip(v, 0.0, None)
    roots = {2: np.sqrt(pos), 3: np.cbrt(pos)}
    cols = []
    for t in root_polynomial_terms(v.shape[-1], degree):
        if len(t) == 1:
            cols.append(v[..., t[0]])
            continue
        r = roots[len(t)]
        term = r[..., t[0]]
        for i in t[1:]:
            term = term * r[..., i]
        cols.append(term)
    return np.stack(cols, axis=-1)


def expansion_jacobian(values: np.ndarray, degree: int) -> np.ndarray:
    """d terms / d channels at ``values`` (..., C) -> (..., T, C): for a term prod c_k^(e_k/d), (e_m/d) term / c_m
    (0 where c_m <= 0, where the clipped root is flat)."""
    v = np.asarray(values, dtype=float)
    C = v.shape[-1]
    terms = root_polynomial_terms(C, degree)
    E = expand(v, degree)
    J = np.zeros(v.shape[:-1] + (len(terms), C))
    safe = np.where(v > 0, v, 1.0)
    for k, t in enumerate(terms):
        if len(t) == 1:
            J[..., k, t[0]] = 1.0
            continue
        for m in set(t):
            J[..., k, m] = np.where(v[..., m] > 0, t.count(m) / len(t) * E[..., k] / safe[..., m], 0.0)
    return J


def noise_gain(jacobian: np.ndarray) -> np.ndarray:
    """Per output (3,): ||J[:, o]|| sqrt(C) / |sum_c J[c, o]| of a model's Jacobian (C, 3) at the white (module
    docstring); inf for an output the white does not reach."""
    J = np.asarray(jacobian, dtype=float)
    total = np.abs(J.sum(axis=0))
    norm = np.linalg.norm(J, axis=0) * np.sqrt(J.shape[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(total > 0, norm / np.where(total > 0, total, 1.0), np.inf)


def condition_number(values: np.ndarray) -> float:
    """2-norm condition number of (n, C) camera values with unit-norm columns (module docstring); inf when a
    channel is all zero or channels are proportional."""
    v = np.asarray(values, dtype=float)
    norms = np.linalg.norm(v, axis=0)
    if v.ndim != 2 or v.shape[0] < v.shape[1] or not np.all(norms > 0) or not np.isfinite(v).all():
        return float("inf")
    s = np.linalg.svd(v / norms, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > s[0] * np.finfo(float).eps * max(v.shape) else float("inf")


def weakest_direction(values: np.ndarray) -> np.ndarray:
    """The unit combination of the equilibrated channels (C,) the values come nearest to cancelling (the right
    singular vector of the smallest singular value): where a near-collinear set's channels are tied."""
    v = np.asarray(values, dtype=float)
    norms = np.linalg.norm(v, axis=0)
    return np.linalg.svd(v / np.where(norms > 0, norms, 1.0), full_matrices=False)[2][-1]
