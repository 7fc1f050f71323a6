"""Characterisation models compared by the parsimony study (N camera channels -> XYZ).

* ``linear``: the thesis' least-squares matrix (N x 3), rank-safe (simulation.matrix_fit.fit_matrix);
* ``root-polynomial``: Finlayson, Mackiewicz & Hurlbert 2015, degree 2: the N channels and the square roots
  of all their pairwise products (6 + 15 = 21 terms for 6 channels), least squares: simulation.colour_models'
  expansion, the one the processing fits and the delivery applies (degree 3 too);
* ``de-optimised``: the N x 3 matrix minimising the mean CIEDE2000 on the training target, started from
  least squares (L-BFGS-B, forward-difference gradient evaluated as one batch); kept only if it improves.

Root-polynomial terms are homogeneous of degree 1 (exposure-invariant), like the linear model.
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab
from dualrgb.simulation.colour_models import expand
from dualrgb.simulation.matrix_fit import fit_matrix

log = logging.getLogger(__name__)

MODELS = ("linear", "de-optimised", "root-polynomial")      # simplest first
MODEL_TERMS = {"linear": lambda n: n, "de-optimised": lambda n: n, "root-polynomial": lambda n: n + n * (n - 1) // 2}


def root_polynomial_terms(values: np.ndarray) -> np.ndarray:
    """(n, N) -> (n, N + N(N-1)/2): the channels, then sqrt(c_i c_j) for i < j (negatives clipped to 0)."""
    return expand(values, 2)


@dataclass
class FittedModel:
    name: str
    matrix: np.ndarray
    expand: Callable[[np.ndarray], np.ndarray]

    def predict(self, values: np.ndarray) -> np.ndarray:
        return self.expand(np.asarray(values, dtype=float)) @ self.matrix


def _identity(v: np.ndarray) -> np.ndarray:
    return v


def fit_model(name: str, values: np.ndarray, xyz: np.ndarray, white: np.ndarray, max_iter: int = 60) -> FittedModel:
    if name == "linear":
        return FittedModel(name, fit_matrix(values, xyz).matrix, _identity)
    if name == "root-polynomial":
        return FittedModel(name, fit_matrix(root_polynomial_terms(values), xyz).matrix, root_polynomial_terms)
    if name == "de-optimised":
        return FittedModel(name, _fit_de(values, xyz, white, max_iter), _identity)
    raise ValueError(f"characterisation model {name!r}: expected one of {', '.join(MODELS)}")


def _fit_de(values: np.ndarray, xyz: np.ndarray, white: np.ndarray, max_iter: int) -> np.ndarray:
    from scipy.optimize import minimize

    values = np.asarray(values, dtype=float)
    A0 = fit_matrix(values, xyz).matrix
    norms = np.linalg.norm(values, axis=0)
    s = np.where(norms > 0, 1.0 / np.where(norms > 0, norms, 1.0), 0.0)       # equilibrate: entries O(1)
    V = values * s
    lab = xyz_to_lab(xyz, white)
    live = norms > 0
    B0 = (A0 / np.where(live, s, 1.0)[:, None])[live]                           # live rows, scaled
    Vl = V[:, live]
    shape = B0.shape
    h = 1e-6 * max(1.0, float(np.abs(B0).max()))
    eye = np.eye(B0.size) * h

    def cost(Bs: np.ndarray) -> np.ndarray:
        pred = np.einsum("nc,pcd->pnd", Vl, Bs.reshape(-1, *shape))
        return delta_e_2000(lab, xyz_to_lab(pred, white)).mean(axis=1)

    def fun_grad(b: np.ndarray) -> tuple[float, np.ndarray]:
        c = cost(np.vstack([b, b + eye]))
        return float(c[0]), (c[1:] - c[0]) / h

    start = float(cost(B0.ravel()[None])[0])
    res = minimize(fun_grad, B0.ravel(), jac=True, method="L-BFGS-B", options={"maxiter": max_iter})
    if not np.isfinite(res.fun) or res.fun >= start:
        return A0
    A = np.zeros_like(A0)
    A[live] = res.x.reshape(shape) * s[live, None]
    return A


def model_errors(model: FittedModel, values: np.ndarray, xyz: np.ndarray, white: np.ndarray) -> np.ndarray:
    return delta_e_2000(xyz_to_lab(xyz, white), xyz_to_lab(model.predict(values), white))
