"""Which exposures a session's darks and flats cover ("darks 2/4 exposures"): every exposure a capture uses needs
a master dark (thesis 8.2.1) and every (light, exposure) an open-gate flat (8.2.2), or processing falls back to
the black level and the calibration is incomplete."""
from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from dualrgb.app.processing.calibration import EXPOSURE_RTOL
from dualrgb.core.vocabulary import Role, latest_takes, light_of, role_of

if TYPE_CHECKING:
    from dualrgb.core.protocols import Session

log = logging.getLogger(__name__)


def _has(times: Sequence[float], t: float) -> bool:
    return any(abs(x - t) <= EXPOSURE_RTOL * max(x, t) for x in times)


@dataclass
class Coverage:
    """Darks per exposure time and flats per (light, exposure) that the plan needs and the session has."""

    dark_times: list[float] = field(default_factory=list)          # every exposure the plan uses
    darks_missing: list[float] = field(default_factory=list)
    flats_needed: list[tuple[str, float]] = field(default_factory=list)
    flats_missing: list[tuple[str, float]] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return not self.darks_missing and not self.flats_missing

    def summary(self) -> str:
        d_have = len(self.dark_times) - len(self.darks_missing)
        f_have = len(self.flats_needed) - len(self.flats_missing)
        return (f"darks {d_have}/{len(self.dark_times)} exposures, flats {f_have}/{len(self.flats_needed)} "
                "light exposures")

    def missing(self) -> str:
        parts = [f"darks at {', '.join(f'{t:.6g} s' for t in self.darks_missing)}"] if self.darks_missing else []
        parts += [f"flats of {n} at {t:.6g} s" for n, t in self.flats_missing]
        return "; ".join(parts) or "nothing"


def coverage(session: Session, plan: Mapping[str, Sequence[float]], *, dark_frames: int = 1,
             flat_frames: int = 1) -> Coverage:
    """Coverage of ``plan`` (light name -> exposures) by the session's darks (>= ``dark_frames`` per time) and
    flats (>= ``flat_frames`` per light and time)."""
    darks: dict[float, int] = {}
    flats: dict[tuple[str, float], int] = {}
    for e in latest_takes(session.entries()):
        role = role_of(e)
        if e.exposure_s is None:
            continue
        if role is Role.DARK:
            darks[float(e.exposure_s)] = darks.get(float(e.exposure_s), 0) + 1
        elif role is Role.FLAT:
            key = (light_of(e), float(e.exposure_s))
            flats[key] = flats.get(key, 0) + 1
    out = Coverage()
    out.dark_times = sorted({float(t) for ts in plan.values() for t in ts})
    enough_darks = [t for t, n in darks.items() if n >= dark_frames]
    out.darks_missing = [t for t in out.dark_times if not _has(enough_darks, t)]
    out.flats_needed = [(n, float(t)) for n, ts in plan.items() for t in sorted(ts)]
    for name, t in out.flats_needed:
        have = [x for (n, x), k in flats.items() if n == name and k >= flat_frames]
        if not _has(have, t):
            out.flats_missing.append((name, t))
    return out


def plan_coverage(have: Mapping[str, Sequence[float]], needed: Mapping[str, Sequence[float]]) -> Coverage:
    """Coverage of ``needed`` (light -> exposures) by a calibration made for ``have``: a calibration profile holds
    master darks at every exposure of its plan and a flat-field white per light for that light's exposures, so
    an HDR plan asking for longer exposures than it was made for leaves it incomplete."""
    dark_have = sorted({float(t) for ts in have.values() for t in ts})
    out = Coverage()
    out.dark_times = sorted({float(t) for ts in needed.values() for t in ts})
    out.darks_missing = [t for t in out.dark_times if not _has(dark_have, t)]
    out.flats_needed = [(n, float(t)) for n, ts in needed.items() for t in sorted(ts)]
    out.flats_missing = [(n, t) for n, t in out.flats_needed if not _has([float(x) for x in have.get(n, [])], t)]
    return out
