"""Choosing the spectral estimate on the training target alone: k-fold cross-validation over methods and their
settings (the smoothness prior, the weight of the training prior, the ridge, and for wiener and pinv a linear or
an affine map: simulation.spectral_estimation's ``offset``).

Each training patch is estimated by the estimator fitted without its fold (the colour matrix of ``matrix-r``
refitted on the fold too); the candidate with the lowest mean spectral RMSE over the held-out patches is fitted
again on the whole training target and delivered. The test target is never passed in, so it cannot take part
in the choice (as the colour matrix: app.processing.characterise.select_model).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from dualrgb.common.progress import CancelToken, check
from dualrgb.simulation.spectral_estimation import (
    QUANTITIES,
    SPECTRAL_METHODS,
    SpectralEstimationError,
    SpectralEstimator,
    SpectralPrior,
    SpectralTraining,
    fit_spectral,
)
from dualrgb.simulation.spectral_metrics import spectral_rmse

log = logging.getLogger(__name__)

CV_FOLDS = 5
SMOOTHNESS = (0.95, 0.98, 0.99, 0.995, 0.999)      # rho at 10 nm
TRAINING_WEIGHTS = (0.0, 0.25, 0.5, 0.75, 1.0)
RIDGES = (0.0, 1e-4, 1e-3, 1e-2)
# Linear, then affine maps (a tie keeps the linear one), per quantity. A film's transmittance where the camera is
# blind (below ~410, above ~690 nm) is its base's, the same whatever the dyes: an offset, which the affine map
# carries (packaged film, noise-free, PSO lights: test chart 0.057 -> 0.020, the virtual film's materials 0.073 ->
# 0.016). Reflectances there have no common value: cross-validation on rawtoaces-190 prefers the affine map (0.103
# against 0.109) but both held-out sets get worse (the virtual painting's measured materials 0.049 -> 0.055, the
# CC24 0.042 -> 0.085), so reflective estimates stay linear (docs/explanation/spectral.md).
OFFSETS = {QUANTITIES["transmissive"]: (False, True), QUANTITIES["reflective"]: (False,)}


def map_forms(quantity: str) -> tuple[bool, ...]:
    """The offsets cross-validation may choose for ``quantity`` (:data:`OFFSETS`; True: an affine map)."""
    return OFFSETS.get(quantity, (False,))


@dataclass(frozen=True)
class SpectralCandidate:
    """One method with one setting: ``prior`` (wiener, matrix-r with the sensitivities) or ``ridge``; ``offset``:
    the affine map (wiener, pinv)."""

    method: str
    prior: SpectralPrior | None = None
    ridge: float | None = None
    offset: bool = False

    def settings(self) -> dict:
        out: dict = {}
        if self.prior is not None:
            out["prior"] = self.prior
        if self.ridge is not None:
            out["ridge"] = self.ridge
        if self.offset:
            out["offset"] = True
        return out

    @property
    def family(self) -> str:
        """The method and its map's form: 'wiener', 'wiener+offset', ... (how figures are grouped)."""
        return f"{self.method}+offset" if self.offset else self.method

    def label(self) -> str:
        if self.prior is not None:
            return (f"{self.family} (smoothness {self.prior.smoothness:g}, training weight "
                    f"{self.prior.training_weight:g})")
        return f"{self.family} (ridge {self.ridge:g})" if self.ridge else self.family

    def fit(self, training: SpectralTraining) -> SpectralEstimator:
        return fit_spectral(training, self.method, **self.settings())


def candidates(training: SpectralTraining, methods: tuple[str, ...] | None = None) -> list[SpectralCandidate]:
    """Every (method, setting) the training data allow: wiener needs the sensitivities, matrix-r the colour
    weights; ``methods`` restricts the methods (default: all of :data:`SPECTRAL_METHODS`)."""
    methods = tuple(methods or SPECTRAL_METHODS)
    unknown = [m for m in methods if m not in SPECTRAL_METHODS]
    if unknown:
        raise SpectralEstimationError(f"spectral methods {', '.join(unknown)}: expected some of "
                                      f"{', '.join(SPECTRAL_METHODS)}")
    priors = [SpectralPrior(s, w) for s in SMOOTHNESS for w in TRAINING_WEIGHTS]
    offsets = map_forms(training.quantity)
    known = training.sensitivities is not None
    out: list[SpectralCandidate] = []
    for m in methods:
        if m == "wiener" and known:
            out += [SpectralCandidate(m, prior=p, offset=o) for o in offsets for p in priors]
        elif m == "matrix-r" and training.colour_weights is not None:
            out += ([SpectralCandidate(m, prior=p) for p in priors] if known
                    else [SpectralCandidate(m, ridge=r) for r in RIDGES])
        elif m == "pinv":
            out += [SpectralCandidate(m, ridge=r, offset=o) for o in offsets for r in RIDGES]
    if not out:
        raise SpectralEstimationError(f"no spectral method of {', '.join(methods)} can be fitted: wiener needs the "
                                      "system's sensitivities, matrix-r the colour weights")
    return out


def folds_of(n: int, folds: int = CV_FOLDS, seed: int = 0) -> list[np.ndarray]:
    """A seeded random partition of ``n`` patches into ``folds`` parts (at least 2 patches each)."""
    k = max(2, min(folds, n // 2))
    return np.array_split(np.random.default_rng(seed).permutation(n), k)


def cross_validate(training: SpectralTraining, cands: list[SpectralCandidate], folds: int = CV_FOLDS,
                   seed: int = 0, cancel: CancelToken | None = None) -> np.ndarray:
    """Held-out spectral RMSE per candidate and training patch: (n_candidates, n_patches)."""
    n = len(training.values)
    errors = np.empty((len(cands), n))
    for held in folds_of(n, folds, seed):
        check(cancel)
        fold = training.subset(np.setdiff1d(np.arange(n), held))
        for i, cand in enumerate(cands):
            est = cand.fit(fold).apply(training.values[held])
            errors[i, held] = spectral_rmse(est, training.spectra[held])
    return errors


@dataclass
class SpectralSelection:
    """The delivered estimator, the candidate it came from and every candidate's cross-validated RMSE."""

    estimator: SpectralEstimator
    chosen: SpectralCandidate
    cv_rmse: dict[str, float] = field(default_factory=dict)
    folds: int = CV_FOLDS

    @property
    def reason(self) -> str:
        return (f"lowest mean spectral RMSE in {self.folds}-fold cross-validation on the training target "
                f"({len(self.cv_rmse)} candidates)")

    def best_per_method(self) -> dict[str, float]:
        out: dict[str, float] = {}
        for label, v in self.cv_rmse.items():
            m = label.split(" ")[0]
            out[m] = min(out.get(m, np.inf), v)
        return out

    def to_dict(self) -> dict:
        return {"chosen": self.chosen.label(), "method": self.chosen.method, "criterion": self.reason,
                "folds": self.folds, "cv_rmse_best_per_method": {k: round(v, 5)
                                                                  for k, v in self.best_per_method().items()},
                "cv_rmse_chosen": round(self.cv_rmse[self.chosen.label()], 5)}


def select_estimator(training: SpectralTraining, methods: tuple[str, ...] | None = None, folds: int = CV_FOLDS,
                     seed: int = 0, cancel: CancelToken | None = None) -> SpectralSelection:
    """The candidate (:func:`candidates`) with the lowest cross-validated mean spectral RMSE, fitted on the whole
    training target; on a tie the earlier method of :data:`SPECTRAL_METHODS` wins."""
    cands = candidates(training, methods)
    cv = cross_validate(training, cands, folds, seed, cancel).mean(axis=1)
    best = int(np.argmin(cv))                 # first minimum: the dispatch table's order breaks ties
    chosen = cands[best]
    log.info("spectral estimate: %s, cross-validated mean RMSE %.4f (%d candidates)", chosen.label(), cv[best],
             len(cands))
    return SpectralSelection(chosen.fit(training), chosen, {c.label(): float(v) for c, v in zip(cands, cv,
                                                                                                 strict=True)},
                             len(folds_of(len(training.values), folds, seed)))
