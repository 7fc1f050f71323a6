"""Load the optimisers' numba kernels before anything is timed, and say so when it means compiling them.

The kernels (simulation.fast_de, simulation.fast_linalg) are compiled on their first call and cached on disk
(``cache=True``): the first run on a machine compiles for 20 s to minutes (longer on a loaded machine), later
runs load them in about a second (2-3 s on a heavily loaded one). :func:`warm_up` makes that first call on a
4-particle batch and reports :data:`COMPILING` through the progress callback when numba has no cache index for
a kernel (at once), or, where numba's cache internals cannot be read, when the call takes longer than
``notice_after_s``; so a user never watches a silent terminal, and run times exclude the one-off compile.
"""
from __future__ import annotations

import logging
import os
import threading
import time
from typing import TYPE_CHECKING

import numpy as np

from dualrgb.common.progress import COMPILING, ProgressCallback, report

if TYPE_CHECKING:
    from dualrgb.simulation.objective import Evaluator

log = logging.getLogger(__name__)


def _cached(dispatcher: object) -> bool | None:
    """Whether numba's on-disk cache holds an index for this kernel; None when its internals are not readable
    (they are private: ``Dispatcher._cache._cache_file._index_path`` in numba 0.59-0.68)."""
    try:
        return os.path.exists(dispatcher._cache._cache_file._index_path)  # type: ignore[attr-defined]
    except (AttributeError, TypeError):
        return None


def kernels_cached() -> bool | None:
    """True when every kernel the optimisers use has an on-disk cache index, False when one has none, None
    when that cannot be told."""
    from dualrgb.simulation.fast_de import mean_de2000_mapped
    from dualrgb.simulation.fast_linalg import fit_light_sets

    states = [_cached(k) for k in (fit_light_sets, mean_de2000_mapped)]
    if None in states:
        return None
    return all(states)


def warm_up(evaluator: Evaluator, progress: ProgressCallback | None = None,
            notice_after_s: float = 1.0) -> float:
    """Compile or load the kernels ``evaluator`` uses; returns the seconds it took.

    The call goes through :class:`simulation.objective.Evaluator`'s own ``cost_indexed`` (not a subclass's
    override, so a GUI convergence tap sees no point) and leaves ``evaluator.evaluations`` unchanged.
    """
    from dualrgb.simulation.objective import Evaluator

    idx = np.zeros((4, 2, 3), dtype=np.int64)
    idx[:, 1] = 1
    done = threading.Event()

    def notice() -> None:
        if not done.is_set():
            log.info(COMPILING)
            report(progress, 0.0, COMPILING)

    cached = kernels_cached()
    timer = threading.Timer(notice_after_s, notice)
    timer.daemon = True
    n0 = evaluator.evaluations
    t0 = time.perf_counter()
    if cached is False:
        notice()
    elif cached is None:                        # a cache load (True) is quiet however long a loaded machine takes
        timer.start()
    try:
        Evaluator.cost_indexed(evaluator, idx, np.ones((4, 2, 3)))
    finally:
        done.set()
        timer.cancel()
        evaluator.evaluations = n0
    seconds = time.perf_counter() - t0
    log.debug("kernels ready in %.2f s", seconds)
    return seconds
