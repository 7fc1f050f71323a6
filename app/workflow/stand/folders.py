"""Where sessions go, and the session rule (Qt-free; the GUI and the CLI call it):

    session = open_session(folder, definition, camera)   # the one way a session is opened (or made)
    session = new_session(root, meta, definition)    # a dated session: <root>/2026-11-24_1, then _2, ...
    old = legacy_captures(settings_dir, root)        # sessions left in the old default beside the settings file
    report = move_sessions(old.folder, root)         # moved, or kept where they are with the reason
    folder_summary(root)                             # '/home/me/.local/share/dualrgb/captures (112 GB free)'

Starting a calibration, a run or an original without a session makes one here (a front end never needs a "new
session" step first), as the CLI's ``--session`` is created when it does not exist. Before issue 22 the GUI kept
captures in ``<settings folder>/captures`` (``~/.config/dualrgb/captures`` on Linux); such a folder is found,
offered and never abandoned: its sessions stay openable where they are, or move as they are (frames are stored
relative to their session folder).
"""
from __future__ import annotations

import datetime as _dt
import errno
import logging
import shutil
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, cast

from dualrgb.app.workflow.stand.defaults import CAPTURES
from dualrgb.core.session import lock as session_lock
from dualrgb.core.session.capture_session import SETTINGS, CaptureSession, SessionError

if TYPE_CHECKING:
    from dualrgb.drivers.camera.base import Camera

log = logging.getLogger(__name__)

MAX_SESSIONS_A_DAY = 999


def dated_name(root: Path, today: _dt.date | None = None) -> str:
    """The first free dated session name in ``root``: '2026-11-24_1', '2026-11-24_2', ..."""
    day = (today or _dt.date.today()).isoformat()
    for n in range(1, MAX_SESSIONS_A_DAY + 1):
        if not (Path(root) / f"{day}_{n}").exists():
            return f"{day}_{n}"
    raise SessionError(errno.EEXIST, f"{root}: {MAX_SESSIONS_A_DAY} sessions on {day} already; choose a folder")


def new_session(root: Path, meta: dict | None = None, definition: dict | None = None,
                today: _dt.date | None = None) -> CaptureSession:
    """A new session in ``root`` under the first free dated name (another program taking that name at the same
    moment moves this one to the next)."""
    for _ in range(MAX_SESSIONS_A_DAY):
        folder = Path(root) / dated_name(root, today)
        try:
            return CaptureSession.create(folder, meta, definition=definition)
        except SessionError as exc:
            if exc.errno != errno.EEXIST or not folder.exists():
                raise
            log.info("%s was taken meanwhile; trying the next name", folder)
    raise SessionError(errno.EEXIST, f"{root}: no free session name")


def open_session(folder: Path | None, definition: dict | None = None, camera: Camera | None = None,
                 meta: dict | None = None, *, root: Path | None = None,
                 hint: str = "use the same options and camera, or another session", existing: bool = False,
                 readonly: bool = False, new_if_different: bool = False) -> CaptureSession:
    """The one way a session is opened or made (the CLI, the window, the demo, the studies, the measurements).

    * ``folder`` None: a new dated session in ``root`` (default: the captures folder);
    * ``readonly``: the session in ``folder``, read only (no writer lock, no writes: plans, re-delivery);
    * ``existing``: the session in ``folder`` (refused when there is none), checked against ``definition`` (the
      caller sets its missing or damaged frames aside: ``set_aside_damaged()``, and says how many);
    * else: a new session in ``folder``, or the one there resumed when it was made with the same ``definition``
      (``new_if_different``: a sibling ``<folder>-2``, ... instead of refusing).

    A mismatching definition is refused in one line naming the difference (``hint`` appended); a writable session
    resumed has its missing or damaged frames set aside (their steps are shot again). With ``camera``: its identity
    and image area join the definition (a session is resumed only with the same camera). One writer at a time."""
    from dualrgb.app.workflow.stand.defaults import DAY_WORKFLOW, captures_dir, day_workflow
    from dualrgb.app.workflow.stand.stand_devices import camera_definition_of

    if readonly:
        return CaptureSession.open(Path(cast(Path, folder)), readonly=True)
    definition = dict(definition or {})
    if folder is not None and definition.get("workflow") == DAY_WORKFLOW:     # an older session of the same day
        definition = {**definition, "workflow": day_workflow(stored_definition(Path(folder)).get("workflow"))}
    if folder is None:
        session = new_session(root or captures_dir(), meta or {}, definition)
    elif existing:
        session = CaptureSession.open(Path(folder), definition=definition, hint=hint)
    else:
        session = CaptureSession.resume(Path(folder), definition, meta or {}, hint=hint,
                                        new_if_different=new_if_different)
    try:
        if camera is not None:
            session.extend_definition(**camera_definition_of(camera))
    except BaseException:
        session.close()
        raise
    return session


def stored_definition(folder: Path) -> dict:
    """The definition a session folder records ({} when there is no session there, or it cannot be read: opening
    it says why)."""
    try:
        return dict(CaptureSession._read_settings(Path(folder) / SETTINGS).get("definition") or {})
    except (SessionError, OSError):
        return {}


def is_session(folder: Path) -> bool:
    return (Path(folder) / SETTINGS).is_file()


def sessions_in(folder: Path) -> list[Path]:
    """The session folders directly in ``folder`` (sorted by name)."""
    try:
        return sorted(p for p in Path(folder).iterdir() if p.is_dir() and is_session(p))
    except OSError:
        return []


@dataclass
class LegacyCaptures:
    """The old default captures folder and the sessions in it."""

    folder: Path
    sessions: list[Path]

    def text(self) -> str:
        n = len(self.sessions)
        return f"{n} session{'s' if n != 1 else ''} in the old captures folder {self.folder}"


def legacy_captures_dir(settings_dir: Path) -> Path:
    """Where captures went by default before issue 22: beside the settings file."""
    return Path(settings_dir) / CAPTURES


def legacy_captures(settings_dir: Path, current: Path) -> LegacyCaptures | None:
    """The old default captures folder when it holds sessions and is not the folder in use."""
    old = legacy_captures_dir(settings_dir)
    if _same(old, current):
        return None
    found = sessions_in(old)
    return LegacyCaptures(old, found) if found else None


def _same(a: Path, b: Path) -> bool:
    try:
        return Path(a).resolve() == Path(b).resolve()
    except OSError:
        return False


@dataclass
class MoveReport:
    moved: list[Path] = field(default_factory=list)                 # where each entry is now
    kept: list[tuple[Path, str]] = field(default_factory=list)      # (entry, why it stayed)

    def text(self) -> str:
        out = f"moved {len(self.moved)}"
        if self.kept:
            out += f", kept {len(self.kept)} where they are (" + "; ".join(f"{p.name}: {why}"
                                                                         for p, why in self.kept) + ")"
        return out


def move_sessions(src: Path, dst: Path, busy: Iterable[Path] = ()) -> MoveReport:
    """Move everything in ``src`` (sessions, test shots) into ``dst`` as it is. An entry whose name ``dst`` has
    already, a session open here (``busy``) or held by another program stays, with the reason; a copy across
    disks goes to a temporary name first, so a failure leaves the original untouched. ``src`` is removed when
    empty."""
    src, dst = Path(src), Path(dst)
    dst.mkdir(parents=True, exist_ok=True)
    report = MoveReport()
    busy_paths = list(busy)
    for entry in sorted(src.iterdir()):
        why = _why_not_move(entry, dst, busy_paths)
        if why:
            report.kept.append((entry, why))
            continue
        try:
            report.moved.append(_move(entry, dst))
        except OSError as exc:
            report.kept.append((entry, str(exc)))
    if not report.kept:
        try:
            src.rmdir()
        except OSError as exc:
            log.info("%s stays: %s", src, exc)
    log.info("captures %s -> %s: %s", src, dst, report.text())
    return report


def _why_not_move(entry: Path, dst: Path, busy: list[Path]) -> str:
    if (dst / entry.name).exists():
        return f"{dst / entry.name} exists"
    if any(_same(entry, b) for b in busy):
        return "open in this window"
    if is_session(entry):
        try:
            key = session_lock.acquire(entry)
        except session_lock.LockHeld as exc:
            return f"in use ({session_lock.describe_holder(exc.holder)})"
        except OSError as exc:
            return str(exc)
        session_lock.release(key)
    return ""


def _move(entry: Path, dst: Path) -> Path:
    final = dst / entry.name
    tmp = dst / f".{entry.name}.moving"
    try:
        shutil.move(str(entry), str(tmp))
    except OSError:
        if tmp.is_dir():                       # a partial copy across disks; the original is untouched
            shutil.rmtree(tmp, ignore_errors=True)
        raise
    tmp.rename(final)
    return final


def free_bytes(folder: Path) -> int | None:
    """Free space where ``folder`` is (or would be: its nearest existing parent); None when unknown."""
    p = Path(folder)
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return shutil.disk_usage(p).free
    except OSError:
        return None


def size_text(n_bytes: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n_bytes < 1000:
            return f"{n_bytes:.3g}\u00a0{unit}"
        n_bytes /= 1000
    return f"{n_bytes:.3g}\u00a0TB"


def folder_summary(folder: Path) -> str:
    """'<folder> (112 GB free)', or '(free space unknown)'."""
    free = free_bytes(folder)
    return f"{folder} ({size_text(free) + ' free' if free is not None else 'free space unknown'})"

