"""Paths a session records about its own files (session.json's originals: the calibration each was delivered with,
its sidecar; the GUI's saved day): written relative to the session folder, and never resolved outside it.

A session is moved and copied as a folder (to another disk, an archive, a colleague). An absolute path in it would
then name the *original* session's file: a copied session whose calibration arrays were removed would silently be
processed with the original session's calibration (issue 38). So:

* :func:`record`: a file inside the session folder is recorded as its path relative to the folder (POSIX
  separators); a file outside it (a calibration from another session, deliverables under ``--out``) absolute.
* :func:`inside`: what a recorded path names *inside* the session folder, or None: a relative path is resolved
  against the folder and must stay in it (``..`` never leaves it); an absolute one counts only when it lies in this
  folder (sessions recorded before this rule). A calibration is taken only this way: one outside the session is
  passed explicitly (``--calibration``), never picked up from session.json.
* :func:`deliverable`: a sidecar may lie outside the session (``--out DIR``, chosen by the user): an absolute path
  outside counts unless it lies inside *another* session's folder (a copy of a session naming the original's
  deliverables).
"""
from __future__ import annotations

import logging
from pathlib import Path, PurePosixPath

log = logging.getLogger(__name__)

SESSION_FILE = "session.json"


def _resolved(path: Path) -> Path:
    try:
        return path.resolve()
    except (OSError, RuntimeError):          # a loop of links: compare as given
        return path.absolute()


def record(session_dir: Path, path: Path | str) -> str:
    """How session.json records ``path``: relative to ``session_dir`` when inside it, else absolute ('' for '')."""
    if not str(path):
        return ""
    full, folder = _resolved(Path(path)), _resolved(Path(session_dir))
    if full.is_relative_to(folder):
        return PurePosixPath(*full.relative_to(folder).parts).as_posix()
    return str(full)


def inside(session_dir: Path, recorded: str | None) -> Path | None:
    """The file ``recorded`` names inside ``session_dir`` (module docstring), None when it names none there."""
    if not recorded:
        return None
    folder = _resolved(Path(session_dir))
    given = Path(recorded)
    full = _resolved(given if given.is_absolute() else folder / given)
    if not full.is_relative_to(folder):
        log.info("%s: %s lies outside the session folder: not used from session.json", session_dir, recorded)
        return None
    return full


def other_session(session_dir: Path, path: Path) -> Path | None:
    """The folder of another session that ``path`` lies in (a folder holding a session.json), if any."""
    folder = _resolved(Path(session_dir))
    for parent in _resolved(path).parents:
        if parent == folder:
            return None
        if (parent / SESSION_FILE).is_file():
            return parent
    return None


def deliverable(session_dir: Path, recorded: str | None) -> Path | None:
    """A recorded sidecar: inside the session (:func:`inside`), or an absolute path outside it that lies in no other
    session's folder (``--out DIR``)."""
    if not recorded:
        return None
    if not Path(recorded).is_absolute():
        return inside(session_dir, recorded)
    found = inside(session_dir, recorded)
    if found is not None:
        return found
    foreign = other_session(session_dir, Path(recorded))
    if foreign is not None:
        log.info("%s: %s lies in another session (%s): not used", session_dir, recorded, foreign)
        return None
    return Path(recorded)
