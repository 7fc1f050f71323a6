"""README's generated sections and the committed study runs they come from (docs/data/), for the tests that check
README holds what the generator writes."""
from __future__ import annotations

from pathlib import Path

import pytest

from dualrgb import resources


def readme_and_run(name: str) -> tuple[str, Path]:
    """README's text and the committed run ``docs/data/<name>``; skipped where they are not beside the package
    (an installed wheel)."""
    root = resources.path().parent
    readme, committed = root / "README.md", root / "docs" / "data" / name
    if not readme.is_file() or not committed.is_file():
        pytest.skip("README.md and docs/data are not beside the package (installed wheel)")
    return readme.read_text(encoding="utf-8"), committed
