"""One writer per session folder: an OS lock on ``<folder>/.session.lock`` (filelock: ``fcntl.flock`` on Linux and
macOS, ``msvcrt.locking`` on Windows), released by the OS when the holder exits or is killed.

Who holds it (pid, host, since, program) is written beside it, in ``<folder>/.session.holder``, so that a second
writer is refused with a line naming the holder (filelock empties and removes its own lock file). Within one
process the lock is shared (reference-counted): the GUI and the tests open one session more than once; it is two
*processes* writing one folder that mixes frames. The lock may be released from another thread than the one that
took it (a session closed by the GUI's worker).

filelock (a well-kept cross-platform lock) replaces the hand-written fcntl / msvcrt branches. Where the OS offers
neither it falls back to an exclusive lock file, which a killed holder leaves behind: that is logged as a warning.
"""
from __future__ import annotations

import contextlib
import json
import logging
import os
import socket
import sys
import threading
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from filelock import BaseFileLock

log = logging.getLogger(__name__)

LOCK_NAME = ".session.lock"
HOLDER_NAME = ".session.holder"


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
    lock: BaseFileLock
    folder: Path
    count: int


_registry: dict[str, _Held] = {}
_registry_guard = threading.Lock()
_guard_owner: list[int] = []        # the thread inside the guard (one item at most)
_deferred: list[str] = []           # releases asked for by a finaliser while this thread held the guard


@contextlib.contextmanager
def _guarded() -> Iterator[None]:
    """The registry's guard; on the way out, the releases deferred meanwhile are done.

    A CaptureSession left for the garbage collector is released by its finaliser, which may run inside
    :func:`acquire` or :func:`release` of this very thread (a collection starts at any allocation): it cannot wait
    for the guard this thread holds, so it leaves the key in ``_deferred`` (:func:`release`)."""
    with _registry_guard:
        _guard_owner.append(threading.get_ident())
        try:
            yield
        finally:
            try:
                while _deferred:
                    _release_one(_deferred.pop())
            finally:
                _guard_owner.clear()


def read_holder(folder: Path) -> dict:
    """What the current (or last) holder wrote beside the lock; {} when unreadable."""
    try:
        data = json.loads((Path(folder) / HOLDER_NAME).read_text(encoding="utf-8") or "{}")
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _write_holder(folder: Path) -> None:
    from dualrgb.common.atomic_files import atomic_write
    from dualrgb.common.strict_json import dumps as strict_dumps

    info = {"pid": os.getpid(), "host": socket.gethostname(),
            "since": datetime.now(UTC).isoformat(timespec="seconds"),
            "program": " ".join(os.path.basename(a) for a in sys.argv[:2])}
    atomic_write(Path(folder) / HOLDER_NAME, strict_dumps(info) + "\n")


def _clear_holder(folder: Path) -> None:
    try:
        (Path(folder) / HOLDER_NAME).unlink()
    except FileNotFoundError:
        pass


def _filelock() -> tuple[type[BaseFileLock], type[Exception]]:
    """filelock's lock for this OS and its Timeout; its warning about a soft lock goes to the log instead."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        import filelock
    for w in said:
        log.warning("session lock: %s (a killed writer leaves the lock file; remove %s by hand then)", w.message,
                    LOCK_NAME)
    return filelock.FileLock, filelock.Timeout


def acquire(folder: Path) -> str:
    """Take (or share, within this process) the writer lock of ``folder``; returns the key for ``release``.

    Raises :class:`LockHeld` when another process has it.
    """
    FileLock, Timeout = _filelock()
    key = os.path.realpath(folder)
    with _guarded():
        held = _registry.get(key)
        if held is not None:
            held.count += 1
            return key
        lock = FileLock(Path(folder) / LOCK_NAME, timeout=0, thread_local=False)
        try:
            lock.acquire()
        except Timeout:
            raise LockHeld(Path(folder), read_holder(Path(folder))) from None
        try:
            _write_holder(Path(folder))
        except BaseException:
            lock.release()
            raise
        _registry[key] = _Held(lock, Path(folder), 1)
    log.debug("session lock taken: %s", key)
    return key


def release(key: str) -> None:
    """Give back one reference to the lock taken by ``acquire``; the last one unlocks the folder."""
    if _guard_owner and _guard_owner[0] == threading.get_ident():     # a finaliser inside acquire / release
        _deferred.append(key)
        return
    with _guarded():
        _release_one(key)


def _release_one(key: str) -> None:
    held = _registry.get(key)
    if held is None:
        return
    held.count -= 1
    if held.count > 0:
        return
    del _registry[key]
    try:
        _clear_holder(held.folder)
    except OSError as exc:  # pragma: no cover - the lock goes anyway; the next holder overwrites the file
        log.warning("session lock holder of %s: %s", key, exc)
    finally:
        held.lock.release()
    log.debug("session lock released: %s", key)
