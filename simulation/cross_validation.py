"""k-fold cross-validation on the training target: how a default is chosen without looking at the test target.

One partition rule for the whole app: the processing's choice of the delivered matrix
(``app.processing.characterise.select_model``) and the studies that choose the packaged defaults
(``simulation.studies.parsimony``, ``simulation.studies.hdr``) use :func:`fold_parts`, so a choice made in a study
is made the way the app makes it on a calibration. The test target is then only ever reported.
"""
from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

log = logging.getLogger(__name__)

CV_FOLDS = 5


def fold_parts(n: int, folds: int = CV_FOLDS, seed: int = 0) -> list[np.ndarray]:
    """A seeded random partition of ``range(n)`` into ``k = clip(folds, 2, n // 2)`` parts (held-out indices).

    Parameters
    ----------
    n : number of patches (at least 2).
    folds : wanted number of folds.
    seed : the partition's random seed.

    Returns
    -------
    list of k index arrays, together a permutation of ``range(n)``.
    """
    if n < 2:
        raise ValueError(f"{n} training patches: cross-validation needs at least 2")
    k = max(2, min(folds, n // 2))
    return np.array_split(np.random.default_rng(seed).permutation(n), k)


def cross_validated_errors(fit_and_score: Callable[[np.ndarray, np.ndarray], np.ndarray], n: int,
                           folds: int = CV_FOLDS, seed: int = 0) -> np.ndarray:
    """Per-patch errors, each from a fit that did not see the patch.

    Parameters
    ----------
    fit_and_score : ``(keep, held) -> errors of the held patches`` for a model fitted on the ``keep`` patches.
    n : number of training patches.
    folds, seed : as :func:`fold_parts`.

    Returns
    -------
    (n,) errors in patch order.
    """
    errors = np.empty(n)
    for held in fold_parts(n, folds, seed):
        keep = np.setdiff1d(np.arange(n), held)
        errors[held] = fit_and_score(keep, held)
    return errors
