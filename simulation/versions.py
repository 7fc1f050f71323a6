"""What made a result: the format tag and software versions every JSON output carries (one function builds it).

``output_header("dualrgb-simulation/1")`` ->
``{"format": "dualrgb-simulation/1", "software": {"dualrgb": "0.1.0", "python": "3.11.7", "numpy": "2.4.6",
"numba": "0.68.1", "colour-science": "0.4.7", "rawpy": "0.28.0", "libraw": "0.22.0"}}``

Versions come from the installed distributions' metadata (no package is imported for it), except LibRaw's,
which only rawpy knows. Lives in simulation/ because the lowest layer that writes JSON (presets, studies)
needs it; importing this module costs nothing measurable (the CLI's ``--version`` uses it).
``importlib.metadata`` itself is imported on the first question (~50 ms, a third of the CLI's start-up).
"""
from __future__ import annotations

import functools
import logging
import platform
from typing import Any

log = logging.getLogger(__name__)

DISTRIBUTION = "dualrgb"
# distributions whose versions change the numbers: the app, arrays, kernels, colorimetry, raw decoding
SOFTWARE = ("numpy", "numba", "colour-science", "rawpy")


@functools.lru_cache(maxsize=16)      # ~1 ms a question (the metadata file parsed): a delivery asks 15 times
def _version(distribution: str) -> str | None:
    from importlib import metadata  # ~50 ms: only when a version is asked for

    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return None


def dualrgb_version() -> str:
    """The installed dualrgb version (pyproject's), or '0+unknown' when run from a tree that was never installed."""
    return _version(DISTRIBUTION) or "0+unknown"


def _libraw_version() -> str | None:
    try:
        import rawpy
    except ImportError:
        return None
    return ".".join(str(v) for v in rawpy.libraw_version) if hasattr(rawpy, "libraw_version") else None


@functools.lru_cache(maxsize=1)
def _versions() -> tuple[tuple[str, str | None], ...]:
    out: list[tuple[str, str | None]] = [(DISTRIBUTION, dualrgb_version()), ("python", platform.python_version())]
    out += [(name, _version(name)) for name in SOFTWARE]
    return tuple(out + [("libraw", _libraw_version())])


def software_versions() -> dict[str, str | None]:
    """dualrgb, Python and the libraries in ``SOFTWARE`` (None when one is not installed), plus LibRaw."""
    return dict(_versions())


def output_header(fmt: str) -> dict[str, Any]:
    """The block every JSON output starts with: ``{"format": fmt, "software": software_versions()}``.

    ``fmt`` is ``dualrgb-<what>/<major version>``; readers check the part before the slash and the major version.
    """
    if not fmt.startswith("dualrgb-") or "/" not in fmt:
        raise ValueError(f"format tag {fmt!r}: expected 'dualrgb-<what>/<version>'")
    return {"format": fmt, "software": software_versions()}


def stamped(fmt: str, data: dict[str, Any]) -> dict[str, Any]:
    """``data`` behind :func:`output_header` (a 'format' or 'software' key of its own is replaced)."""
    return {**output_header(fmt), **{k: v for k, v in data.items() if k not in ("format", "software")}}
