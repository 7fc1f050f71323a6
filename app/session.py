"""Crash-safe capture sessions: one folder per session, every raw file on disk before the next shot.

Layout of a session folder::

    session.json        settings (written atomically: temp file, fsync, rename, fsync the folder)
    manifest.jsonl      append-only log, one JSON object per line, fsynced after every line
    0001_dark_DSC_0001.NEF, ...   the raw files exactly as downloaded (sha256 in the manifest)

``CaptureSession.record(raw, role, ...)`` writes the bytes of a :class:`drivers.camera.base.RawCapture` to a
temp file in the same folder, flushes and fsyncs it, renames it to its final name (atomic on POSIX), fsyncs the
folder, then appends and fsyncs one manifest line. When ``record`` has returned, the shot survives a kill or a
power cut. A kill before that leaves either nothing, a ``.tmp`` file (removed on the next open) or a complete
file without a manifest line (kept and reported by :meth:`CaptureSession.verify` as an orphan, never deleted).
A kill in the middle of a manifest append leaves a truncated last line: it is skipped with a warning when the
session is opened, and the next append starts on a fresh line.

Disk full (``ENOSPC``) or any other write error while recording raises :class:`SessionError` (an ``OSError``,
one line naming the file) after removing the temp file and rolling the manifest back to its last complete line,
so the session stays valid and the shot can simply be retried.

Public API (what the sequences, GUI and demo call)::

    session = CaptureSession.create(folder, {"operator": "...", "object": "..."})   # new folder
    session = CaptureSession.open(folder)                                             # resume
    entry = session.record(raw_capture, "dark", step_id="dark/1-60s/03",
                           light=LightSource((1, 6, 8), name="light 1"), sphere_temperature_c=31.2)
    session.has_step("dark/1-60s/03") -> bool      # skip what a resumed sequence already shot
    session.entries(role="dark") -> list[SessionEntry]
    session.file_path(entry) -> Path
    session.verify() -> VerifyReport               # sha256 of every file, missing files, orphans
    session.update_settings(key=value)             # rewrites session.json atomically

Roles used by the sequences: ``dark``, ``flat`` (white / open gate), ``target`` (colour target, meta
``target="train"|"test"``), ``hdr`` / ``object`` (the artwork), ``crf`` (camera response series).
"""
from __future__ import annotations

import errno
import hashlib
import json
import logging
import os
import re
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Optional, Union

from drivers.camera.base import RawCapture
from simulation.versions import software_versions

log = logging.getLogger(__name__)

MANIFEST = "manifest.jsonl"
SETTINGS = "session.json"
FORMAT_VERSION = 1
TMP_SUFFIX = ".tmp"

PathLike = Union[str, "os.PathLike[str]"]


class SessionError(OSError):
    """A session problem with a one-line message (disk full, not a session folder, file missing...)."""


@dataclass
class SessionEntry:
    """One recorded raw file, as one line of manifest.jsonl."""

    seq: int
    file: str                                   # name inside the session folder
    role: str
    sha256: str
    size: int
    step_id: Optional[str] = None
    exposure_s: Optional[float] = None
    iso: Optional[int] = None
    aperture: Optional[float] = None
    camera: str = ""
    camera_filename: str = ""                   # name the camera gave the file (DSC_0001.NEF)
    light: Optional[dict] = None                # {"name", "leds": [1-based], "levels": [0..1]}
    sphere_temperature_c: Optional[float] = None
    settings: dict = field(default_factory=dict)   # camera settings at capture time
    captured_at: str = ""                       # ISO 8601 UTC
    recorded_at: str = ""
    meta: dict = field(default_factory=dict)    # anything else the sequence wants to keep (target, ev, ...)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "SessionEntry":
        known = {f for f in cls.__dataclass_fields__}
        kwargs = {k: v for k, v in data.items() if k in known}
        extra = {k: v for k, v in data.items() if k not in known}
        entry = cls(**kwargs)
        if extra:
            entry.meta = {**extra, **entry.meta}
        return entry

    @property
    def light_name(self) -> str:
        return (self.light or {}).get("name", "") if self.light else ""


@dataclass
class VerifyReport:
    ok: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    corrupted: list[str] = field(default_factory=list)      # sha256 or size mismatch
    orphans: list[str] = field(default_factory=list)        # complete files that no manifest line names
    skipped_lines: list[int] = field(default_factory=list)  # 1-based manifest lines that could not be parsed

    @property
    def valid(self) -> bool:
        return not self.missing and not self.corrupted

    def summary(self) -> str:
        return (f"{len(self.ok)} ok, {len(self.missing)} missing, {len(self.corrupted)} corrupted, "
                f"{len(self.orphans)} orphan files, {len(self.skipped_lines)} unreadable manifest lines")


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


_SAFE = re.compile(r"[^A-Za-z0-9._-]+")


def _safe(text: str) -> str:
    return _SAFE.sub("_", text).strip("._") or "raw"


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        if n <= 0:  # pragma: no cover - os.write raises instead on real errors
            raise OSError(errno.EIO, "write returned 0")
        view = view[n:]


def _json_default(obj: Any) -> Any:
    if hasattr(obj, "to_dict"):
        return obj.to_dict()
    if hasattr(obj, "__dataclass_fields__"):
        return asdict(obj)
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot store {type(obj).__name__} in the session manifest")


def _light_dict(light: Any) -> Optional[dict]:
    if light is None:
        return None
    if isinstance(light, dict):
        return dict(light)
    if hasattr(light, "to_dict"):
        return light.to_dict()
    raise TypeError(f"light must be a LightSource or a dict, got {type(light).__name__}")


def atomic_write(path: Path, data: bytes, *, exclusive: bool = False) -> None:
    """Write ``data`` to ``path`` so that a reader sees the old file or the new one, never a part.

    Temp file in the same folder (``exclusive``: it must not exist yet), fsync, rename, fsync the folder. On error
    the temp file is removed and the error re-raised as a one-line :class:`SessionError` naming the file (disk
    full says so).
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}{TMP_SUFFIX}")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | (os.O_EXCL if exclusive else os.O_TRUNC), 0o644)
    except OSError as exc:
        raise _session_error(exc, tmp) from exc
    try:
        try:
            _write_all(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
        _fsync_dir(path.parent)
    except OSError as exc:
        _remove_quietly(tmp)
        raise _session_error(exc, path) from exc


def _remove_quietly(path: Path) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass
    except OSError as exc:  # pragma: no cover - nothing more we can do
        log.warning("could not remove %s: %s", path, exc)


def _session_error(exc: OSError, path: Path) -> SessionError:
    if isinstance(exc, SessionError):
        return exc
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return SessionError(exc.errno, f"{path}: disk full while writing; free space and retry the shot "
                                       f"(the session is intact)")
    return SessionError(exc.errno or errno.EIO, f"{path}: cannot write: {exc.strerror or exc}")


class CaptureSession:
    """A capture session folder (see the module docstring). Not safe for two writers at once."""

    def __init__(self, path: Path, settings: dict, entries: list[SessionEntry], skipped_lines: list[int]):
        self.path = path
        self.settings = settings
        self._entries = entries
        self._skipped_lines = skipped_lines

    # ---- creation / opening ----
    @classmethod
    def create(cls, path: PathLike, meta: Optional[dict] = None) -> "CaptureSession":
        """A new session in ``path`` (created; must not exist or be an empty folder)."""
        p = Path(path)
        if p.exists():
            if not p.is_dir():
                raise SessionError(errno.EEXIST, f"{p}: exists and is not a folder")
            if any(p.iterdir()):
                raise SessionError(errno.EEXIST, f"{p}: folder is not empty; open it to resume or choose a new one")
        try:
            p.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise _session_error(exc, p) from exc
        settings = {"format": "dualrgb-session", "version": FORMAT_VERSION,
                    "software": software_versions(), "created_at": _now(), **(meta or {})}
        atomic_write(p / SETTINGS, (json.dumps(settings, indent=2, default=_json_default) + "\n").encode())
        try:
            fd = os.open(p / MANIFEST, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            os.fsync(fd)
            os.close(fd)
            _fsync_dir(p)
        except OSError as exc:
            raise _session_error(exc, p / MANIFEST) from exc
        log.info("created capture session %s", p)
        return cls(p, settings, [], [])

    @classmethod
    def open(cls, path: PathLike, *, clean_temp: bool = True) -> "CaptureSession":
        """Open an existing session; unreadable manifest lines are skipped with a warning (never fatal).

        ``clean_temp`` removes ``.tmp`` files left by a process killed mid-write (they never were complete).
        """
        p = Path(path)
        settings_path = p / SETTINGS
        if not settings_path.is_file():
            raise SessionError(errno.ENOENT, f"{p}: not a capture session (no {SETTINGS})")
        try:
            settings = json.loads(settings_path.read_text())
        except (ValueError, OSError) as exc:
            raise SessionError(errno.EIO, f"{settings_path}: unreadable session settings ({exc})") from exc
        entries, skipped = cls._read_manifest(p / MANIFEST)
        if clean_temp:
            for tmp in p.glob(f".*{TMP_SUFFIX}"):
                log.warning("removing incomplete file %s left by an interrupted write", tmp.name)
                _remove_quietly(tmp)
        log.info("opened capture session %s: %d files", p, len(entries))
        return cls(p, settings, entries, skipped)

    @staticmethod
    def _read_manifest(path: Path) -> tuple[list[SessionEntry], list[int]]:
        entries: list[SessionEntry] = []
        skipped: list[int] = []
        if not path.exists():
            raise SessionError(errno.ENOENT, f"{path}: manifest missing")
        raw = path.read_bytes()
        lines = raw.split(b"\n")
        last_index = len(lines) - 1
        for i, line in enumerate(lines):
            if not line.strip():
                continue
            try:
                entries.append(SessionEntry.from_dict(json.loads(line)))
            except (ValueError, TypeError, UnicodeDecodeError) as exc:
                skipped.append(i + 1)
                where = "last line (truncated by an interrupted write)" if i == last_index else f"line {i + 1}"
                log.warning("%s: skipping unreadable %s: %s", path, where, exc)
        return entries, skipped

    # ---- queries ----
    def entries(self, role: Optional[str] = None, *, include_superseded: bool = False) -> list[SessionEntry]:
        """Entries in recording order; a retaken step (same step_id recorded again) shows only its last take."""
        out = list(self._entries)
        if not include_superseded:
            last = {e.step_id: e.seq for e in out if e.step_id}
            out = [e for e in out if not e.step_id or last[e.step_id] == e.seq]
        if role is not None:
            out = [e for e in out if e.role == role]
        return out

    def has_step(self, step_id: str) -> bool:
        return any(e.step_id == step_id for e in self._entries)

    def entry(self, step_id: str) -> SessionEntry:
        for e in reversed(self._entries):
            if e.step_id == step_id:
                return e
        raise KeyError(f"step {step_id!r} not recorded in {self.path}")

    def file_path(self, entry: SessionEntry) -> Path:
        return self.path / entry.file

    def __len__(self) -> int:
        return len(self.entries())

    # ---- writing ----
    def _next_seq(self) -> int:
        return max((e.seq for e in self._entries), default=0) + 1

    def _file_name(self, seq: int, role: str, camera_name: str) -> str:
        name = f"{seq:04d}_{_safe(role)}_{_safe(Path(camera_name).name or 'capture.raw')}"
        while (self.path / name).exists():       # an orphan from a killed run may hold the name
            seq += 100000
            name = f"{seq:04d}_{_safe(role)}_{_safe(Path(camera_name).name or 'capture.raw')}"
        return name

    def record(self, raw: RawCapture, role: str, *, step_id: Optional[str] = None, light: Any = None,
               sphere_temperature_c: Optional[float] = None, settings: Optional[dict] = None,
               captured_at: Optional[str] = None, **meta: Any) -> SessionEntry:
        """Write one downloaded raw file durably and log it; returns its manifest entry.

        ``light`` is a :class:`simulation.lightsource.LightSource` (or its dict); ``settings`` the camera
        settings at capture time; extra keyword arguments go to ``entry.meta`` (must be JSON-serialisable).
        """
        if not role or not isinstance(role, str):
            raise ValueError(f"role must be a non-empty string, got {role!r}")
        data = bytes(raw.data)
        if not data:
            raise SessionError(errno.EINVAL, f"{raw.filename or 'capture'}: the camera returned an empty file")
        seq = self._next_seq()
        name = self._file_name(seq, role, raw.filename)
        final = self.path / name
        entry = SessionEntry(
            seq=seq, file=name, role=role, sha256=hashlib.sha256(data).hexdigest(), size=len(data),
            step_id=step_id, exposure_s=raw.exposure_s, iso=raw.iso, aperture=raw.aperture, camera=raw.camera,
            camera_filename=raw.filename, light=_light_dict(light), sphere_temperature_c=sphere_temperature_c,
            settings=dict(settings or {}), captured_at=captured_at or str(raw.extra.get("captured_at", "")) or _now(),
            recorded_at="", meta={**{k: v for k, v in raw.extra.items() if k != "captured_at"}, **meta})
        try:                                     # fail on unstorable meta before anything is written
            json.dumps(entry.to_dict(), default=_json_default)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name}: session metadata is not JSON-serialisable: {exc}") from exc
        # 1. the raw file, durable under its final name
        atomic_write(final, data, exclusive=True)
        # 2. the manifest line, durable
        entry.recorded_at = _now()
        line = json.dumps(entry.to_dict(), default=_json_default, separators=(",", ":")) + "\n"
        try:
            self._append_manifest(line.encode())
        except OSError as exc:
            _remove_quietly(final)               # no manifest line: do not leave an unexplained file
            try:
                _fsync_dir(self.path)
            except OSError:  # pragma: no cover
                pass
            raise _session_error(exc, self.path / MANIFEST) from exc
        self._entries.append(entry)
        log.debug("recorded %s (%s, %d bytes)", name, role, len(data))
        return entry

    def _append_manifest(self, line: bytes) -> None:
        path = self.path / MANIFEST
        fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            size = os.fstat(fd).st_size
            prefix = b""
            if size:
                os.lseek(fd, size - 1, os.SEEK_SET)
                if os.read(fd, 1) != b"\n":
                    prefix = b"\n"              # a killed append left a partial line: start a fresh one
            try:
                _write_all(fd, prefix + line)
                os.fsync(fd)
            except OSError:
                try:                             # roll back to the last complete line
                    os.ftruncate(fd, size)
                    os.fsync(fd)
                except OSError as exc2:  # pragma: no cover
                    log.warning("could not roll back %s: %s", path, exc2)
                raise
        finally:
            os.close(fd)

    def update_settings(self, **values: Any) -> None:
        """Merge ``values`` into session.json (atomic rewrite)."""
        new = {**self.settings, **values}
        atomic_write(self.path / SETTINGS, (json.dumps(new, indent=2, default=_json_default) + "\n").encode())
        self.settings = new

    # ---- checking ----
    def verify(self, *, check_hashes: bool = True) -> VerifyReport:
        """Check that every recorded file exists with its size and sha256; list orphans and bad lines."""
        report = VerifyReport(skipped_lines=list(self._skipped_lines))
        named = set()
        for e in self._entries:
            named.add(e.file)
            p = self.path / e.file
            if not p.is_file():
                report.missing.append(e.file)
                continue
            if p.stat().st_size != e.size:
                report.corrupted.append(e.file)
                continue
            if check_hashes and _sha256_file(p) != e.sha256:
                report.corrupted.append(e.file)
                continue
            report.ok.append(e.file)
        for p in sorted(self.path.iterdir()):
            if p.name in (MANIFEST, SETTINGS) or p.name.startswith(".") or p.is_dir() or p.name in named:
                continue
            report.orphans.append(p.name)
        level = logging.INFO if report.valid else logging.WARNING
        log.log(level, "verify %s: %s", self.path, report.summary())
        return report


def _sha256_file(path: Path, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while True:
            block = fh.read(chunk)
            if not block:
                break
            h.update(block)
    return h.hexdigest()


__all__ = ["CaptureSession", "SessionEntry", "SessionError", "VerifyReport", "atomic_write", "MANIFEST",
           "SETTINGS"]
