"""Characterisation: the matrix A of eqs 5.2-5.4 / 5.11-5.14 mapping N-channel camera values to XYZ.

Least squares as the thesis (Moore-Penrose, eq 5.4), rank-safe: a single fit uses SVD least squares (the
pseudo-inverse; an all-zero channel from an LED clipped to 0 or a light switched off gets a zero row, never
a singular system or NaN). The batched form the optimisers use solves the normal equations from precomputed
Gram matrices with columns equilibrated (unit norm) and a tiny ridge; it equals the pseudo-inverse to ~1e-6
for well-conditioned light sets and stays finite for degenerate ones.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from dualrgb.simulation.colour_models import expand, expansion_jacobian, n_terms, noise_gain

log = logging.getLogger(__name__)

RIDGE = 1e-12  # relative to the equilibrated diagonal (= 1): regularises only singular values below ~1e-6


class CharacterisationError(ValueError):
    """The training data cannot define a characterisation (e.g. fewer patches than channels)."""


@dataclass
class CharacterisationMatrix:
    """XYZ = terms(values) @ matrix: ``degree`` 1 (linear) maps the channels themselves, ``matrix`` (n_channels, 3);
    a root-polynomial of ``degree`` 2 or 3 (simulation.colour_models) maps its terms, ``matrix`` (n_terms, 3)."""

    matrix: np.ndarray
    channels: list[str] = field(default_factory=list)
    method: str = "least-squares"
    degree: int = 1

    @property
    def n_channels(self) -> int:
        """Camera channels the model takes (the matrix's rows for a linear model)."""
        return len(self.channels) if self.channels else self.matrix.shape[0]

    def apply(self, values: np.ndarray) -> np.ndarray:
        values = np.asarray(values, dtype=float)
        if values.shape[-1] != self.n_channels:
            raise ValueError(f"characterisation expects {self.n_channels} channels, got {values.shape[-1]}")
        return expand(values, self.degree) @ self.matrix

    def jacobian(self, values: np.ndarray) -> np.ndarray:
        """d XYZ / d channels at ``values`` (..., C) -> (..., C, 3)."""
        v = np.asarray(values, dtype=float)
        if self.degree == 1:
            return np.broadcast_to(self.matrix, v.shape[:-1] + self.matrix.shape).copy()
        return np.einsum("...tc,ta->...ca", expansion_jacobian(v, self.degree), self.matrix)

    def noise_gain(self) -> np.ndarray:
        """(X, Y, Z) noise gain at the flat-fielded white (simulation.colour_models.noise_gain)."""
        return noise_gain(self.jacobian(np.ones(self.n_channels)))

    def to_dict(self) -> dict:
        return {"matrix": self.matrix.round(10).tolist(), "channels": self.channels, "method": self.method,
                "degree": self.degree}

    @classmethod
    def from_dict(cls, data: dict) -> CharacterisationMatrix:
        return cls(np.asarray(data["matrix"], dtype=float), list(data.get("channels", [])),
                   data.get("method", "least-squares"), int(data.get("degree", 1)))


def _check_patches(n_patches: int, n_channels: int) -> None:
    if n_patches < n_channels:
        raise CharacterisationError(
            f"training target has {n_patches} patches but the fit needs at least {n_channels} (one per channel)"
        )


def solve_normal_equations(CtC: np.ndarray, CtB: np.ndarray) -> np.ndarray:
    """Rank-safe batched least squares from normal equations: CtC (P, n, n), CtB (P, n, 3) -> A (P, n, 3).

    Columns are equilibrated (unit diagonal) and RIDGE added; an all-zero channel gets a zero row. The same
    rules as the optimisers' numba kernel (simulation.fast_linalg.fit_light_sets), with LAPACK, for callers
    that solve a handful of systems at a time.
    """
    d = np.einsum("pii->pi", CtC)
    s = np.where(d > 0, 1.0 / np.sqrt(np.where(d > 0, d, 1.0)), 0.0)
    M = CtC * s[:, :, None] * s[:, None, :]
    n = M.shape[1]
    M[:, np.arange(n), np.arange(n)] += RIDGE + (d <= 0)
    return np.linalg.solve(M, CtB * s[:, :, None]) * s[:, :, None]


def fit_matrix(values: np.ndarray, xyz: np.ndarray, channels: list[str] | None = None) -> CharacterisationMatrix:
    """Least-squares characterisation of one capture: values (n_patches, n_channels), xyz (n_patches, 3)."""
    values = np.asarray(values, dtype=float)
    xyz = np.asarray(xyz, dtype=float)
    if values.ndim != 2 or xyz.shape != (values.shape[0], 3):
        raise ValueError(f"values {values.shape} and xyz {xyz.shape} do not describe the same patches")
    if not (np.isfinite(values).all() and np.isfinite(xyz).all()):
        raise CharacterisationError("camera values or XYZ contain NaN or infinity")
    _check_patches(*values.shape)
    # SVD least squares = the Moore-Penrose solution of eq 5.4; the minimum-norm answer gives a zero row for
    # an all-zero channel, so rank deficiency is safe here too
    A = np.linalg.lstsq(values, xyz, rcond=None)[0]
    return CharacterisationMatrix(A, channels or [f"ch{i + 1}" for i in range(values.shape[1])])


def fit_root_polynomial(values: np.ndarray, xyz: np.ndarray, degree: int, channels: list[str] | None = None
                        ) -> CharacterisationMatrix:
    """Least squares on the root-polynomial terms of ``degree`` (simulation.colour_models; Finlayson et al. 2015),
    rank-safe as :func:`fit_matrix`."""
    values = np.asarray(values, dtype=float)
    if values.ndim != 2:
        raise ValueError(f"values {values.shape}: expected (n_patches, n_channels)")
    _check_patches(values.shape[0], n_terms(values.shape[1], degree))
    m = fit_matrix(expand(values, degree), xyz)
    return CharacterisationMatrix(m.matrix, channels or [f"ch{i + 1}" for i in range(values.shape[1])],
                                  f"root-polynomial-{degree}", degree)
