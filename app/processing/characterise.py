"""Characterisation of a capture: camera values of the training target -> XYZ matrix, two ways, validated.

* ``least-squares``: the thesis' Moore-Penrose fit (eqs 5.2-5.6) via ``simulation.matrix_fit.fit_matrix``
  (rank-safe: an all-zero channel gets a zero row).
* ``de2000``: the matrix that minimises the *mean CIEDE2000* on the training target (eq 5.7 used as the cost),
  as Beyond RGB does: start from the least-squares matrix and minimise with a quasi-Newton method
  (``scipy.optimize.minimize``, BFGS, batched forward-difference gradients; the parameters are the matrix entries
  with equilibrated channels so all are O(1)). The result is never worse than its start on the training set:
  if the optimiser does not improve, the least-squares matrix is kept (and the method is still reported).

``characterise(...)`` fits both on the training target and chooses the delivered matrix (``best``) by k-fold
cross-validation on the training target alone (``select_model``: each training patch predicted by the matrix
fitted without its fold; the lower mean CIEDE2000 wins, least squares on a tie). The training set's own error
cannot choose (the dE00-optimised matrix always fits it better), and the test target must not: choosing by the
test error would bias the reported test error optimistically. The test target is only evaluated, after the
choice; both methods' errors on training and test targets use the float64 reference
``simulation.colorimetry.delta_e_2000``.
"""
from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab
from dualrgb.simulation.cross_validation import CV_FOLDS, fold_parts
from dualrgb.simulation.matrix_fit import CharacterisationMatrix, fit_matrix
from dualrgb.simulation.objective import ErrorStats

log = logging.getLogger(__name__)

LEAST_SQUARES = "least-squares"
DE2000 = "de2000"


def patch_errors(matrix: CharacterisationMatrix | np.ndarray, values: np.ndarray, xyz: np.ndarray,
                 white: np.ndarray) -> np.ndarray:
    """Per-patch CIEDE2000 between reference ``xyz`` and ``values @ matrix`` (Lab relative to ``white``)."""
    A = matrix.matrix if isinstance(matrix, CharacterisationMatrix) else np.asarray(matrix, dtype=float)
    pred = np.asarray(values, dtype=float) @ A
    return delta_e_2000(xyz_to_lab(np.asarray(xyz, dtype=float), white), xyz_to_lab(pred, white))


def fit_least_squares(values: np.ndarray, xyz: np.ndarray, channels: list[str] | None = None
                      ) -> CharacterisationMatrix:
    m = fit_matrix(values, xyz, channels)
    m.method = LEAST_SQUARES
    return m


def _batch_mean_de2000(V: np.ndarray, lab_ref: np.ndarray, white: np.ndarray, scale: float
                       ) -> Callable[[np.ndarray], np.ndarray]:
    """Mean dE00 of a batch of parameter vectors (k, n_params) in one vectorised pass: each is a matrix for the
    equilibrated values ``V`` (n, channels), divided by ``scale``."""
    def costs(P: np.ndarray) -> np.ndarray:
        B = P.reshape(P.shape[0], -1, 3) * scale
        pred = np.einsum("nc,kcj->knj", V, B)
        return delta_e_2000(lab_ref[None], xyz_to_lab(pred, white)).mean(axis=1)

    return costs


def fit_de2000(values: np.ndarray, xyz: np.ndarray, white: np.ndarray, channels: list[str] | None = None, *,
               start: CharacterisationMatrix | None = None, max_iter: int = 500,
               progress: ProgressCallback | None = None, cancel: CancelToken | None = None
               ) -> CharacterisationMatrix:
    """The matrix minimising mean CIEDE2000 on (values, xyz), started from least squares (or ``start``)."""
    values = np.asarray(values, dtype=float)
    xyz = np.asarray(xyz, dtype=float)
    start = start or fit_least_squares(values, xyz, channels)
    A0 = start.matrix
    norms = np.linalg.norm(values, axis=0)
    live = norms > 0
    s = np.where(live, 1.0 / np.where(live, norms, 1.0), 0.0)     # equilibrate channels
    B0 = A0[live] / s[live, None]
    scale = float(np.sqrt(np.mean(B0 ** 2))) or 1.0
    costs = _batch_mean_de2000((values * s)[:, live], xyz_to_lab(xyz, white), white, scale)   # columns of unit norm
    n_eval = [0]

    def cost(p: np.ndarray) -> float:
        return float(costs(p[None])[0])

    def cost_and_grad(p: np.ndarray) -> tuple[float, np.ndarray]:
        # forward differences, all perturbed matrices evaluated in one batch (~20x fewer numpy calls)
        n_eval[0] += 1
        if n_eval[0] % 50 == 0:
            check(cancel)
        h = 1e-6 * max(1.0, float(np.abs(p).max()))
        P = np.vstack([p, p + h * np.eye(p.size)])
        c = costs(P)
        return float(c[0]), (c[1:] - c[0]) / h

    p0 = (B0 / scale).ravel()
    c0 = cost(p0)
    it = [0]

    def callback(xk: np.ndarray) -> None:     # scipy passes the iterate (unused: only the count)
        it[0] += 1
        check(cancel)
        report(progress, min(it[0] / max_iter, 1.0), f"dE00 optimisation, iteration {it[0]}")

    res = optimize.minimize(cost_and_grad, p0, jac=True, method="BFGS", callback=callback,
                            options={"maxiter": max_iter, "gtol": 1e-7})
    p = res.x if res.fun < c0 else p0
    A = np.zeros_like(A0)
    A[live] = p.reshape(-1, 3) * scale * s[live, None]
    final = cost(p)
    log.info("dE00-optimised matrix: train mean dE00 %.4f -> %.4f (%d evaluations, %s)", c0, final, n_eval[0],
             res.message if isinstance(res.message, str) else res.message)
    report(progress, 1.0, "dE00 optimisation done")
    return CharacterisationMatrix(A, list(start.channels), DE2000)


@dataclass
class MethodResult:
    matrix: CharacterisationMatrix
    train_errors: np.ndarray
    test_errors: np.ndarray | None = None

    @property
    def train(self) -> ErrorStats:
        return ErrorStats.of(self.train_errors)

    @property
    def test(self) -> ErrorStats | None:
        return None if self.test_errors is None else ErrorStats.of(self.test_errors)

    def errors(self, target: str) -> np.ndarray:
        """dE00 per patch on ``target`` ('train' or 'test'); ``ValueError`` for a test target not evaluated."""
        errors = self.train_errors if target == "train" else self.test_errors
        if errors is None:
            raise ValueError(f"no errors on the {target} target: it was not evaluated")
        return errors

    def stats(self, target: str) -> ErrorStats:
        """The statistics of :meth:`errors`."""
        return ErrorStats.of(self.errors(target))

    def to_dict(self) -> dict:
        return {"matrix": self.matrix.to_dict(), "train": self.train.to_dict(),
                "test": self.test.to_dict() if self.test else None}


@dataclass
class ModelSelection:
    """Which matrix is delivered and why: mean cross-validated dE00 per method on the training target."""

    chosen: str
    cv_mean: dict[str, float]
    folds: int

    @property
    def reason(self) -> str:
        if len(self.cv_mean) < 2:
            return f"only {self.chosen} was fitted"
        return f"lowest mean dE00 in {self.folds}-fold cross-validation on the training target"

    def to_dict(self) -> dict:
        return {"chosen": self.chosen, "criterion": self.reason, "folds": self.folds,
                "cv_mean_de00": {k: round(v, 4) for k, v in self.cv_mean.items()}}


def _fitters(white: np.ndarray, channels: list[str], optimise: bool, cancel: CancelToken | None) -> dict:
    fits = {LEAST_SQUARES: lambda v, x: fit_least_squares(v, x, channels)}
    if optimise:
        fits[DE2000] = lambda v, x: fit_de2000(v, x, white, channels, cancel=cancel)
    return fits


def select_model(train_values: np.ndarray, train_xyz: np.ndarray, white: np.ndarray, channels: list[str], *,
                 optimise: bool = True, folds: int = CV_FOLDS, seed: int = 0,
                 progress: ProgressCallback | None = None, cancel: CancelToken | None = None
                 ) -> ModelSelection:
    """Choose the matrix method by k-fold cross-validation on the training target (it never sees a test target:
    none is passed). Folds are a seeded random partition; each patch's error comes from a fit without it."""
    fitters = _fitters(white, channels, optimise, cancel)
    if len(fitters) == 1:
        return ModelSelection(LEAST_SQUARES, {}, 0)
    values = np.asarray(train_values, dtype=float)
    xyz = np.asarray(train_xyz, dtype=float)
    n = len(values)
    parts = fold_parts(n, folds, seed)            # the partition rule the studies choose their defaults with
    k = len(parts)
    errors = {m: np.empty(n) for m in fitters}
    for i, held in enumerate(parts):
        check(cancel)
        keep = np.setdiff1d(np.arange(n), held)
        for m, fit in fitters.items():
            errors[m][held] = patch_errors(fit(values[keep], xyz[keep]), values[held], xyz[held], white)
        report(progress, (i + 1) / k, f"cross-validation fold {i + 1} of {k}")
    cv = {m: float(e.mean()) for m, e in errors.items()}
    chosen = min(cv, key=lambda m: (cv[m], m != LEAST_SQUARES))
    return ModelSelection(chosen, cv, k)


@dataclass
class Characterisation:
    """Both fits with their per-patch errors; ``best`` is the delivered one, chosen on the training target
    (``selection``); test errors are reported, never used to choose."""

    results: dict[str, MethodResult]
    white: np.ndarray
    channels: list[str] = field(default_factory=list)
    selection: ModelSelection | None = None

    @property
    def best(self) -> str:
        if self.selection is not None:
            return self.selection.chosen
        return LEAST_SQUARES if LEAST_SQUARES in self.results else next(iter(self.results))

    @property
    def matrix(self) -> CharacterisationMatrix:
        return self.results[self.best].matrix

    def to_dict(self) -> dict:
        return {"best": self.best, "selection": self.selection.to_dict() if self.selection else None,
                "white": self.white.tolist(), "channels": self.channels,
                "methods": {k: v.to_dict() for k, v in self.results.items()}}


def characterise(train_values: np.ndarray, train_xyz: np.ndarray, white: np.ndarray,
                 test_values: np.ndarray | None = None, test_xyz: np.ndarray | None = None,
                 channels: Sequence[str] | None = None, *, optimise: bool = True,
                 progress: ProgressCallback | None = None, cancel: CancelToken | None = None
                 ) -> Characterisation:
    """Fit least squares and (``optimise``) the dE00-optimised matrix, choose one by cross-validation on the
    training target (``select_model``), then evaluate both on train and test."""
    train_values = np.asarray(train_values, dtype=float)
    white = np.asarray(white, dtype=float)
    channels = list(channels) if channels else [f"ch{i + 1}" for i in range(train_values.shape[1])]
    bad = ~np.isfinite(train_values).all(axis=1)
    if bad.any():
        raise ValueError(f"training patches {', '.join(str(i + 1) for i in np.flatnonzero(bad)[:10])} have no "
                         f"valid camera values (NaN): check the patch grid and the flat field")
    report(progress, 0.0, "least-squares fit")
    fits = {LEAST_SQUARES: fit_least_squares(train_values, train_xyz, channels)}
    if optimise:
        check(cancel)
        sub = None if progress is None else (lambda f, m: progress(0.05 + 0.45 * f, m))
        fits[DE2000] = fit_de2000(train_values, train_xyz, white, channels, start=fits[LEAST_SQUARES],
                                  progress=sub, cancel=cancel)
    cv = None if progress is None else (lambda f, m: progress(0.5 + 0.45 * f, m))
    selection = select_model(train_values, train_xyz, white, channels, optimise=optimise, progress=cv, cancel=cancel)
    results = {}
    for name, m in fits.items():                   # evaluation only: the choice above is already made
        te = None
        if test_values is not None and test_xyz is not None:
            te = patch_errors(m, test_values, test_xyz, white)
        results[name] = MethodResult(m, patch_errors(m, train_values, train_xyz, white), te)
    out = Characterisation(results, white, channels, selection)
    for name, r in results.items():
        log.info("%s: train mean dE00 %.3f%s%s", name, r.train.mean,
                 f", cross-validated {selection.cv_mean[name]:.3f}" if name in selection.cv_mean else "",
                 f", test mean {r.test.mean:.3f}" if r.test else "")
    report(progress, 1.0, f"characterised; delivered {out.best} ({selection.reason})")
    return out
