"""Camera response function and exposure-time linearity (thesis 4.1 and appendix A).

From an exposure sweep of a uniform field: the mean green signal above black per exposure time; the linear
fit through the origin over the clearly linear part; the linear limit (the highest signal still within
``tolerance`` of the fit, thesis: ~11 000 DN for the D610); and the exposure times whose response departs
from the line in the linear region ("bumps" of a mechanical shutter), flagged by changepoint detection
(ruptures, PELT on the relative residuals, as appendix A.2.4 proposes) together with a robust outlier test.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

log = logging.getLogger(__name__)


@dataclass
class CrfResult:
    exposures: list[float]
    signal_dn: list[float]              # mean green above black per exposure
    slope_dn_per_s: float
    linear_limit_dn: float
    flagged: list[float] = field(default_factory=list)      # exposure times departing from linearity
    residuals: list[float] = field(default_factory=list)    # relative deviation from the line
    changepoints: list[float] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"exposures": self.exposures, "signal_dn": [round(v, 2) for v in self.signal_dn],
                "slope_dn_per_s": self.slope_dn_per_s, "linear_limit_dn": round(self.linear_limit_dn, 1),
                "flagged_exposures": self.flagged, "changepoints": self.changepoints,
                "relative_residuals": [round(v, 5) for v in self.residuals]}


def analyse_crf(exposures: Sequence[float], signal: Sequence[float], *, min_signal: float = 500.0,
                fit_below: float = 8000.0, tolerance: float = 0.02, flag_threshold: float = 0.012,
                penalty: float = 3.0) -> CrfResult:
    t = np.asarray(exposures, dtype=float)
    s = np.asarray(signal, dtype=float)
    order = np.argsort(t)
    t, s = t[order], s[order]
    lin = (s > min_signal) & (s < fit_below)
    if lin.sum() < 3:
        raise ValueError(f"need at least 3 exposures with {min_signal:g}-{fit_below:g} DN to fit the CRF, "
                         f"got {int(lin.sum())}")
    # robust slope through the origin: median of s/t over the fitting range, then least squares on inliers
    ratios = s[lin] / t[lin]
    k = float(np.median(ratios))
    inl = np.abs(ratios / k - 1) < 3 * tolerance
    k = float((s[lin][inl] * t[lin][inl]).sum() / (t[lin][inl] ** 2).sum())
    rel = s / (k * t) - 1.0
    within = (np.abs(rel) <= tolerance) & (s > min_signal)
    above = np.nonzero(~within & (s > fit_below))[0]
    limit = float(s[above[0] - 1]) if len(above) and above[0] > 0 else float(s[within].max())
    # bumps are looked for where the sensor is clearly linear: between the knee onset and the limit the
    # compressive response would be flagged as a shutter fault
    region = (s > min_signal) & (s <= min(limit, fit_below))
    flagged: set[float] = set()
    cps: list[float] = []
    r = rel[region]
    if len(r) >= 4:
        import ruptures as rpt
        algo = rpt.Pelt(model="l2", min_size=1, jump=1).fit(r.reshape(-1, 1))
        sigma = max(float(np.median(np.abs(r - np.median(r)))) * 1.4826, 1e-4)
        bkps = algo.predict(pen=penalty * sigma ** 2 * np.log(len(r)))
        idx = np.nonzero(region)[0]
        start = 0
        for end in bkps:
            seg = r[start:end]
            if end - start <= 2 and np.abs(seg.mean()) > flag_threshold:     # a short excursion = a bump
                flagged.update(float(x) for x in t[idx[start:end]])
            if end < len(r):
                cps.append(float(t[idx[end]]))
            start = end
        flagged.update(float(x) for x in t[idx][np.abs(r) > max(flag_threshold, 4 * sigma)])
    return CrfResult(t.tolist(), s.tolist(), k, limit, sorted(flagged), rel.tolist(), cps)
