"""Fill numba's on-disk cache with the kernels the application runs, once, right after installing.

Why: every numba kernel is compiled on its first call on a machine and cached on disk (``cache=True``). On a fresh
install that first call falls inside the technician's first run: the first delivery compiled for ~25 s and the
first optimisation for longer, and a Cancel pressed meanwhile waits for the compiler (a kernel cannot be stopped
half-compiled). ``make venv`` (so ``make run`` and ``make test``) runs this module after installing, so the first
run loads the kernels in about a second instead; it is also safe to run again (then it only loads them)::

    python -m dualrgb.app.warm_kernels

One line per group of kernels, with the seconds it took (compiled, or loaded from the cache).
"""
from __future__ import annotations

import logging
import sys
import time
from collections.abc import Callable

import numpy as np

log = logging.getLogger(__name__)


def warm_processing() -> None:
    """The half-resolution processing kernels (darks, HDR merge, flat field + superpixel)."""
    from dualrgb.app.processing import kernels

    kernels.warm_up()


def warm_delivery(exposures: tuple[int, ...] = (1, 2, 3)) -> None:
    """The delivery's kernels: encodings, spectral cube, the full-resolution row kernels for lights of
    ``exposures`` frames each, the demosaic."""
    from dualrgb.app.processing import encode, master_kernels, spectral_cube
    from dualrgb.app.processing.demosaic import demosaic

    encode.warm_up()
    spectral_cube.warm_up()
    master_kernels.warm_up(exposures)
    demosaic(np.zeros((4, 4), np.float32))


def _optimisers() -> None:
    from dualrgb.simulation.datasets import default_setup
    from dualrgb.simulation.expected_error import ExpectedErrorEvaluator
    from dualrgb.simulation.objective import Evaluator
    from dualrgb.simulation.warmup import warm_up

    setup = default_setup("reflective")
    warm_up(Evaluator(setup))
    ExpectedErrorEvaluator(setup).warm_up_kernels()


GROUPS: dict[str, Callable[[], None]] = {
    "processing (darks, HDR merge, flat field)": warm_processing,
    "delivery (full-resolution rows, demosaic, encodings, spectral cube)": warm_delivery,
    "optimisers (noise-free and expected-captured objectives)": _optimisers,
}


def warm_all(say: Callable[[str], None] = print) -> dict[str, float]:
    """Compile (or load) every group of kernels; ``say`` gets one line per group. Returns the seconds per group."""
    took: dict[str, float] = {}
    for name, warm in GROUPS.items():
        t0 = time.perf_counter()
        warm()
        took[name] = time.perf_counter() - t0
        say(f"numba kernels: {name}: {took[name]:.1f} s")
    return took


def main(argv: list[str] | None = None) -> int:
    if argv:
        print("usage: python -m dualrgb.app.warm_kernels (no arguments)", file=sys.stderr)
        return 2
    warm_all()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
