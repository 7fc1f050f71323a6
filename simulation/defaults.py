"""The defaults that the studies chose, per target mode (``resources/parsimony.json``): spectral grid,
characterisation model, HDR exposures per light and HDR merge. :func:`load_defaults` reads the user's copy
(per-user data folder, written by ``dualrgb study parsimony|hdr --write-defaults``) when there is one, else the
packaged file; :func:`save_defaults` updates one mode of one file, keeping what another study or mode wrote there.

Format ``dualrgb-parsimony/2`` (one entry per mode; every choice made on training data, never on the test
target the app reports)::

    {"format": "dualrgb-parsimony/2", "software": {...}, "generated_by": "...", "created": "...",
     "modes": {"reflective":   {"spectral_step_nm": 10.0, "spectral_start_nm": 410.0, "spectral_end_nm": 780.0,
                                "characterisation_model": "...", "hdr_exposures": 2, "hdr_merge": "variance",
                                "tolerance_de00": 0.05, "criteria": {...}, "evidence": {...}},
               "transmissive": {...}}}

The older single-mode ``dualrgb-parsimony/1`` files (the four keys at the top level) stay readable: their values
then hold for every mode. The studies (simulation.studies.parsimony, simulation.studies.hdr) write it; the
simulation, the processing, the copy-stand workflow and ``dualrgb simulate`` read it, each for its own mode. It
lives outside the studies so that core modules never import a study.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

from dualrgb import resources
from dualrgb.common.atomic_files import atomic_write
from dualrgb.common.strict_json import dumps as strict_dumps
from dualrgb.simulation.choices import MODES
from dualrgb.simulation.grid import SpectralGrid

log = logging.getLogger(__name__)

FORMAT = "dualrgb-parsimony/2"
FORMAT_V1 = "dualrgb-parsimony/1"          # single-mode files written before the per-mode studies: still read
FALLBACK_DEFAULTS: dict[str, Any] = {"spectral_step_nm": 10.0, "spectral_start_nm": 410.0, "spectral_end_nm": 780.0,
                                     "characterisation_model": "linear", "hdr_exposures": 1, "hdr_merge": "thesis"}


def check_mode(mode: str) -> str:
    if mode not in MODES:
        raise ValueError(f"mode {mode!r}: expected one of {', '.join(MODES)}")
    return mode


def _read(p: str | Path) -> dict:
    return json.loads(Path(p).read_text(encoding="utf-8"))


def _mode_entry(data: dict, mode: str, source: str | Path) -> dict | None:
    """The choices of ``mode`` in a parsed defaults file of either format (None: unusable, with a warning)."""
    if data.get("format") == FORMAT_V1:
        return data
    if data.get("format") == FORMAT:
        entry = data.get("modes", {}).get(mode)
        if entry is None:
            log.warning("%s: no defaults for mode %s; using the thesis defaults for it", source, mode)
        return entry
    log.warning("%s: format %r, expected %r (or %r); using the thesis defaults", source, data.get("format"), FORMAT,
                FORMAT_V1)
    return None


def load_defaults(mode: str, path: str | Path | None = None) -> dict:
    """The defaults the studies chose for ``mode`` ('reflective' or 'transmissive'): from ``path``, else the
    user's parsimony.json (per-user data folder), else the packaged resources/parsimony.json; the thesis'
    choices (FALLBACK_DEFAULTS: 410-780 nm at 10 nm, least squares, one exposure, eq 8.9) where none is readable.
    Returns the keys of FALLBACK_DEFAULTS."""
    check_mode(mode)
    p = path or resources.user_or_packaged("parsimony.json")
    try:
        data = _read(p)
    except (OSError, ValueError) as exc:
        log.info("no parsimony defaults (%s); using %s", exc, FALLBACK_DEFAULTS)
        return dict(FALLBACK_DEFAULTS)
    entry = _mode_entry(data, mode, p) or {}
    return {k: entry.get(k, v) for k, v in FALLBACK_DEFAULTS.items()}


def default_grid(mode: str, path: str | Path | None = None) -> SpectralGrid:
    """The spectral grid the parsimony study chose for ``mode`` (:func:`load_defaults`)."""
    d = load_defaults(mode, path)
    return SpectralGrid(float(d["spectral_start_nm"]), float(d["spectral_end_nm"]), float(d["spectral_step_nm"]))


def _upgrade(data: dict) -> dict:
    """A parsed file as format 2 (a format-1 file's choices copied to every mode; anything else: empty)."""
    if data.get("format") == FORMAT:
        return data
    if data.get("format") == FORMAT_V1:
        entry = {k: v for k, v in data.items() if k not in ("format", "software", "generated_by", "created")}
        return {"modes": {m: json.loads(json.dumps(entry)) for m in MODES}}
    return {}


def save_defaults(path: str | Path, mode: str, update: dict, header: dict | None = None) -> Path:
    """Write ``update`` into ``mode``'s entry of the defaults file at ``path``, keeping the keys (and evidence)
    another study or the other mode wrote there: the parsimony study owns the grid, model and exposure count,
    ``dualrgb study hdr`` the HDR estimator. ``header``: top-level keys (format tag, software versions,
    generated_by, created) to set."""
    check_mode(mode)
    p = Path(path)
    try:
        data = _upgrade(_read(p))
    except (OSError, ValueError):
        data = {}
    modes = data.setdefault("modes", {})
    entry = modes.setdefault(mode, {})
    evidence = {**entry.get("evidence", {}), **update.get("evidence", {})}
    criteria = {**entry.get("criteria", {}), **update.get("criteria", {})}
    entry.update({**update, "evidence": evidence, "criteria": criteria})
    data.update({**(header or {}), "format": FORMAT})
    ordered = {"format": FORMAT, **{k: v for k, v in data.items() if k not in ("format", "modes")},
               "modes": {m: modes[m] for m in MODES if m in modes}}
    p.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(p, strict_dumps(ordered, indent=2) + "\n")
    return p
