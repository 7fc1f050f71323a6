"""The copy-stand day as a checklist, and the queue of originals (Qt-free; the GUI's guide and Originals step).

    queue = OriginalsQueue.from_session(session)          # originals delivered earlier in the session come back
    queue.add(Original("ACC-1", title="Portrait"))
    steps = day_checklist(DayState(sphere="...", camera="...", session=session, plan=..., profile=profile,
                                   queue=queue))
    for step in steps: print(step.title, step.state.value, *step.lines)

The checklist is the order the technician follows: Connect -> Calibrate (darks, flats, targets; coverage such as
"darks 2/4 exposures"; a warning when a new HDR plan needs exposures the calibration lacks) -> Originals ->
Deliver. Each step says what is done and what is next; the first step not done is the active one.
"""
from __future__ import annotations

import json
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dualrgb.app.workflow.calibration.coverage import Coverage, coverage, plan_coverage
from dualrgb.app.workflow.calibration.profile import CalibrationProfile, ReuseCheck
from dualrgb.app.workflow.delivery.delivery import Original
from dualrgb.app.workflow.delivery.delivery_folder import sidecar_of
from dualrgb.core.vocabulary import Role, latest_takes, role_of, subject_of

if TYPE_CHECKING:
    from dualrgb.core.protocols import Session

log = logging.getLogger(__name__)


class OriginalState(StrEnum):
    WAITING = "waiting"
    CAPTURING = "capturing"
    CAPTURED = "captured"         # every frame is in the session; the deliverables are being written
    DELIVERED = "delivered"
    FAILED = "failed"


@dataclass
class QueueRow:
    """One original in the day's queue: what it is, what lies on a virtual stand for it, and how far it got."""

    original: Original
    stand_in: str = ""                      # the virtual lab's stand-in ('painting', 'film', 'shadow'); '' = real
    frames: int = 1                         # frames averaged per exposure
    state: OriginalState = OriginalState.WAITING
    qa: str = ""                            # the delivery's QA line, or why it failed
    files: dict[str, Path] = field(default_factory=dict)
    sidecar: Path | None = None
    warnings: list[str] = field(default_factory=list)
    calibration: str = ""                   # the id of the calibration its deliverables were made with

    @property
    def identifier(self) -> str:
        return self.original.identifier

    @property
    def main_file(self) -> Path | None:
        """The file to open first: the sRGB TIFF (any deliverable when it is missing)."""
        return self.files.get("srgb") or next(iter(self.files.values()), None)

    @property
    def folder(self) -> Path | None:
        return self.sidecar.parent if self.sidecar is not None else None

    def delivered(self, report: Any) -> None:
        """It was captured and delivered (``report``: app.workflow.stand.copystand.CaptureReport)."""
        d = report.delivery
        self.state, self.qa = OriginalState.DELIVERED, report.summary()
        self.files, self.sidecar, self.calibration = dict(d.files), d.sidecar, d.calibration
        self.warnings = list(report.check.warnings) + list(report.warnings)

    def redelivered(self, delivery: Any) -> None:
        """Its frames were delivered again (``delivery``: app.workflow.delivery.delivery.Delivery, e.g. Tools ->
        Re-deliver with another calibration): the new QA line, files and calibration replace the old ones."""
        self.state, self.qa = OriginalState.DELIVERED, delivery.qa.text()
        self.files, self.sidecar, self.calibration = dict(delivery.files), delivery.sidecar, delivery.calibration
        self.warnings = list(delivery.qa.warnings)


class OriginalsQueue:
    """The originals of the day in the order they were added; identifiers are unique."""

    def __init__(self) -> None:
        self.rows: list[QueueRow] = []

    def add(self, original: Original, stand_in: str = "", frames: int = 1) -> QueueRow:
        if any(r.identifier == original.identifier for r in self.rows):
            raise ValueError(f"{original.identifier} is already in the queue")
        if frames < 1:
            raise ValueError(f"frames per exposure {frames}: expected at least 1")
        row = QueueRow(original, stand_in, frames)
        self.rows.append(row)
        return row

    def add_many(self, originals: Sequence[Original], stand_in: str = "", frames: int = 1) -> list[str]:
        """Add ``originals`` in order (a queue CSV's: app.workflow.day.queue_csv); returns why any was left out."""
        left_out = []
        for original in originals:
            try:
                self.add(original, stand_in, frames)
            except ValueError as exc:
                left_out.append(str(exc))
        return left_out

    def row(self, identifier: str) -> QueueRow:
        for r in self.rows:
            if r.identifier == identifier:
                return r
        raise KeyError(f"{identifier} is not in the queue")

    def remove(self, identifier: str) -> None:
        self.rows.remove(self.row(identifier))

    def waiting(self) -> list[QueueRow]:
        return [r for r in self.rows if r.state is OriginalState.WAITING]

    def counts(self) -> dict[OriginalState, int]:
        return {s: sum(r.state is s for r in self.rows) for s in OriginalState}

    @classmethod
    def from_session(cls, session: Session) -> OriginalsQueue:
        """The originals already delivered in ``session`` (session.json 'originals', their sidecars)."""
        queue = cls()
        for ident, meta in (session.settings.get("originals") or {}).items():
            try:
                row = queue.add(Original.from_dict(meta, identifier=ident))
            except (TypeError, ValueError) as exc:
                log.warning("session original %r skipped: %s", ident, exc)
                continue
            _read_delivery(row, _sidecar(session, row.original, meta.get("sidecar")))
        return queue


def _sidecar(session: Session, original: Original, recorded: str | None) -> Path:
    """The sidecar session.json names, or where delivery puts it in this session's folder when that path is gone
    (a session moved to another captures folder keeps its deliverables)."""
    from dualrgb.core.session.paths import deliverable

    path = deliverable(Path(session.path), recorded)       # never another session's (core.session.paths)
    if path is not None and path.is_file():
        return path
    moved = sidecar_of(Path(session.path) / "deliverables", original)
    return moved if moved.is_file() or path is None else path


def _read_delivery(row: QueueRow, sidecar: Path) -> None:
    try:
        doc = json.loads(sidecar.read_text())
    except (OSError, ValueError) as exc:
        row.state, row.qa = OriginalState.CAPTURED, f"in the session; deliverables not readable ({exc})"
        return
    row.sidecar = sidecar
    row.files = {k: sidecar.parent / name for k, name in (doc.get("files") or {}).items()}
    row.qa = str((doc.get("qa") or {}).get("text", ""))
    row.warnings = list((doc.get("qa") or {}).get("warnings", []))
    row.calibration = str((doc.get("calibration") or {}).get("id", ""))
    row.state = OriginalState.DELIVERED


# ---------------------------------------------------------------- the checklist
class DayStep(StrEnum):
    CONNECT = "connect"
    CALIBRATE = "calibrate"
    ORIGINALS = "originals"
    DELIVER = "deliver"


class StepState(StrEnum):
    TODO = "todo"
    ACTIVE = "active"             # the next thing to do
    DONE = "done"
    WARNING = "warning"           # done once, but something now needs attention


STEP_TITLES = {DayStep.CONNECT: "Connect", DayStep.CALIBRATE: "Calibrate", DayStep.ORIGINALS: "Originals",
               DayStep.DELIVER: "Deliver"}


@dataclass
class GuideStep:
    step: DayStep
    state: StepState
    lines: list[str] = field(default_factory=list)

    @property
    def title(self) -> str:
        return STEP_TITLES[self.step]


@dataclass
class DayState:
    """What the checklist looks at. ``plan``: the exposures the captures use now (light -> seconds: the base
    exposures and every HDR bracket planned), ``profile``/``check``: the current calibration and its last check
    against the stand."""

    sphere: str = ""
    camera: str = ""
    session: Session | None = None
    plan: Mapping[str, Sequence[float]] = field(default_factory=dict)
    profile: CalibrationProfile | None = None
    check: ReuseCheck | None = None
    queue: OriginalsQueue = field(default_factory=OriginalsQueue)
    deliverables: Path | None = None
    session_note: str = ""                # why the session was made ('for the calibration'), '' when by hand


def day_checklist(state: DayState) -> list[GuideStep]:
    steps = [_connect(state), _calibrate(state), _originals(state), _deliver(state)]
    for s in steps:                         # the first step not done is the one to do now
        if s.state is StepState.TODO:
            s.state = StepState.ACTIVE
            break
        if s.state in (StepState.ACTIVE, StepState.WARNING):
            break
    return steps


def _connect(st: DayState) -> GuideStep:
    """The devices; the session is made when the first calibration, run or original starts (or by hand)."""
    lines = [f"sphere: {st.sphere or 'not connected'}", f"camera: {st.camera or 'not connected'}",
             _session_line(st)]
    done = bool(st.sphere and st.camera)
    return GuideStep(DayStep.CONNECT, StepState.DONE if done else StepState.TODO, lines)


def _session_line(st: DayState) -> str:
    if st.session is None:
        return "session: none yet; a dated one is made in the captures folder (Devices) when you calibrate, run or " \
               "capture"
    note = f", {st.session_note}" if st.session_note else ""
    return f"session: {Path(st.session.path).name} ({len(st.session.entries())} frames{note})"


def targets_captured(session: Session) -> set[str]:
    """'train' / 'test' when the session holds that target (without the ND filter)."""
    out = set()
    for e in latest_takes(session.entries()):
        if role_of(e) is Role.TARGET:
            subject = subject_of(e)
            if subject is not None and not subject.nd:
                out.add(subject.name)
    return out


def _calibrate(st: DayState) -> GuideStep:
    prof = st.profile
    if prof is None:
        lines = ["no calibration yet: Calibrate (or load one)"]
        if st.session is not None and st.plan:
            lines.append(coverage(st.session, st.plan).summary())
            have = targets_captured(st.session)
            lines.append("targets: " + ", ".join(f"{n} {'done' if n in have else 'to do'}" for n in ("train", "test")))
        return GuideStep(DayStep.CALIBRATE, StepState.TODO, lines)
    test = f", test ΔE00 {prof.test_mean:.2f}" if prof.test_mean is not None else ""
    lines = [f"{prof.id}: {prof.age_h():.1f} h old{test}"]
    needed = {n: sorted(set(prof.exposures.get(n, [])) | {float(t) for t in st.plan.get(n, [])})
              for n in prof.exposures}
    cov = plan_coverage(prof.exposures, needed)
    lines.append(cov.summary())
    state = StepState.DONE
    if not cov.complete:
        state = StepState.WARNING
        lines.append(f"incomplete for the new HDR plan: missing {cov.missing()}; recalibrate with HDR")
    for row in st.queue.rows:
        for w in row.warnings:
            if "recalibrate" in w:
                state = StepState.WARNING
                lines.append(f"{row.identifier}: {w}")
    if st.check is not None:
        if not st.check.ok:
            state = StepState.WARNING
            lines.append(f"does not match the stand: {st.check.message()}")
        lines += st.check.warnings
    return GuideStep(DayStep.CALIBRATE, state, lines)


def _originals(st: DayState) -> GuideStep:
    counts = st.queue.counts()
    n = len(st.queue.rows)
    if not n:
        return GuideStep(DayStep.ORIGINALS, StepState.TODO, ["none in the queue: add one with its identifier"])
    parts = ", ".join(f"{k} {s.value}" for s, k in counts.items() if k)
    lines = [f"{n} in the queue: {parts}"]
    failed = [r.identifier for r in st.queue.rows if r.state is OriginalState.FAILED]
    if failed:
        return GuideStep(DayStep.ORIGINALS, StepState.WARNING, lines + [f"failed: {', '.join(failed)}"])
    done = counts[OriginalState.DELIVERED] == n
    return GuideStep(DayStep.ORIGINALS, StepState.DONE if done else StepState.TODO, lines)


def _deliver(st: DayState) -> GuideStep:
    delivered = [r for r in st.queue.rows if r.state is OriginalState.DELIVERED]
    n = len(st.queue.rows)
    where = f" to {Path(st.deliverables).parent.name}/{Path(st.deliverables).name}" if st.deliverables else ""
    lines = [f"{len(delivered)} of {n} delivered{where}"]
    done = bool(n) and len(delivered) == n
    return GuideStep(DayStep.DELIVER, StepState.DONE if done else StepState.TODO, lines)


__all__ = ["Coverage", "DayState", "DayStep", "GuideStep", "OriginalState", "OriginalsQueue", "QueueRow",
           "StepState", "day_checklist", "targets_captured"]
