"""One writer per session folder: an OS lock on ``<folder>/.session.lock`` (``fcntl.flock`` on POSIX,
``msvcrt.locking`` on Windows), released by the OS when the holder exits or is killed.

The lock file holds who has it (pid, host, since, program) so that a second writer is refused with a line
naming the holder. Within one process the lock is shared (reference-counted): the GUI and the tests open one
session more than once; it is two *processes* writing one folder that mixes frames.
"""
from __future__ import annotations

import json
import logging
import os
import socket
import sys
import threading
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from dualrgb.common.strict_json import dumps as strict_dumps

log = logging.getLogger(__name__)

LOCK_NAME = ".session.lock"
_WIN_LOCK_OFFSET = 1 << 30        # Windows locks a byte far past the holder info, so the info stays readable


class LockHeld(Exception):
    """Another process holds the folder's lock; ``holder`` is what it wrote (may be empty)."""

    def __init__(self, folder: Path, holder: dict):
        self.folder = folder
        self.holder = holder
        super().__init__(f"{folder}: in use by another writer ({describe_holder(holder)}); close it first "
                         "(only one program may write a session at a time)")


def describe_holder(holder: dict) -> str:
    if not holder:
        return "holder unknown"
    return (f"pid {holder.get('pid', '?')} on {holder.get('host', '?')} since {holder.get('since', '?')}"
            + (f", {holder['program']}" if holder.get("program") else ""))


@dataclass
class _Held:
    fd: int
    count: int


_registry: dict[str, _Held] = {}
_registry_guard = threading.RLock()      # re-entrant: a session finalised by GC inside acquire releases


def _try_lock(fd: int) -> bool:
    if sys.platform == "win32":  # pragma: no cover - exercised on Windows only
        import msvcrt

        os.lseek(fd, _WIN_LOCK_OFFSET, os.SEEK_SET)
        try:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        except OSError:
            return False
        return True
    import fcntl

    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


def _unlock(fd: int) -> None:
    if sys.platform == "win32":  # pragma: no cover
        import msvcrt

        os.lseek(fd, _WIN_LOCK_OFFSET, os.SEEK_SET)
        msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)
        return
    import fcntl

    fcntl.flock(fd, fcntl.LOCK_UN)


def read_holder(folder: Path) -> dict:
    """What the current (or last) holder wrote into the lock file; {} when unreadable."""
    try:
        data = json.loads((Path(folder) / LOCK_NAME).read_text(encoding="utf-8") or "{}")
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _write_holder(fd: int) -> None:
    info = {"pid": os.getpid(), "host": socket.gethostname(),
            "since": datetime.now(UTC).isoformat(timespec="seconds"),
            "program": " ".join(os.path.basename(a) for a in sys.argv[:2])}
    os.ftruncate(fd, 0)
    os.lseek(fd, 0, os.SEEK_SET)
    os.write(fd, strict_dumps(info).encode() + b"\n")


def acquire(folder: Path) -> str:
    """Take (or share, within this process) the writer lock of ``folder``; returns the key for ``release``.

    Raises :class:`LockHeld` when another process has it.
    """
    key = os.path.realpath(folder)
    with _registry_guard:
        held = _registry.get(key)
        if held is not None:
            held.count += 1
            return key
        fd = os.open(Path(folder) / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            if not _try_lock(fd):
                raise LockHeld(Path(folder), read_holder(Path(folder)))
            _write_holder(fd)
        except BaseException:
            os.close(fd)
            raise
        _registry[key] = _Held(fd, 1)
    log.debug("session lock taken: %s", key)
    return key


def release(key: str) -> None:
    """Give back one reference to the lock taken by ``acquire``; the last one unlocks the folder."""
    with _registry_guard:
        held = _registry.get(key)
        if held is None:
            return
        held.count -= 1
        if held.count > 0:
            return
        del _registry[key]
        try:
            os.ftruncate(held.fd, 0)
            _unlock(held.fd)
        except OSError as exc:  # pragma: no cover - closing the descriptor unlocks anyway
            log.warning("unlocking %s: %s", key, exc)
        finally:
            os.close(held.fd)
    log.debug("session lock released: %s", key)
