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

log = logging.getLogger(__name__)

RIDGE = 1e-12  # relative to the equilibrated diagonal (= 1): regularises only singular values below ~1e-6


class CharacterisationError(ValueError):
    """The training data cannot define a characterisation (e.g. fewer patches than channels)."""


@dataclass
class CharacterisationMatrix:
    """XYZ = values @ matrix; ``matrix`` has shape (n_channels, 3)."""

    matrix: np.ndarray
    channels: list[str] = field(default_factory=list)
    method: str = "least-squares"

    def apply(self, values: np.ndarray) -> np.ndarray:
        values = np.asarray(values, dtype=float)
        if values.shape[-1] != self.matrix.shape[0]:
            raise ValueError(f"characterisation expects {self.matrix.shape[0]} channels, got {values.shape[-1]}")
        return values @ self.matrix

    def to_dict(self) -> dict:
        return {"matrix": self.matrix.round(10).tolist(), "channels": self.channels, "method": self.method}

    @classmethod
    def from_dict(cls, data: dict) -> CharacterisationMatrix:
        return cls(np.asarray(data["matrix"], dtype=float), list(data.get("channels", [])),
                   data.get("method", "least-squares"))


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
