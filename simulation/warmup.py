"""Load the optimisers' numba kernels before anything is timed, and say so when it means compiling them.

The kernels (simulation.fast_de, simulation.fast_linalg) are compiled on their first call and cached on disk
(``cache=True``): the first run on a machine compiles for 10 s to minutes (longer on a loaded machine), later
runs load them in well under a second. :func:`warm_up` makes that first call on a 4-particle batch, and when it
has taken longer than ``notice_after_s`` (a cache load never does) it reports :data:`COMPILING` through the
progress callback, so a user never watches a silent terminal; run times then exclude the one-off compile.
"""
from __future__ import annotations

import logging
import threading
import time
from typing import TYPE_CHECKING, Optional

import numpy as np

from simulation.progress import COMPILING, ProgressCallback, report

if TYPE_CHECKING:
    from simulation.objective import Evaluator

log = logging.getLogger(__name__)


def warm_up(evaluator: "Evaluator", progress: Optional[ProgressCallback] = None,
            notice_after_s: float = 1.0) -> float:
    """Compile or load the kernels ``evaluator`` uses; returns the seconds it took.

    The call goes through :class:`simulation.objective.Evaluator`'s own ``cost_indexed`` (not a subclass's
    override, so a GUI convergence tap sees no point) and leaves ``evaluator.evaluations`` unchanged.
    """
    from simulation.objective import Evaluator

    idx = np.zeros((4, 2, 3), dtype=np.int64)
    idx[:, 1] = 1
    done = threading.Event()

    def notice() -> None:
        if not done.is_set():
            log.info(COMPILING)
            report(progress, 0.0, COMPILING)

    timer = threading.Timer(notice_after_s, notice)
    timer.daemon = True
    n0 = evaluator.evaluations
    t0 = time.perf_counter()
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
