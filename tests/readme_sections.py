"""The docs pages' generated sections and the committed study runs they come from (docs/data/), for the tests that
check a page holds what its generator writes. (The sections lived in README.md before the docs site; the module
keeps its name for the tests that import it.)"""
from __future__ import annotations

from pathlib import Path

import pytest

from dualrgb import resources


def page_and_run(page: str, name: str) -> tuple[str, Path]:
    """The text of the docs page ``page`` (a path from the checkout's root, e.g. docs/explanation/spectral.md) and
    the committed run ``docs/data/<name>``; skipped where they are not beside the package (an installed wheel)."""
    root = resources.path().parent
    doc, committed = root / page, root / "docs" / "data" / name
    if not doc.is_file() or not committed.is_file():
        pytest.skip(f"{page} and docs/data are not beside the package (installed wheel)")
    return doc.read_text(encoding="utf-8"), committed
