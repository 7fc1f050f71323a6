"""Fill numba's on-disk cache with the kernels the application runs, once, right after installing.

Why: every numba kernel is compiled on its first call on a machine and cached on disk (``cache=True``). On a fresh
install that first call falls inside the technician's first run: the first delivery compiled for ~25 s and the
first optimisation for longer, and a Cancel pressed meanwhile waits for the compiler (a kernel cannot be stopped
half-compiled). ``make venv`` (so ``make run`` and ``make test``) runs this module after installing, so the first
run loads the kernels in about a second instead; it is also safe to run again (then it only loads them)::

    python -m dualrgb.app.warm_kernels

One line per group of kernels, with the seconds it took (compiled, or loaded from the cache).

A pip install of the wheel runs nothing after installing, and a new numba or another CPU makes the cache stale:
:func:`ensure_ready` is what the commands that process (calibrate, capture, process, import, cube, demo, simulate,
study) call first, before any device is opened: a group whose kernels are not known to be in the cache is warmed
there, with one line saying so, so the first run neither waits silently nor compiles inside a lit sequence. A
group is known to be ready by a stamp file beside the cache (:func:`stamp_path`), keyed by the sources of its
modules (path, size, time), the dualrgb, numba and Python versions and the CPU; :func:`warm_all` writes them.
"""
from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

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
PROCESSING, DELIVERY, OPTIMISERS = GROUPS          # the group names, in GROUPS' order
SOURCES = {PROCESSING: "processing", DELIVERY: "processing", OPTIMISERS: "simulation"}   # where their kernels are
SOURCE_DIRS = {"processing": ("app", "processing"), "simulation": ("simulation",)}


def _source_key(group: str) -> str:
    """What numba's cache of ``group`` depends on: its modules' sources (path, size, time), the versions, the CPU."""
    import hashlib
    import platform
    from importlib.metadata import version

    from dualrgb.simulation.versions import dualrgb_version

    folder = Path(__file__).resolve().parent.parent.joinpath(*SOURCE_DIRS[SOURCES[group]])
    if not folder.is_dir():                     # installed: the dualrgb package's own folders
        folder = Path(__file__).resolve().parent.joinpath(*SOURCE_DIRS[SOURCES[group]][1:])
    files = sorted(folder.rglob("*.py"))
    parts = [group, dualrgb_version(), version("numba"), platform.python_version(), _cpu(),
             os.environ.get("NUMBA_CACHE_DIR", "")]
    parts += [f"{f}:{f.stat().st_size}:{f.stat().st_mtime_ns}" for f in files]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:20]


def _cpu() -> str:
    """This CPU's model (numba's cache is per CPU), read without importing numba: it takes seconds to import."""
    import platform

    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.startswith(("model name", "flags")):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return f"{platform.machine()} {platform.processor()}"


def stamp_path(group: str) -> Path:
    """The stamp that says ``group``'s kernels are in numba's cache: beside the cache (NUMBA_CACHE_DIR, else this
    package's __pycache__ where numba writes it), else in the per-user data folder when that is read-only."""
    slug = group.split(" ")[0]
    name = f"dualrgb-kernels-{slug}-{_source_key(group)}.ok"
    cache = os.environ.get("NUMBA_CACHE_DIR")
    folder = Path(cache) if cache else Path(__file__).resolve().parent / "__pycache__"
    if not os.access(folder if folder.exists() else folder.parent, os.W_OK):
        from dualrgb.resources import user_path

        folder = user_path("kernels")
    return folder / name


def ready(group: str) -> bool:
    """Whether ``group``'s kernels are known to be in numba's cache (its stamp exists)."""
    return stamp_path(group).is_file()


def warm(group: str, say: Callable[[str], None] = print) -> float:
    """Compile (or load) one group and write its stamp; one line with the seconds it took."""
    t0 = time.perf_counter()
    GROUPS[group]()
    took = time.perf_counter() - t0
    stamp = stamp_path(group)
    try:
        stamp.parent.mkdir(parents=True, exist_ok=True)
        stamp.write_text(f"{took:.1f} s\n", encoding="utf-8")
    except OSError as exc:                      # a read-only install: warmed now, checked again next time
        log.info("kernel stamp %s not written: %s", stamp, exc)
    say(f"numba kernels: {group}: {took:.1f} s")
    return took


def ensure_ready(groups: Sequence[str] = (PROCESSING, DELIVERY), say: Callable[[str], None] | None = None) -> None:
    """Warm every group of ``groups`` not known to be ready, saying so first in one line (the first run after an
    install, a numba upgrade or on another CPU); silent when all are ready."""
    todo = [g for g in groups if not ready(g)]
    if not todo:
        return
    say = say or (lambda line: print(line, file=sys.stderr, flush=True))
    say(f"first run of this installation: compiling {len(todo)} group{'s' * (len(todo) > 1)} of numba kernels once "
        "(about a minute; later runs load them in seconds)")
    for group in todo:
        warm(group, say)


def warm_all(say: Callable[[str], None] = print) -> dict[str, float]:
    """Compile (or load) every group of kernels; ``say`` gets one line per group. Returns the seconds per group."""
    return {name: warm(name, say) for name in GROUPS}


def main(argv: list[str] | None = None) -> int:
    if argv:
        print("usage: python -m dualrgb.app.warm_kernels (no arguments)", file=sys.stderr)
        return 2
    warm_all()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
