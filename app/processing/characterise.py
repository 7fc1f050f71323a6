"""Characterisation of a capture: camera values of the training target -> XYZ, four models, chosen by the scene.

* ``least-squares``: the thesis' Moore-Penrose fit (eqs 5.2-5.6) via ``simulation.matrix_fit.fit_matrix``
  (rank-safe: an all-zero channel gets a zero row).
* ``de2000``: the matrix that minimises the *mean CIEDE2000* on the training target (eq 5.7 used as the cost),
  as Beyond RGB does: start from the least-squares matrix and minimise with a quasi-Newton method
  (``scipy.optimize.minimize``, BFGS, batched forward-difference gradients; the parameters are the matrix entries
  with equilibrated channels so all are O(1)). The result is never worse than its start on the training set:
  if the optimiser does not improve, the least-squares matrix is kept (and the method is still reported).
* ``root-polynomial-2`` / ``-3``: least squares on the root-polynomial terms of degree 2 and 3 (Finlayson,
  Mackiewicz & Hurlbert 2015; simulation.colour_models: 21 and 71 terms for 6 channels, exposure-invariant),
  fitted when every fold of the cross-validation keeps at least as many patches as the model has terms.

The delivery applies each of them per pixel (app.processing.colour_kernels). ``characterise(...)`` fits them on
the training target and chooses the delivered one (``best``) by k-fold cross-validation on the training target
alone (``select_model``: each training patch predicted by the model fitted without its fold) with the
one-standard-error rule (Hastie, Tibshirani & Friedman, *The Elements of Statistical Learning*, 2nd ed., 7.10):
the simplest model (the order above) whose cross-validated mean dE00 is within one standard error (of the fold
means, of the best model) of the lowest. The training set's own error cannot choose (the richer models always fit
it better), and the test target must not: choosing by the test error would bias the reported test error
optimistically. The test target is only evaluated, after the choice; every model's errors on training and test
targets use the float64 reference ``simulation.colorimetry.delta_e_2000``, as patch means and, given the chart's
pixels, per pixel (simulation.pixel_error), with the model's noise gain and the training values' condition number
(simulation.colour_models).
"""
from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab
from dualrgb.simulation.colour_models import condition_number, n_terms
from dualrgb.simulation.cross_validation import CV_FOLDS, fold_parts
from dualrgb.simulation.matrix_fit import CharacterisationMatrix, fit_matrix, fit_root_polynomial
from dualrgb.simulation.objective import ErrorStats
from dualrgb.simulation.pixel_error import PixelErrors, pixel_errors

log = logging.getLogger(__name__)

LEAST_SQUARES = "least-squares"
DE2000 = "de2000"
ROOT_POLYNOMIAL_2 = "root-polynomial-2"
ROOT_POLYNOMIAL_3 = "root-polynomial-3"
MODELS = (LEAST_SQUARES, DE2000, ROOT_POLYNOMIAL_2, ROOT_POLYNOMIAL_3)      # simplest first (the 1-SE rule's order)
DEGREES = {LEAST_SQUARES: 1, DE2000: 1, ROOT_POLYNOMIAL_2: 2, ROOT_POLYNOMIAL_3: 3}


def patch_errors(matrix: CharacterisationMatrix | np.ndarray, values: np.ndarray, xyz: np.ndarray,
                 white: np.ndarray) -> np.ndarray:
    """Per-patch CIEDE2000 between reference ``xyz`` and the model's prediction from ``values`` (a bare array:
    ``values @ matrix``; Lab relative to ``white``)."""
    if isinstance(matrix, CharacterisationMatrix):
        pred = matrix.apply(values)
    else:
        pred = np.asarray(values, dtype=float) @ np.asarray(matrix, dtype=float)
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


def terms_of(model: str, n_channels: int) -> int:
    """The number of terms a model maps (its matrix's rows)."""
    return n_terms(n_channels, DEGREES.get(model, 1))


@dataclass
class MethodResult:
    matrix: CharacterisationMatrix
    train_errors: np.ndarray
    test_errors: np.ndarray | None = None
    pixels: dict[str, PixelErrors] = field(default_factory=dict)     # target -> per-pixel dE00 (given the pixels)

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

    def noise_gain(self) -> dict[str, float | str]:
        """(X, Y, Z) noise gain at the white; 'inf' for an output the white does not reach (strict JSON)."""
        return {k: round(float(v), 4) if np.isfinite(v) else "inf"
                for k, v in zip("XYZ", self.matrix.noise_gain(), strict=True)}

    def to_dict(self) -> dict:
        return {"matrix": self.matrix.to_dict(), "train": self.train.to_dict(),
                "test": self.test.to_dict() if self.test else None, "noise_gain": self.noise_gain(),
                **({"per_pixel_de00": {k: v.to_dict() for k, v in self.pixels.items()}} if self.pixels else {})}


@dataclass
class ModelSelection:
    """Which model is delivered and why: per model the mean cross-validated dE00 on the training target and its
    standard error (of the fold means); ``chosen`` by the one-standard-error rule; ``skipped``: models not fitted
    and why."""

    chosen: str
    cv_mean: dict[str, float]
    folds: int
    cv_se: dict[str, float] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def lowest(self) -> str:
        return min(self.cv_mean, key=lambda m: (self.cv_mean[m], MODELS.index(m) if m in MODELS else 99)) \
            if self.cv_mean else self.chosen

    @property
    def reason(self) -> str:
        if len(self.cv_mean) < 2:
            return f"only {self.chosen} was fitted"
        if self.chosen == self.lowest:
            return f"lowest mean dE00 in {self.folds}-fold cross-validation on the training target"
        return (f"the simplest model within one standard error ({self.cv_se.get(self.lowest, 0.0):.3f}) of the lowest "
                f"mean dE00 ({self.lowest}) in {self.folds}-fold cross-validation on the training target")

    def to_dict(self) -> dict:
        return {"chosen": self.chosen, "criterion": self.reason, "folds": self.folds, "rule": "one standard error",
                "cv_mean_de00": {k: round(v, 4) for k, v in self.cv_mean.items()},
                "cv_se_de00": {k: round(v, 4) for k, v in self.cv_se.items()},
                **({"not_fitted": self.skipped} if self.skipped else {})}


def one_standard_error(cv_mean: dict[str, float], cv_se: dict[str, float]) -> str:
    """The simplest model (order of :data:`MODELS`) whose mean is within one standard error of the lowest mean."""
    order = sorted(cv_mean, key=lambda m: MODELS.index(m) if m in MODELS else len(MODELS))
    lowest = min(order, key=lambda m: cv_mean[m])
    limit = cv_mean[lowest] + cv_se.get(lowest, 0.0)
    return next(m for m in order if cv_mean[m] <= limit)


def _fitters(white: np.ndarray, channels: list[str], optimise: bool, root_polynomial: bool, n_fit: int,
             cancel: CancelToken | None) -> tuple[dict, dict[str, str]]:
    """The models to fit in :data:`MODELS` order, and those left out with the reason; root-polynomials only when
    ``n_fit`` (the fewest patches any fit sees) is at least their number of terms."""
    fits: dict = {LEAST_SQUARES: lambda v, x: fit_least_squares(v, x, channels)}
    skipped: dict[str, str] = {}
    if optimise:
        fits[DE2000] = lambda v, x: fit_de2000(v, x, white, channels, cancel=cancel)
    for name in (ROOT_POLYNOMIAL_2, ROOT_POLYNOMIAL_3):
        terms = terms_of(name, len(channels))
        if not root_polynomial:
            skipped[name] = "not asked for"
        elif n_fit < terms:
            skipped[name] = f"{terms} terms but a fold keeps {n_fit} training patches"
        else:
            fits[name] = (lambda d: lambda v, x: fit_root_polynomial(v, x, d, channels))(DEGREES[name])
    return fits, skipped


def select_model(train_values: np.ndarray, train_xyz: np.ndarray, white: np.ndarray, channels: list[str], *,
                 optimise: bool = True, root_polynomial: bool = True, folds: int = CV_FOLDS, seed: int = 0,
                 progress: ProgressCallback | None = None, cancel: CancelToken | None = None
                 ) -> ModelSelection:
    """Choose the model by k-fold cross-validation on the training target with the one-standard-error rule (it
    never sees a test target: none is passed). Folds are a seeded random partition; each patch's error comes from
    a fit without it."""
    values = np.asarray(train_values, dtype=float)
    xyz = np.asarray(train_xyz, dtype=float)
    n = len(values)
    parts = fold_parts(n, folds, seed)            # the partition rule the studies choose their defaults with
    k = len(parts)
    fitters, skipped = _fitters(white, channels, optimise, root_polynomial, n - max(len(p) for p in parts), cancel)
    if len(fitters) == 1:
        return ModelSelection(LEAST_SQUARES, {}, 0, skipped=skipped)
    errors = {m: np.empty(n) for m in fitters}
    for i, held in enumerate(parts):
        check(cancel)
        keep = np.setdiff1d(np.arange(n), held)
        for m, fit in fitters.items():
            errors[m][held] = patch_errors(fit(values[keep], xyz[keep]), values[held], xyz[held], white)
        report(progress, (i + 1) / k, f"cross-validation fold {i + 1} of {k}")
    cv = {m: float(e.mean()) for m, e in errors.items()}
    se = {m: float(np.std([e[p].mean() for p in parts], ddof=1) / np.sqrt(k)) for m, e in errors.items()}
    return ModelSelection(one_standard_error(cv, se), cv, k, se, skipped)


@dataclass
class Characterisation:
    """Every fitted model with its per-patch (and per-pixel) errors; ``best`` is the delivered one, chosen on the
    training target (``selection``); test errors are reported, never used to choose. ``condition_number``: of the
    captured training values (simulation.colour_models.condition_number), the figure the plan checked before
    the light (app.workflow.stand.preflight.check_conditioning) from the camera model."""

    results: dict[str, MethodResult]
    white: np.ndarray
    channels: list[str] = field(default_factory=list)
    selection: ModelSelection | None = None
    condition_number: float | None = None

    @property
    def best(self) -> str:
        if self.selection is not None:
            return self.selection.chosen
        return LEAST_SQUARES if LEAST_SQUARES in self.results else next(iter(self.results))

    @property
    def matrix(self) -> CharacterisationMatrix:
        return self.results[self.best].matrix

    @property
    def linear_matrix(self) -> CharacterisationMatrix:
        """The delivered model when it is linear, else least squares (what a linear consumer, the spectral
        estimate's matrix R, needs)."""
        return self.matrix if self.matrix.degree == 1 else self.results[LEAST_SQUARES].matrix

    def model_table(self) -> list[dict]:
        """One row per model: terms, parameters, cross-validated dE00 +- SE, train / test dE00 (patch means),
        per-pixel test dE00, noise gain (Y), and whether it is delivered."""
        sel = self.selection

        def cv(table: dict[str, float], name: str) -> float | None:
            return None if sel is None or name not in table else round(table[name], 4)

        rows = []
        for name, r in self.results.items():
            target = "test" if "test" in r.pixels else "train" if "train" in r.pixels else None
            px = r.pixels[target] if target else None
            rows.append({"model": name, "degree": r.matrix.degree, "terms": int(r.matrix.matrix.shape[0]),
                         "parameters": int(r.matrix.matrix.size),
                         "cv_mean_de00": cv(sel.cv_mean, name) if sel else None,
                         "cv_se_de00": cv(sel.cv_se, name) if sel else None,
                         "train_de00": round(r.train.mean, 4),
                         "test_de00": None if r.test is None else round(r.test.mean, 4),
                         "per_pixel_target": target,
                         "per_pixel_de00_mean": None if px is None else round(px.mean, 4),
                         "per_pixel_de00_p90": None if px is None else round(px.p90, 4),
                         "noise_gain_y": r.noise_gain()["Y"], "chosen": name == self.best})
        return rows

    def to_dict(self) -> dict:
        best = self.results[self.best]
        cond = self.condition_number
        return {"best": self.best, "selection": self.selection.to_dict() if self.selection else None,
                "white": self.white.tolist(), "channels": self.channels,
                "methods": {k: v.to_dict() for k, v in self.results.items()}, "models": self.model_table(),
                "per_pixel_de00": {k: {"mean": round(v.mean, 4), "p90": round(v.p90, 4)}
                                   for k, v in best.pixels.items()},
                "noise_gain": best.noise_gain(),
                "condition_number": None if cond is None else (round(cond, 2) if np.isfinite(cond) else "inf")}


def _evaluate(fits: dict[str, CharacterisationMatrix], train: tuple[np.ndarray, np.ndarray],
              test: tuple[np.ndarray | None, np.ndarray | None], white: np.ndarray,
              pixels: Mapping[str, Sequence[np.ndarray]] | None) -> dict[str, MethodResult]:
    """Every model's patch errors on train (and test), and per pixel where ``pixels`` has the target's."""
    refs = {k: v for k, v in (("train", train[1]), ("test", test[1])) if v is not None}
    results = {}
    for name, m in fits.items():
        te = None if test[0] is None or test[1] is None else patch_errors(m, test[0], test[1], white)
        px = {k: pixel_errors(m.apply, p, refs[k], white) for k, p in (pixels or {}).items() if k in refs}
        results[name] = MethodResult(m, patch_errors(m, train[0], train[1], white), te, px)
    return results


def characterise(train_values: np.ndarray, train_xyz: np.ndarray, white: np.ndarray,
                 test_values: np.ndarray | None = None, test_xyz: np.ndarray | None = None,
                 channels: Sequence[str] | None = None, *, optimise: bool = True, root_polynomial: bool = True,
                 pixels: Mapping[str, Sequence[np.ndarray]] | None = None,
                 progress: ProgressCallback | None = None, cancel: CancelToken | None = None
                 ) -> Characterisation:
    """Fit least squares, (``optimise``) the dE00-optimised matrix and (``root_polynomial``) the root-polynomials
    of degree 2 and 3, choose one by cross-validation on the training target (``select_model``), then evaluate
    every model on train and test, per patch and, for each target ``pixels`` holds (its patches' (m, C) pixel
    values), per pixel."""
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
    selection = select_model(train_values, train_xyz, white, channels, optimise=optimise,
                             root_polynomial=root_polynomial, progress=cv, cancel=cancel)
    for name in (ROOT_POLYNOMIAL_2, ROOT_POLYNOMIAL_3):
        if name in selection.cv_mean:                   # fitted in every fold, so on the whole target too
            fits[name] = fit_root_polynomial(train_values, train_xyz, DEGREES[name], channels)
    results = _evaluate(fits, (train_values, train_xyz), (test_values, test_xyz), white, pixels)
    out = Characterisation(results, white, channels, selection, condition_number(train_values))
    for name, r in results.items():
        log.info("%s: train mean dE00 %.3f%s%s", name, r.train.mean,
                 f", cross-validated {selection.cv_mean[name]:.3f}" if name in selection.cv_mean else "",
                 f", test mean {r.test.mean:.3f}" if r.test else "")
    report(progress, 1.0, f"characterised; delivered {out.best} ({selection.reason})")
    return out
