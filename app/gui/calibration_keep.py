"""*Calibrate again* -> *Keep*: the calibration computed again from the frames the session holds, with nothing lit.

Keep is offered only where the session allows it (:func:`keep_refusal`): the new calibration's settings recorded in
the session's definition (the charts: a frame of one chart is never used for another) are the session's, and the
session holds a training-target frame under every light, whose exposures are the open-gate exposures the
calibration is computed at (:func:`kept_base`: no auto-exposure, so no metering under the light). The stand's
sphere is wrapped (:class:`UnlitSphere`) so that a frame the session does not hold is refused before anything is
switched on, rather than shot.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

from dualrgb.app.protocols import Session
from dualrgb.app.session.manifest import definition_differences, normalise
from dualrgb.app.workflow.charts import definition as chart_definition
from dualrgb.app.workflow.light_safety import LightSafetyError
from dualrgb.app.workflow.vocabulary import NamedLight, Role, Subject, role_of, subject_of

log = logging.getLogger(__name__)


def kept_base(session: Session) -> dict[str, float]:
    """Light name -> the exposure of the session's training-target frames under it (the calibration's open-gate
    exposure for that light)."""
    out: dict[str, float] = {}
    train = Subject.target("train")
    for e in session.entries():
        if role_of(e) is Role.TARGET and subject_of(e) == train and e.exposure_s:
            if e.light_name:
                out[e.light_name] = float(e.exposure_s)
    return out


def keep_refusal(session: Session, charts: dict[str, Any], lights: Sequence[NamedLight]) -> str:
    """Why the session's calibration frames cannot be kept for a calibration with ``charts`` under ``lights``
    ('' when they can)."""
    wanted = normalise(chart_definition(charts))
    stored = dict(getattr(session, "definition", {}) or {})
    common = [k for k in wanted if k in stored]
    diffs = definition_differences({k: stored[k] for k in common}, {k: wanted[k] for k in common})
    if diffs:
        more = f" (and {len(diffs) - 1} more)" if len(diffs) > 1 else ""
        return f"its frames were taken with other settings: {diffs[0]}{more}"
    base = kept_base(session)
    missing = [nl.name for nl in lights if nl.name not in base]
    if missing:
        return f"it holds no training-target frame under {', '.join(missing)}"
    return ""


class UnlitSphere:
    """The stand's sphere for a Keep run: everything as the sphere, except that switching the light on is refused
    (a LightSafetyError naming what is missing) - a Keep run takes only what the session holds."""

    def __init__(self, sphere: Any):
        self._sphere = sphere

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sphere, name)

    def on(self, max_on_s: float | None = None) -> Any:
        raise LightSafetyError("Keep: a frame the calibration needs is not in the session, and Keep lights "
                               "nothing; the light stays off (choose Re-shoot to take the missing frames)")
