"""The plan of a day's queue before anything is shot (Qt-free): which rows will be shot, which are kept (already
delivered in the session) and which are refused, with the reason - a bad row (app.workflow.day.queue_csv), an original
whose mode is not the calibration's (app.workflow.stand.mode_rule). ``dualrgb capture --queue FILE --check`` prints it
and touches no device; ``dualrgb capture --queue`` and the GUI's *Import CSV…* act on the same plan.

    plan = plan_queue(read_queue_csv(path), profile, session=session, force=False)
    for line in plan.lines(): print(line)
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dualrgb.app.workflow.day.queue_csv import QueueImport
from dualrgb.app.workflow.stand.mode_rule import mode_problem, override_text
from dualrgb.common.formatting import counted
from dualrgb.core.metadata import Original

log = logging.getLogger(__name__)

SHOOT, KEPT, REFUSED = "shoot", "kept", "refused"
PLAN_FORMAT = "dualrgb-queue-plan/1"


@dataclass(frozen=True)
class PlanRow:
    row: int                        # as a spreadsheet numbers it (the header is row 1)
    identifier: str
    state: str                      # SHOOT | KEPT | REFUSED
    reason: str = ""                # why refused, why kept, or the override said when forced
    original: Original | None = None
    bad: bool = False               # refused for a bad value (the reason names the column), not for its mode

    def line(self) -> str:
        return f"row {self.row}: {self.identifier or '?'}: {self.state}" + (f" ({self.reason})" if self.reason else "")

    def refusal(self) -> str:
        """The row's refusal as the CLI lists it: a bad row as queue_csv says it (``row 6, column 'Title': ...``),
        an original of the other mode with its identifier (``row 7: F-1: transmissive original, ...``)."""
        return f"row {self.row}, {self.reason}" if self.bad else f"row {self.row}: {self.identifier}: {self.reason}"


@dataclass
class QueuePlan:
    source: Path
    calibration: str
    rows: list[PlanRow] = field(default_factory=list)
    column_lines: list[str] = field(default_factory=list)

    def of(self, state: str) -> list[PlanRow]:
        return [r for r in self.rows if r.state == state]

    @property
    def to_shoot(self) -> list[Original]:
        return [r.original for r in self.of(SHOOT) if r.original is not None]

    def summary(self) -> str:
        n = {s: len(self.of(s)) for s in (SHOOT, KEPT, REFUSED)}
        under = f"with calibration {self.calibration}" if self.calibration else "(no calibration yet: modes unchecked)"
        return (f"{self.source.name}: {counted(len(self.rows), 'row')} {under}: {n[SHOOT]} to shoot, {n[KEPT]} kept, "
                f"{n[REFUSED]} refused")

    def lines(self) -> list[str]:
        """The summary, one line per row, and one line per unmapped column whose values were not all kept."""
        return [self.summary(), *(r.line() for r in self.rows), *self.column_lines]

    def refused_lines(self) -> list[str]:
        return [r.refusal() for r in self.of(REFUSED)]

    def to_dict(self) -> dict[str, Any]:
        return {"queue": str(self.source), "calibration": self.calibration, "summary": self.summary(),
                "rows": [{"row": r.row, "identifier": r.identifier, "state": r.state, "reason": r.reason}
                         for r in self.rows], "columns": self.column_lines}


def plan_queue(queue: QueueImport, profile: Any, *, session: Any = None, force: bool = False,
               reshoot: bool = False) -> QueuePlan:
    """Each row of ``queue`` under calibration ``profile``: refused (a bad row; a mode other than the
    calibration's unless ``force``), kept (delivered in ``session`` already, unless ``reshoot``) or to shoot.
    ``profile`` None (the GUI before a calibration): the mode rule waits for one; the rest is the same."""
    plan = QueuePlan(queue.path, profile.id if profile is not None else "", column_lines=queue.column_lines())
    rows: list[PlanRow] = []
    bad = dict(zip(queue.bad_rows, queue.bad_lines(), strict=True))
    for row, line in bad.items():
        rows.append(PlanRow(row, queue.bad_identifiers.get(row, ""), REFUSED, line.split(", ", 1)[1], bad=True))
    for entry in queue.entries:
        rows.append(_plan_row(entry.row, entry.original, profile, session, force, reshoot))
    plan.rows = sorted(rows, key=lambda r: r.row)
    return plan


def _plan_row(row: int, original: Original, profile: Any, session: Any, force: bool, reshoot: bool) -> PlanRow:
    problem = mode_problem(original.mode, profile.mode, profile.id) if profile is not None else ""
    if problem and not force:
        return PlanRow(row, original.identifier, REFUSED, problem, original)
    if session is not None and not reshoot:
        from dualrgb.app.workflow.day.queue_run import delivered_sidecar

        if delivered_sidecar(session, original) is not None:
            return PlanRow(row, original.identifier, KEPT, "already delivered in the session", original)
    reason = override_text(original.mode, profile.mode, profile.id) if problem and profile is not None else ""
    return PlanRow(row, original.identifier, SHOOT, reason, original)
