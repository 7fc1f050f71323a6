"""CRF and exposure-time linearity sweep (thesis 4.1, appendix A) on the open gate.

For each light level, exposures run from the shortest offered time upwards until the field clips (or the
light-on limit is reached); the mean green signal above black of the central region is recorded per frame,
and app.processing.crf_analysis.analyse_crf finds the linear limit and flags exposure times that depart from linearity.
Several light levels give every exposure time a sample inside the linear range (appendix A.2.1).
"""
from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from dualrgb.app.processing.crf_analysis import CrfResult, analyse_crf
from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.sequences.base import Sequence as BaseSequence
from dualrgb.core.light_safety import StandFacts
from dualrgb.core.messages import Place, PlanSteps, ReadFrame, Shot
from dualrgb.core.vocabulary import EventKind, exposure_key
from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)


def green_mean(frame, region: float = 0.3) -> float:
    h, w = frame.mosaic.shape
    r0, r1 = int(h * (1 - region) / 2) // 2 * 2, int(h * (1 + region) / 2) // 2 * 2
    c0, c1 = int(w * (1 - region) / 2) // 2 * 2, int(w * (1 + region) / 2) // 2 * 2
    vals = []
    for name, (r, c), idx in frame.channels():
        if name.startswith("G"):
            vals.append(float(frame.mosaic[r0 + r:r1:2, c0 + c:c1:2].mean()) - frame.black_levels[idx])
    return float(np.mean(vals))


class CrfSweep(BaseSequence):
    name = "CRF sweep"

    def __init__(self, facts: StandFacts, light: LightSource, levels: Sequence[float] = (1.0, 0.25, 0.0625),
                 exposures: Sequence[float] | None = None, min_exposure_s: float = 1 / 4000):
        super().__init__()
        self.facts = facts
        self.light = light
        self.levels = list(levels)
        limit = facts.max_exposure_s
        offered = exposures or facts.shutter_speeds()
        self.exposures = [t for t in sorted(offered) if min_exposure_s <= t <= limit]
        self.samples: dict[float, list[tuple[float, float]]] = {}
        self.results: dict[float, CrfResult] = {}

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame("crf", t, f"{self.light.label()} x {lv:g}", "open gate, until clipping")
                for lv in self.levels for t in self.exposures]

    def _scaled(self, level: float) -> LightSource:
        return LightSource(self.light.leds, tuple(v * level for v in self.light.levels), f"CRF x{level:g}")

    def _steps(self) -> PlanSteps:
        total = len(self.levels) * len(self.exposures)
        yield Place("open-gate", ask="Open gate (no target), then continue")
        step = 0
        for lv in self.levels:
            light = self._scaled(lv)
            pts: list[tuple[float, float]] = []
            clipped = 0
            for t in self.exposures:
                taken = yield Shot("crf", light, t, f"crf/{lv:g}/{exposure_key(t)}", {"crf_level": lv})
                frame = yield ReadFrame(taken.entry, keep=False)
                g = green_mean(frame)
                pts.append((t, g))
                step += 1
                yield ProgressEvent(step, total, f"CRF x{lv:g}: {t:g} s -> {g:.0f} DN", kind=EventKind.FRAME,
                                    data={"exposure_s": t, "signal_dn": g, "level": lv})
                if g >= 0.97 * (frame.white_level - max(frame.black_levels)):
                    clipped += 1
                    if clipped >= 2:
                        break
            self.samples[lv] = pts
            try:
                self.results[lv] = analyse_crf([p[0] for p in pts], [p[1] for p in pts])
            except ValueError as exc:
                log.info("CRF x%g: %s", lv, exc)
        yield ProgressEvent(total, total, "CRF sweep analysed", kind=EventKind.DONE, data={"result": self.summary()})

    def summary(self) -> dict:
        flagged = sorted({t for r in self.results.values() for t in r.flagged})
        limits = [r.linear_limit_dn for r in self.results.values()]
        return {"levels": {f"{lv:g}": r.to_dict() for lv, r in self.results.items()},
                "linear_limit_dn": float(np.median(limits)) if limits else None,
                "flagged_exposures": flagged}
