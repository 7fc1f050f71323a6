"""The day kept in its session folder (Qt-free): the originals queue - waiting rows with their metadata, the failed
ones with their reason - and the calibration in use, written atomically as they change, so a window closed (or a
machine that went down) resumes the day where it stopped.

    save_day(session.path, queue, calibration_path)        # <session>/day/queue.json
    queue, calibration, notes = restore_day(session)       # delivered originals (session.json) + saved rows

The delivered originals come from the session itself (``OriginalsQueue.from_session``: session.json and their
sidecars); the file adds the rows not delivered yet, in the order they were queued. A row saved while it was being
captured comes back waiting ("interrupted"): its frames so far are in the session and a capture keeps or re-shoots
them (the re-shoot question). The calibration is the one the file names, else the session's newest.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dualrgb.app.workflow.day.day import OriginalsQueue, OriginalState, QueueRow
from dualrgb.common.atomic_files import atomic_write
from dualrgb.common.strict_json import dumps as strict_dumps
from dualrgb.core.metadata import Original
from dualrgb.simulation.versions import stamped

if TYPE_CHECKING:
    from dualrgb.core.protocols import Session

log = logging.getLogger(__name__)

DAY_FORMAT = "dualrgb-day/1"
DAY_FOLDER = "day"                      # a folder: session checks skip folders (no orphan file in the session)
DAY_FILE = "queue.json"
INTERRUPTED = "interrupted when the window closed: its frames so far stay in the session"


def day_path(session_path: Path) -> Path:
    return Path(session_path) / DAY_FOLDER / DAY_FILE


def _row_dict(row: QueueRow) -> dict[str, Any]:
    state = OriginalState.WAITING if row.state is OriginalState.CAPTURING else row.state
    qa = INTERRUPTED if row.state is OriginalState.CAPTURING else row.qa
    return {"original": row.original.to_dict(), "stand_in": row.stand_in, "frames": row.frames,
            "state": state.value, "qa": qa}


def day_rows(queue: OriginalsQueue) -> tuple[list[str], list[dict[str, Any]]]:
    """The queue's order and its rows not delivered (a delivered one is in session.json and its sidecar), as
    plain data: cheap to take on the GUI thread, written on another (:func:`write_day`)."""
    return ([r.identifier for r in queue.rows],
            [_row_dict(r) for r in queue.rows if r.state is not OriginalState.DELIVERED])


def save_day(session_path: Path, queue: OriginalsQueue, calibration: Path | None) -> Path:
    """Write the day's queue and calibration into ``<session>/day/queue.json`` (atomically; returns the path)."""
    return write_day(session_path, *day_rows(queue), calibration)


def write_day(session_path: Path, order: list[str], rows: list[dict[str, Any]], calibration: Path | None) -> Path:
    """Write :func:`day_rows` and the calibration's path (stamped: format and software first)."""
    path = day_path(session_path)
    path.parent.mkdir(exist_ok=True)
    from dualrgb.core.session.paths import record

    doc = stamped(DAY_FORMAT, {"calibration": record(session_path, calibration) if calibration else None,
                               "order": order, "rows": rows})
    return atomic_write(path, strict_dumps(doc, indent=1) + "\n")


@dataclass
class SavedDay:
    calibration: Path | None = None
    rows: list[QueueRow] = field(default_factory=list)
    order: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)      # what could not be restored, one line each


def read_day(session_path: Path) -> SavedDay:
    """The saved day of a session ({} when none was saved); an unreadable file or row is a note, never fatal."""
    path = day_path(session_path)
    if not path.is_file():
        return SavedDay()
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(doc, dict) or str(doc.get("format", "")).split("/")[0] != DAY_FORMAT.split("/")[0]:
            raise ValueError(f"expected format {DAY_FORMAT}")
    except (OSError, ValueError) as exc:
        return SavedDay(notes=[f"{path}: not restored ({exc})"])
    day = SavedDay(_calibration(session_path, doc.get("calibration")), order=list(doc.get("order") or []))
    for item in doc.get("rows") or []:
        try:
            row = QueueRow(Original.from_dict(item["original"]), str(item.get("stand_in", "")),
                           int(item.get("frames", 1)), OriginalState(item.get("state", "waiting")),
                           str(item.get("qa", "")))
        except (KeyError, TypeError, ValueError) as exc:
            day.notes.append(f"{path}: a row not restored ({exc})")
            continue
        day.rows.append(row)
    return day


def _calibration(session_path: Path, recorded: object) -> Path | None:
    """The saved calibration: a path relative to the session folder stays in it (core.session.paths); an absolute one
    (a calibration of another folder, chosen in the GUI) as it was saved."""
    if not recorded or not isinstance(recorded, str):
        return None
    if Path(recorded).is_absolute():
        return Path(recorded)
    from dualrgb.core.session.paths import inside

    return inside(session_path, recorded)


def restore_queue(session: Session, saved: SavedDay | None = None) -> OriginalsQueue:
    """The session's delivered originals with the saved rows not delivered, in the order they were queued."""
    queue = OriginalsQueue.from_session(session)
    saved = saved if saved is not None else read_day(Path(session.path))
    known = {r.identifier for r in queue.rows}
    queue.rows += [r for r in saved.rows if r.identifier not in known]
    rank = {ident: i for i, ident in enumerate(saved.order)}
    queue.rows.sort(key=lambda r: rank.get(r.identifier, len(rank)))        # stable: unknown ones keep their place
    return queue


def newest_calibration(session: Session) -> Path | None:
    """The session's own newest calibration file (``<session>/calibration/cal-*.json``), None when it has none."""
    found = sorted((Path(session.path) / "calibration").glob("cal-*.json"))
    return found[-1] if found else None


def restore_day(session: Session) -> tuple[OriginalsQueue, Path | None, list[str]]:
    """The queue, the calibration to use (the saved one when it still exists, else the session's newest) and
    notes on what could not be restored."""
    saved = read_day(Path(session.path))
    calibration = saved.calibration
    if calibration is not None and not calibration.is_file():
        saved.notes.append(f"calibration {calibration} is gone; using the session's newest")
        calibration = None
    return restore_queue(session, saved), calibration or newest_calibration(session), saved.notes


def restored_line(session_name: str, queue: OriginalsQueue, calibration: str) -> str:
    """The one line the window says on start: what came back."""
    counts = queue.counts()
    parts = ", ".join(f"{n} {s.value}" for s, n in counts.items() if n) or "empty"
    where = f"session {session_name}" if session_name else "(no session yet)"
    return f"restored {where}, calibration {calibration or 'none'}, queue: {parts}"


__all__ = ["DAY_FORMAT", "SavedDay", "day_path", "day_rows", "newest_calibration", "read_day", "restore_day",
           "restore_queue", "restored_line", "save_day", "write_day"]
