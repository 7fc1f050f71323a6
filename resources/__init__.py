"""Data only: LED spectra, camera sensitivities, targets and presets, loaded with importlib.resources.

Every CSV says in its header its units, its source and how it was made; ``python -m resources.generate``
(``make resources``) rebuilds them all from colour-science data and the models in that script.
"""
from __future__ import annotations

from importlib import resources as _res
from pathlib import Path


def path(*parts: str) -> Path:
    """Filesystem path of a packaged resource file, e.g. ``path("leds", "sphere10_relative.csv")``."""
    return Path(str(_res.files(__name__).joinpath(*parts)))
