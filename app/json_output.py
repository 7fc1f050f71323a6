"""``--json PATH`` for every command: one meaning everywhere (PATH ``-`` = standard output).

Every JSON document the app writes starts with :func:`simulation.versions.output_header`'s format tag and
software versions; :func:`write_json` adds it (:func:`simulation.versions.stamped`), so a command only names
its format.
"""
from __future__ import annotations

import argparse
import logging
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
    """``json.dumps`` as every JSON the app writes is made (common.strict_json): NaN and Infinity are refused
    (they are not JSON), a ValueError naming the first key path that holds one."""
    from dualrgb.common.strict_json import dumps as strict_dumps

    return strict_dumps(data, default=default, **kw)


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
