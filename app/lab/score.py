"""``dualrgb lab score SESSION``: a session's deliverables against the virtual lab's originals, a separate step
after the delivery (no production file carries it).

Each original delivered in the session (session.json ``originals``, each naming its sidecar) is compared with the
virtual original the lab showed for it (``stand_ins``: identifier -> a virtual original's name; default the
mode's, painting or film): per-pixel dE00 of the delivered XYZ TIFF and per-pixel spectral RMSE of the delivered
spectra (the ENVI cube, or the cube made from the channel files through the calibration's estimator), over the
whole frame, the edges and the flat regions (app.lab.truth). The truth is made at the sensor's size the sidecar
names, so a delivery at half resolution is compared on the 2x2 cells.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dualrgb.app.lab.truth import assess, original_truth, qa_text
from dualrgb.app.session.paths import deliverable

log = logging.getLogger(__name__)

DEFAULT_STAND_INS = {"reflective": "painting", "transmissive": "film"}


@dataclass
class OriginalScore:
    """One delivered original against its virtual original."""

    identifier: str
    shown_as: str
    sidecar: Path
    figures: dict[str, Any]

    def line(self) -> str:
        """``ACC-1 (painting): virtual truth (painting, full): dE00 mean 0.54 / p90 0.90, spectral RMSE ...``"""
        return f"{self.identifier}: {qa_text(self.figures)}"

    def to_dict(self) -> dict[str, Any]:
        return {"identifier": self.identifier, "shown_as": self.shown_as, "sidecar": str(self.sidecar),
                **self.figures}


def stand_ins(pairs: list[str]) -> dict[str, str]:
    """``["ACC-1=shadow", ...]`` -> {identifier: virtual original}; a one-line ValueError for anything else."""
    out = {}
    for pair in pairs:
        ident, sep, name = pair.partition("=")
        if not sep or not ident.strip() or not name.strip():
            raise ValueError(f"--original {pair!r}: expected ID=NAME (the original's identifier = the virtual "
                             "original it was shown as, e.g. ACC-1=shadow)")
        out[ident.strip()] = name.strip()
    return out


def delivered(session: Path) -> dict[str, dict[str, Any]]:
    """identifier -> its entry in the session's ``originals`` (session.json)."""
    path = Path(session) / "session.json"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a session's settings ({exc}); expected a dualrgb session folder") from None
    originals = doc.get("originals") if isinstance(doc, dict) else None
    return {str(k): v for k, v in (originals or {}).items() if isinstance(v, dict) and v.get("sidecar")}


def score_original(identifier: str, sidecar: Path, shown_as: str | None = None) -> OriginalScore:
    """One delivery (its sidecar) against the virtual original ``shown_as`` (None: the mode's)."""
    from dualrgb.app.workflow.delivery_folder import read_sidecar
    from dualrgb.app.workflow.profile import load_profile

    doc = read_sidecar(sidecar)
    mode = str((doc.get("original") or {}).get("mode") or "reflective")
    name = shown_as or DEFAULT_STAND_INS.get(mode, "painting")
    size = doc.get("resolution") or {}
    profile = load_profile(Path(doc["calibration"]["file"]))
    files = {k: sidecar.parent / v for k, v in (doc.get("files") or {}).items()}
    truth = original_truth(name, int(size["sensor_height"]), int(size["sensor_width"]), profile.mode)
    figures = assess(truth, files, list(profile.white_xyz), profile.estimator)
    log.info("%s (%s): %s", identifier, name, qa_text(figures))
    return OriginalScore(identifier, name, sidecar, figures)


def score_session(session: Path, shown_as: dict[str, str] | None = None) -> list[OriginalScore]:
    """Every original delivered in ``session`` (module docstring)."""
    shown_as = shown_as or {}
    originals = delivered(session)
    unknown = sorted(set(shown_as) - set(originals))
    if unknown:
        raise ValueError(f"{session}: no delivered original {', '.join(unknown)} (delivered: "
                         f"{', '.join(sorted(originals)) or 'none'})")
    out = []
    for ident, entry in originals.items():
        sidecar = deliverable(Path(session), entry["sidecar"])      # recorded relative to the session folder
        if sidecar is None or not sidecar.is_file():
            raise ValueError(f"{session}: the delivery of {ident!r} ({entry['sidecar']}) is not there")
        out.append(score_original(ident, sidecar, shown_as.get(ident)))
    return out
