"""What an original's last delivery asked for, so that a re-delivery (``dualrgb process``, the window's
*Re-deliver*) gives the same deliverables again with the new calibration: the extra masters, the access copies, the
spectral choice and rendering light, the institution's creator and rights (the sidecar's ``delivery_settings``) and
the sampling (ppi) it was delivered at, which belongs to the frames (the stand's height when they were shot), not to
the calibration used now. A command that names its own (``--delivery-settings``, ``--spectral``, ``--ppi``, the
window's ppi field) wins; an original never delivered, or whose sidecar is gone, gets the settings file's.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path

from dualrgb.app.workflow.delivery.delivery_settings import DeliverySettings, from_record, load
from dualrgb.core.session.paths import inside

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PreviousRequest:
    """The settings and the sampling of an original's current delivery, and the sidecar they were read from."""

    settings: DeliverySettings
    ppi: float | None
    sidecar: Path

    def said(self) -> str:
        extra = [*self.settings.masters, *(f"{a} access copy" for a in self.settings.access)]
        sampling = f"{self.ppi:.0f} ppi" if self.ppi else "no ppi"
        return (f"as its last delivery asked ({', '.join(extra) or 'the default masters'}; {sampling}; "
                f"{self.sidecar.name})")


def previous_request(session_dir: Path, record: dict, resolution: str) -> PreviousRequest | None:
    """What the delivery session.json's ``record`` of an original names asked for, at ``resolution`` (its ppi
    halved or doubled when the resolution changes); None when there is none to read. A sidecar that is not JSON or
    records settings the settings file could not hold is ValueError naming it (that original is not delivered)."""
    sidecar = inside(Path(session_dir), record.get("sidecar") if isinstance(record, dict) else None)
    if sidecar is None or not sidecar.is_file():
        return None
    try:
        doc = json.loads(sidecar.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{sidecar}: not readable JSON ({exc}); give --delivery-settings and --ppi to deliver "
                         "it again") from None
    asked = doc.get("delivery_settings") if isinstance(doc, dict) else None
    if not isinstance(asked, dict):
        return None
    settings = from_record(asked, sidecar, load())
    ppi = doc.get("ppi")
    ppi = float(ppi) if isinstance(ppi, int | float) and not isinstance(ppi, bool) and ppi > 0 else None
    was = (doc.get("resolution") or {}).get("mode")
    if ppi and was in ("full", "half") and was != resolution:
        ppi *= 2.0 if resolution == "full" else 0.5
    return PreviousRequest(settings, ppi, sidecar)


__all__ = ["PreviousRequest", "previous_request"]
