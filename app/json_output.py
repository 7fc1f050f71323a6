"""``--json PATH`` for every command: one meaning everywhere (PATH ``-`` = standard output).

Every JSON document the app writes starts with :func:`simulation.versions.output_header`'s format tag and
software versions; :func:`write_json` adds it (:func:`simulation.versions.stamped`), so a command only names
its format.
"""
from __future__ import annotations

import argparse
import json
import logging
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

log = logging.getLogger(__name__)

STDOUT = "-"
HELP = "write the result as JSON to PATH ('-': standard output)"


def add_json_option(parser: argparse.ArgumentParser, help: str = HELP) -> None:
    """``--json PATH``; ``args.json`` is None when not given."""
    parser.add_argument("--json", metavar="PATH", help=help)


def text_stream(dest: str | os.PathLike[str] | None) -> TextIO:
    """Where a command's human-readable lines go: stderr when ``--json -`` gives stdout to the JSON alone."""
    return sys.stderr if dest is not None and str(dest) == STDOUT else sys.stdout


def dumps(data: Any, default: Callable[[Any], Any] | None = None, **kw: Any) -> str:
    """``json.dumps`` as every JSON the app writes is made: NaN and Infinity are refused (they are not JSON), a
    ValueError naming the first key path that holds one."""
    try:
        return json.dumps(data, default=default, allow_nan=False, **kw)
    except ValueError as exc:
        raise ValueError(f"{exc}: at {non_finite_path(data) or '?'} (not JSON; a number must be finite)") from None


def non_finite_path(data: Any, path: str = "") -> str:
    """The key path ('a.b[2]') of the first NaN or infinite float in ``data``; '' when there is none."""
    if isinstance(data, float):
        return "" if math.isfinite(data) else (path or "(top)")
    items: Any = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list | tuple) else ()
    for k, v in items:
        found = non_finite_path(v, f"{path}.{k}" if isinstance(k, str) else f"{path}[{k}]")
        if found:
            return found.lstrip(".")
    return ""


def write_json(dest: str | os.PathLike[str] | None, fmt: str, data: dict,
               default: Callable[[Any], Any] | None = None) -> Path | None:
    """Write ``data`` with its header to ``dest`` ('-': stdout; None: nothing). A file is written whole or not at
    all (common.atomic_files) and its parent folders are created; returns the file's path (None for stdout)."""
    from dualrgb.common.atomic_files import atomic_write
    from dualrgb.simulation.versions import stamped

    if dest is None:
        return None
    text = dumps(stamped(fmt, data), default=default, indent=2) + "\n"
    if str(dest) == STDOUT:
        sys.stdout.write(text)
        sys.stdout.flush()
        return None
    path = Path(dest)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, text)
    log.info("wrote %s", path)
    return path
