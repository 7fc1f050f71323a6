"""Which charts a calibration uses, as the technician chooses them (Qt-free; the CLI, the GUI's calibration box
and the demo all read them here): per target, the chart's reference file, its layout and the patches to leave
out. No file: the mode's packaged target (simulation.charts.PACKAGED_STANDS_FOR says what each stands for).

    choices = {"train": ChartChoice("SG.txt", "10x14", "A1,A10"), "test": ChartChoice("CC24.cie")}
    charts = load_charts(choices, "reflective")     # read before any device acts; one line per problem
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

ROLES = ("train", "test")


@dataclass(frozen=True)
class ChartChoice:
    """One target's chart as chosen: its reference file (spectral CGATS or CSV), layout ROWSxCOLS ('' = the
    file's own) and the patches to leave out (comma-separated names)."""

    file: str = ""
    layout: str = ""
    leave_out: str = ""

    @property
    def given(self) -> bool:
        return bool(self.file.strip())


def load_charts(choices: dict[str, ChartChoice], mode: str) -> dict[str, Any]:
    """The stand's own charts (simulation.charts.Chart) for the targets whose file is given; the others are left
    out of the result (the packaged targets of ``mode`` are used for them). Every problem is one line naming the
    file (simulation.charts.ChartError, a SpectralDataError: a ValueError); warnings (a NUMBER_OF_FIELDS mismatch,
    a range extended beyond the measurement) are logged."""
    from dualrgb.simulation.charts import read_chart
    from dualrgb.simulation.defaults import default_grid

    grid = default_grid(mode)
    out = {}
    for role in ROLES:
        choice = choices.get(role) or ChartChoice()
        if not choice.given:
            if choice.layout.strip() or choice.leave_out.strip():
                raise ValueError(f"the {'training' if role == 'train' else role} chart's layout or patches to leave "
                                 f"out are given without its reference file (--{role}-target FILE)")
            continue
        out[role] = read_chart(Path(choice.file.strip()), grid, role=role, mode=mode,
                               layout=choice.layout.strip() or None, leave_out=choice.leave_out)
        log.info("%s chart: %s", role, out[role].label())
    return out


def definition(charts: dict[str, Any]) -> dict[str, Any]:
    """What a session records of the charts on the stand (a resume with other charts is refused, so target frames
    of one chart are never kept for another): per target the file name and sha256, the layout and the patches left
    out, or ``"packaged"`` for the mode's packaged target."""
    def of(role: str) -> Any:
        c = charts.get(role)
        return "packaged" if c is None else {"file": c.file.name, "sha256": c.file.sha256, "layout": list(c.layout),
                                             "left_out": list(c.leave_out)}
    return {"charts": {role: of(role) for role in ROLES}}


def charts_of_profile(profile: Any) -> dict[str, Any]:
    """The stand's own charts a calibration profile was made with (its ``charts`` records), read again from the files
    they name and checked against the recorded sha256 ({}: it used the packaged targets); a file that is gone or
    changed is a one-line ValueError naming it."""
    records = dict(getattr(profile, "charts", None) or {})
    choices = {}
    for role, rec in records.items():
        if not isinstance(rec, dict) or rec.get("packaged"):
            continue
        layout = "x".join(str(int(v)) for v in rec.get("layout") or ())
        choices[role] = ChartChoice(str(rec.get("path") or rec.get("file") or ""), layout,
                                    ",".join(rec.get("left_out") or ()))
    charts = load_charts(choices, profile.mode) if choices else {}
    for role, chart in charts.items():
        if chart.file.sha256 != records[role].get("sha256"):
            raise ValueError(f"{chart.file.path}: not the {role} chart calibration {profile.id} was made with (its "
                             "sha256 differs); put that file back, or calibrate again")
    return charts
