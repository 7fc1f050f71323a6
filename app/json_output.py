"""``--json PATH`` for every command: one meaning everywhere (PATH ``-`` = standard output).

Every JSON document the app writes starts with :func:`simulation.versions.output_header`'s format tag and
software versions; :func:`write_json` adds it (:func:`simulation.versions.stamped`), so a command only names
its format.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

STDOUT = "-"
HELP = "write the result as JSON to PATH ('-': standard output)"


def add_json_option(parser: argparse.ArgumentParser, help: str = HELP) -> None:
    """``--json PATH``; ``args.json`` is None when not given."""
    parser.add_argument("--json", metavar="PATH", help=help)


def write_json(dest: str | os.PathLike[str], fmt: str, data: dict,
               default: Callable[[Any], Any] | None = None) -> Path | None:
    """Write ``data`` with its header to ``dest`` ('-': stdout). A file is written whole or not at all
    (common.atomic_files) and its parent folders are created; returns the file's path (None for stdout)."""
    from dualrgb.common.atomic_files import atomic_write
    from dualrgb.simulation.versions import stamped

    text = json.dumps(stamped(fmt, data), indent=2, default=default) + "\n"
    if str(dest) == STDOUT:
        sys.stdout.write(text)
        sys.stdout.flush()
        return None
    path = Path(dest)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, text)
    log.info("wrote %s", path)
    return path
