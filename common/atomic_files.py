"""Atomic file output for everything the product writes (session files, raw frames, reports, TIFFs, figures,
CSVs, presets): a reader sees the old file or the new one, never a part of one.

The data goes to a temp file in the target's folder (``.<name>.<pid>.tmp``), is flushed and fsynced, renamed
over the target (atomic on POSIX and on NTFS) and the folder is fsynced. On any error the temp file is removed
and a :class:`FileWriteError` (an ``OSError``) with one line naming the target file is raised; disk full says so.

    atomic_write(path, b"...")                    # bytes or str (UTF-8)
    with atomic_output(path, "w", newline="") as fh:   # a file object for libraries that write to one
        csv.writer(fh).writerow(...)
    require_free_space(folder, needed_bytes, "the dark series")   # refuse up front what cannot fit

It lives in ``common`` (below every layer, beside ``common.progress``) so that drivers/, simulation/ and app/
share one implementation; ``core.session.capture_session.atomic_write`` wraps it to raise ``SessionError``.
"""
from __future__ import annotations

import errno
import logging
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, Union

log = logging.getLogger(__name__)

TMP_SUFFIX = ".tmp"
PathLike = Union[str, "os.PathLike[str]"]


class FileWriteError(OSError):
    """A file could not be written; ``str()`` is one line naming the file and the problem."""

    def __init__(self, code: int | None, message: str, filename: str | None = None):
        super().__init__(code or errno.EIO, message)
        self.message = message
        self.filename = filename

    def __str__(self) -> str:
        return self.message


class InsufficientSpaceError(FileWriteError):
    """Not enough free space for what is about to be written; nothing was written."""


def temp_path(path: Path) -> Path:
    """The temp file used while ``path`` is being written (hidden, same folder, per process)."""
    return path.with_name(f".{path.name}.{os.getpid()}{TMP_SUFFIX}")


def fsync_dir(path: Path) -> None:
    """Make a rename or a new file in ``path`` durable (no-op where folders cannot be opened, e.g. Windows)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except (PermissionError, IsADirectoryError):  # pragma: no cover - Windows
        return
    try:
        os.fsync(fd)
    except OSError as exc:  # pragma: no cover - some file systems refuse fsync on folders
        if exc.errno not in (errno.EINVAL, errno.EBADF):
            raise
    finally:
        os.close(fd)


def write_error(exc: OSError, path: Path) -> FileWriteError:
    """The one-line error for a failed write of ``path`` (disk full is named as such)."""
    if isinstance(exc, FileWriteError):
        return exc
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return FileWriteError(exc.errno, f"{path}: disk full while writing; free space and retry "
                                         f"(the previous version of the file, if any, is intact)", str(path))
    return FileWriteError(exc.errno, f"{path}: cannot write: {exc.strerror or exc}", str(path))


def remove_quietly(path: Path) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass
    except OSError as exc:  # pragma: no cover - nothing more can be done
        log.warning("could not remove %s: %s", path, exc)


def write_all(fd: int, data: bytes) -> None:
    """``os.write`` until every byte is written (a short write is not an error)."""
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        if n <= 0:  # pragma: no cover - os.write raises instead on real errors
            raise OSError(errno.EIO, "write returned 0")
        view = view[n:]


def atomic_write(path: PathLike, data: bytes | str, *, exclusive: bool = False) -> Path:
    """Write ``data`` (str is UTF-8 encoded) to ``path`` atomically and durably; returns the path.

    ``exclusive``: the temp file must not exist yet (two writers of one name fail instead of mixing).
    """
    path = Path(path)
    raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    tmp = temp_path(path)
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | (os.O_EXCL if exclusive else os.O_TRUNC), 0o644)
    except OSError as exc:
        raise write_error(exc, path) from exc
    try:
        try:
            write_all(fd, raw)
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
        fsync_dir(path.parent)
    except OSError as exc:
        remove_quietly(tmp)
        raise write_error(exc, path) from exc
    return path


@contextmanager
def atomic_output(path: PathLike, mode: str = "wb", **open_kwargs: Any) -> Iterator[IO]:
    """A file object for ``path`` whose content appears there only when the block ends without error.

    ``mode`` is ``"wb"`` or ``"w"`` (text: UTF-8 unless ``encoding`` is given); ``open_kwargs`` go to ``open``.
    The parent folder is created. An exception inside the block removes the temp file and leaves ``path``
    as it was; an ``OSError`` becomes a :class:`FileWriteError` naming ``path``.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_output mode {mode!r}: expected 'w' or 'wb'")
    path = Path(path)
    if mode == "w":
        open_kwargs.setdefault("encoding", "utf-8")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = temp_path(path)
        fh = open(tmp, mode, **open_kwargs)
    except OSError as exc:
        raise write_error(exc, path) from exc
    try:
        try:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        finally:
            fh.close()
        os.replace(tmp, path)
        fsync_dir(path.parent)
    except OSError as exc:
        remove_quietly(tmp)
        raise write_error(exc, path) from exc
    except BaseException:
        remove_quietly(tmp)
        raise


def free_bytes(folder: PathLike) -> int:
    """Free bytes on the file system holding ``folder`` (its nearest existing parent)."""
    p = Path(folder).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return shutil.disk_usage(p).free


def require_free_space(folder: PathLike, needed_bytes: int, what: str, *, margin: float = 1.1) -> None:
    """Raise :class:`InsufficientSpaceError` unless ``folder`` has ``needed_bytes`` x ``margin`` free."""
    need = int(needed_bytes * margin)
    free = free_bytes(folder)
    if free < need:
        raise InsufficientSpaceError(
            errno.ENOSPC, f"{folder}: {what} needs about {_mib(need)} but only {_mib(free)} is free; "
                          f"free space or choose another folder", str(folder))
    log.debug("%s: %s needs %s, %s free", folder, what, _mib(need), _mib(free))


def _mib(n: int) -> str:
    return f"{n / 2**20:.1f} MiB" if n < 2**30 else f"{n / 2**30:.2f} GiB"


__all__ = ["FileWriteError", "InsufficientSpaceError", "atomic_output", "atomic_write", "free_bytes",
           "fsync_dir", "remove_quietly", "require_free_space", "temp_path", "write_all", "write_error"]
