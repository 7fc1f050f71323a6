"""The defaults that the studies chose (``resources/parsimony.json``, format ``dualrgb-parsimony/1``): spectral
step, characterisation model, HDR exposures per light and HDR merge. :func:`load_defaults` reads the user's copy
(per-user data folder, written by ``dualrgb study parsimony|hdr --write-defaults``) when there is one, else the
packaged file; :func:`save_defaults` updates one file, keeping what another study wrote there.

The studies (simulation.studies.parsimony, simulation.studies.hdr) write it; the processing, the copy-stand
workflow and ``dualrgb simulate`` read it. It lives outside the studies so that core modules never import a study.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path

import resources
from common.atomic_files import atomic_write

log = logging.getLogger(__name__)

FORMAT = "dualrgb-parsimony/1"
FALLBACK_DEFAULTS = {"spectral_step_nm": 10.0, "characterisation_model": "linear", "hdr_exposures": 1,
                     "hdr_merge": "thesis"}


def load_defaults(path: str | None = None) -> dict:
    """The app's defaults chosen by the parsimony study: ``path``, else the user's parsimony.json (per-user data
    folder), else the packaged resources/parsimony.json; the thesis defaults when none is readable."""
    try:
        p = path or resources.user_or_packaged("parsimony.json")
        data = json.loads(open(p, encoding="utf-8").read())
    except (OSError, ValueError) as exc:
        log.info("no parsimony defaults (%s); using %s", exc, FALLBACK_DEFAULTS)
        return dict(FALLBACK_DEFAULTS)
    if data.get("format") != FORMAT:
        log.warning("%s: format %r, expected %r; using the thesis defaults", p, data.get("format"), FORMAT)
        return dict(FALLBACK_DEFAULTS)
    return {k: data.get(k, v) for k, v in FALLBACK_DEFAULTS.items()}


def save_defaults(path: str, update: dict) -> Path:
    """Write ``update`` into the defaults file, keeping keys (and evidence) another study wrote there: the
    parsimony study owns the step, model and exposure count, ``dualrgb study hdr`` the HDR estimator."""
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
        if data.get("format") != FORMAT:
            data = {}
    except (OSError, ValueError):
        data = {}
    evidence = {**data.get("evidence", {}), **update.get("evidence", {})}
    data.update({**update, "format": FORMAT, "evidence": evidence})
    p.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(p, json.dumps(data, indent=2) + "\n")
    return p
