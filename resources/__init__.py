"""Data only: LED spectra, camera sensitivities, targets, presets and reference charts, read with
importlib.resources from the installed package; and the per-user folder for what the app writes at run time.

Every CSV says in its header its units, its source and how it was made; ``python -m tools.generate_resources``
(``make resources``, not shipped) rebuilds them all from colour-science data and the models in that script.
Nothing is ever written into the package: ``user_path`` is the place (e.g. ``~/.local/share/dualrgb`` on Linux,
``%LOCALAPPDATA%\\dualrgb`` on Windows, ``~/Library/Application Support/dualrgb`` on macOS; the
``DUALRGB_DATA_DIR`` environment variable moves it), and a packaged file is the fallback where a user copy
can override it (``parsimony.json``).
"""
from __future__ import annotations

import os
from importlib import resources as _res
from pathlib import Path

APP_NAME = "dualrgb"
DATA_DIR_ENV = "DUALRGB_DATA_DIR"


def path(*parts: str) -> Path:
    """Filesystem path of a packaged resource file, e.g. ``path("leds", "sphere10_relative.csv")``."""
    return Path(str(_res.files(__name__).joinpath(*parts)))


def user_path(*parts: str) -> Path:
    """Path under the per-user data folder (not created), e.g. ``user_path("studies", "parsimony")``."""
    base = os.environ.get(DATA_DIR_ENV)
    if not base:
        import platformdirs

        base = platformdirs.user_data_dir(APP_NAME, appauthor=False)
    return Path(base).joinpath(*parts)


def user_or_packaged(*parts: str) -> Path:
    """The user's copy of a data file when there is one, else the packaged file (which may be absent too)."""
    mine = user_path(*parts)
    return mine if mine.is_file() else path(*parts)


def world_names() -> list[str]:
    """The packaged virtual-lab worlds' names (worlds/*.json stems), ``nominal`` first (cheap: for option help)."""
    names = sorted(p.stem for p in path("worlds").glob("*.json"))
    return sorted(names, key=lambda n: n != "nominal")
