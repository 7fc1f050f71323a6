"""Type-check the ``dualrgb`` namespace as it is installed: ``python -m tools.typecheck [mypy options]``.

The checkout keeps app/, common/, core/, drivers/, simulation/ and resources/ at the top while the wheel installs them
as
``dualrgb.app`` ... (pyproject.toml's package-dir). mypy finds modules by their folders and knows no such mapping, so
this links the folders under ``build/typecheck/dualrgb/`` (pyproject's ``mypy_path``; copies where the OS refuses
links), runs mypy with pyproject's settings, and prints each file by its own path (``app/cli.py``, not the link's).
The exit status is mypy's.
"""
from __future__ import annotations

import os
import re
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TREE = ROOT / "build" / "typecheck" / "dualrgb"
FOLDERS = ("app", "common", "core", "drivers", "simulation", "resources")
LINKED_FILES = ("__init__.py", "__main__.py", "py.typed")
PREFIX = re.compile(r"build[/\\]typecheck[/\\]dualrgb[/\\]")


def _link(target: Path, link: Path) -> None:
    if link.is_symlink() and Path(os.readlink(link)) == target:
        return
    if link.is_symlink() or link.is_file():
        link.unlink()
    elif link.is_dir():
        shutil.rmtree(link)
    try:
        link.symlink_to(target, target_is_directory=target.is_dir())
    except OSError:                      # Windows without the symlink privilege: a copy, made afresh each run
        (shutil.copytree if target.is_dir() else shutil.copy2)(target, link)


def link_tree() -> Path:
    """``build/typecheck/dualrgb`` with the namespace's folders and files linked in; returns its parent."""
    TREE.mkdir(parents=True, exist_ok=True)
    for name in FOLDERS:
        _link(ROOT / name, TREE / name)
    for name in LINKED_FILES:
        _link(ROOT / "dualrgb" / name, TREE / name)
    return TREE.parent


def main(argv: list[str]) -> int:
    from mypy import api

    link_tree()
    os.chdir(ROOT)
    out, err, status = api.run(argv)
    sys.stdout.write(PREFIX.sub("", out))
    sys.stderr.write(PREFIX.sub("", err))
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
