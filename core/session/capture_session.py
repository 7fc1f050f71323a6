"""Crash-safe capture sessions: one folder per session, every raw file on disk before the next shot.

Layout of a session folder::

    session.json        settings and the session's *definition* (written atomically)
    manifest.jsonl      append-only log, one JSON object per line, fsynced after every line
    0001_dark_DSC_0001.NEF, ...   the raw files exactly as downloaded (sha256 in the manifest)
    damaged/            frames found missing or damaged on resume, moved aside (never deleted)
    .session.lock       the writer's OS lock (core.session.lock)
    .session.holder     who holds it (pid, host, since, program)

``CaptureSession.record(raw, role, ...)`` writes the bytes of a :class:`drivers.camera.base.RawCapture` to a
temp file in the same folder, flushes and fsyncs it, renames it to its final name (atomic on POSIX), fsyncs the
folder, then appends and fsyncs one manifest line. When ``record`` has returned, the shot survives a kill or a
power cut. A kill before that leaves either nothing, a ``.tmp`` file (removed on the next open) or a complete
file without a manifest line (kept and reported by :meth:`CaptureSession.verify` as an orphan, never deleted).
A kill in the middle of a manifest append leaves a truncated last line: it is skipped with a warning when the
session is opened, and the next append starts on a fresh line. Lines that are valid JSON but not a valid
record (``123``, ``null``, a field of the wrong type) are skipped and reported the same way.

Integrity rules (issue 9):

* **Definition.** ``create(..., definition={...})`` stores everything that defines the frames (mode, frame
  size, seed, lights with exact levels, camera identity, ISO, aperture, exposure plan ...). ``open(...,
  definition=...)`` refuses, in one line naming the first difference, a resume asking for anything else
  (:class:`DefinitionMismatch`); :meth:`CaptureSession.extend_definition` adds what is decided later (the
  exposures from auto-exposure) under the same rule.
* **One writer.** A writing session holds an OS lock on its folder; a second process is refused with a line
  naming the holder (pid, host, since) (:class:`SessionLockedError`). ``open(readonly=True)`` reads without it.
* **Light dose.** ``record_dose(light, on_s, step_id=...)`` appends each lit period as it ends (a line of kind
  ``dose``); :meth:`CaptureSession.light_dose` sums them, so a killed and resumed run reports the whole dose.
* **Damaged frames.** :meth:`CaptureSession.require_intact` (before processing) refuses missing or damaged
  files naming the first; :meth:`CaptureSession.set_aside_damaged` (on resume) moves them to ``damaged/`` and
  logs a ``set_aside`` line, so their steps are no longer done and are shot again.

Disk full (``ENOSPC``) or any other write error while recording raises :class:`SessionError` (an ``OSError``,
one line naming the file) after removing the temp file and rolling the manifest back to its last complete line,
so the session stays valid and the shot can simply be retried.

Public API (what the sequences, GUI and demo call)::

    session = CaptureSession.create(folder, {"operator": "..."}, definition={"mode": "reflective", ...})
    session = CaptureSession.open(folder, definition={...})          # resume; refuses another definition
    session = CaptureSession.resume(folder, definition, meta)         # create, or open + set damaged aside
    entry = session.record(raw_capture, "dark", step_id="dark/1-60s/03",
                           light=LightSource((1, 6, 8), name="light 1"), sphere_temperature_c=31.2)
    session.record_dose(light, 0.52, step_id="flat/LS1/0.5/0");  session.light_dose() -> LightDose
    session.has_step("dark/1-60s/03") -> bool      # skip what a resumed sequence already shot
    session.entries(role="dark") -> list[SessionEntry]
    session.file_path(entry) -> Path
    session.verify() -> VerifyReport               # sha256 of every file, missing files, orphans
    session.require_intact()                       # before processing: DamagedFramesError naming the file
    session.update_settings(key=value)             # rewrites session.json atomically
    session.close()                                # gives the writer lock back (also on garbage collection)

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
import weakref
from pathlib import Path
from typing import Any, Union

from dualrgb.common import atomic_files
from dualrgb.common.atomic_files import TMP_SUFFIX, FileWriteError, fsync_dir, remove_quietly, write_all
from dualrgb.common.debris import sweep
from dualrgb.common.strict_json import dumps as strict_dumps
from dualrgb.core.metadata import frame_stem
from dualrgb.core.session import lock as session_lock
from dualrgb.core.session.manifest import (
    DamagedFramesError,
    DefinitionMismatch,
    DoseRecord,
    SessionEntry,
    SessionError,
    SessionLockedError,
    SetAside,
    VerifyReport,
    camera_definition,
    definition_differences,
    json_default,
    light_definition,
    normalise,
    now,
    read_manifest,
)
from dualrgb.drivers.camera.base import RawCapture
from dualrgb.simulation.versions import software_versions

log = logging.getLogger(__name__)

MANIFEST = "manifest.jsonl"
SETTINGS = "session.json"
DAMAGED_DIR = "damaged"
FORMAT = "dualrgb-session"
FORMAT_VERSION = 1

PathLike = Union[str, "os.PathLike[str]"]


_SAFE = re.compile(r"[^A-Za-z0-9._-]+")


def _safe(text: str) -> str:
    return _SAFE.sub("_", text).strip("._") or "raw"


def _light_dict(light: Any) -> dict | None:
    if light is None:
        return None
    if isinstance(light, dict):
        return dict(light)
    if hasattr(light, "to_dict"):
        return light.to_dict()
    raise TypeError(f"light must be a LightSource or a dict, got {type(light).__name__}")


def atomic_write(path: Path, data: bytes, *, exclusive: bool = False) -> None:
    """:func:`common.atomic_files.atomic_write` raising :class:`SessionError` (one line naming the file)."""
    try:
        atomic_files.atomic_write(path, data, exclusive=exclusive)
    except FileWriteError as exc:
        raise SessionError(exc.errno, str(exc)) from exc


def _session_error(exc: OSError, path: Path) -> SessionError:
    if isinstance(exc, SessionError):
        return exc
    return SessionError(exc.errno, str(atomic_files.write_error(exc, path)))


def _settings_bytes(settings: dict) -> bytes:
    return (strict_dumps(settings, indent=2, default=json_default) + "\n").encode()


def _allowed_leftover(p: Path) -> bool:
    """What a create killed before session.json leaves: the lock, its holder file and temp files."""
    return p.name in (session_lock.LOCK_NAME, session_lock.HOLDER_NAME) or (p.name.startswith(".")
                                                                            and p.name.endswith(TMP_SUFFIX))


def _lock(folder: Path) -> str:
    try:
        return session_lock.acquire(folder)
    except session_lock.LockHeld as exc:
        raise SessionLockedError(str(exc), exc.holder) from None
    except OSError as exc:
        raise _session_error(exc, folder / session_lock.LOCK_NAME) from exc


class CaptureSession:
    """A capture session folder (see the module docstring). One writing process at a time (OS lock)."""

    def __init__(self, path: Path, settings: dict, lines: list, skipped_lines: list[int], *,
                 lock_key: str | None = None):
        self.path = path
        self.settings = settings
        self._entries = [x for x in lines if isinstance(x, SessionEntry)]
        self._doses = [x for x in lines if isinstance(x, DoseRecord)]
        self._set_aside = [x for x in lines if isinstance(x, SetAside)]
        self._aside_seqs = {x.seq for x in self._set_aside}
        self._skipped_lines = skipped_lines
        self._pending: list[bytes] = []          # dose lines not yet on disk (a write failed; retried)
        self.readonly = lock_key is None
        self._lock_key = lock_key
        self._finalizer = weakref.finalize(self, session_lock.release, lock_key) if lock_key else None

    # ---- creation / opening ----
    @classmethod
    def create(cls, path: PathLike, meta: dict | None = None, *,
               definition: dict | None = None) -> CaptureSession:
        """A new session in ``path`` (created; must not exist or be an empty folder), locked for writing."""
        p = Path(path)
        if p.exists() and not p.is_dir():
            raise SessionError(errno.EEXIST, f"{p}: exists and is not a folder")
        try:
            p.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise _session_error(exc, p) from exc
        key = _lock(p)
        try:
            if any(not _allowed_leftover(x) for x in p.iterdir()):
                raise SessionError(errno.EEXIST, f"{p}: folder is not empty; open it to resume or choose a new one")
            for tmp in p.glob(f".*{TMP_SUFFIX}"):
                remove_quietly(tmp)
            settings = {"format": FORMAT, "version": FORMAT_VERSION, "software": software_versions(),
                        "created_at": now(), **(meta or {})}
            if definition is not None:
                settings["definition"] = normalise(definition)
            atomic_write(p / SETTINGS, _settings_bytes(settings))
            cls._create_manifest(p)
        except BaseException:
            session_lock.release(key)
            raise
        log.info("created capture session %s", p)
        return cls(p, settings, [], [], lock_key=key)

    @staticmethod
    def _create_manifest(p: Path) -> None:
        try:
            fd = os.open(p / MANIFEST, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            os.fsync(fd)
            os.close(fd)
            fsync_dir(p)
        except OSError as exc:
            raise _session_error(exc, p / MANIFEST) from exc

    @classmethod
    def open(cls, path: PathLike, *, definition: dict | None = None, readonly: bool = False,
             clean_temp: bool = True, hint: str = "") -> CaptureSession:
        """Open an existing session; unreadable manifest lines are skipped with a warning (never fatal).

        ``definition``: refuse (:class:`DefinitionMismatch`, ``hint`` appended) when the session was made
        with another one. ``readonly``: no writer lock, no writes. ``clean_temp`` removes the temp files and
        staging folders of processes killed mid-write (their owner named in them: common.debris). A session
        killed between session.json and its manifest gets an empty one.
        """
        p = Path(path)
        settings_path = p / SETTINGS
        if not settings_path.is_file():
            raise SessionError(errno.ENOENT, f"{p}: not a capture session (no {SETTINGS})")
        key = None if readonly else _lock(p)
        try:
            settings = cls._read_settings(settings_path)
            if not (p / MANIFEST).exists() and not readonly:
                log.warning("%s: no manifest (creation was interrupted); starting an empty one", p)
                cls._create_manifest(p)
            lines, skipped = read_manifest(p / MANIFEST)
            session = cls(p, settings, lines, skipped, lock_key=key)
        except BaseException:
            if key:
                session_lock.release(key)
            raise
        if definition is not None:
            try:
                session.check_definition(definition, hint=hint)
            except BaseException:
                session.close()
                raise
        if clean_temp and not readonly:
            sweep(p)                # temp files and staging folders of writers that were killed (common.debris)
        log.info("opened capture session %s: %d files", p, len(session._entries))
        return session

    @classmethod
    def resume(cls, path: PathLike, definition: dict, meta: dict | None = None, *,
               new_if_different: bool = False, hint: str = "") -> CaptureSession:
        """The session for a run defined by ``definition``: a new one in ``path``, or the one there resumed
        (definition checked, missing/damaged frames set aside so their steps are shot again).

        ``new_if_different``: instead of refusing a different definition, use the first sibling folder
        ``<path>-2``, ``<path>-3`` ... that is new or holds a session with this definition.
        """
        p = Path(path)
        candidates = [p] + ([p.with_name(f"{p.name}-{i}") for i in range(2, 100)] if new_if_different else [])
        for folder in candidates:
            if not (folder / SETTINGS).exists():
                return cls.create(folder, meta, definition=definition)
            try:
                session = cls.open(folder, definition=definition, hint=hint)
            except DefinitionMismatch:
                if folder == candidates[-1]:
                    raise
                continue
            if folder != p:
                log.warning("%s was made with other settings: using %s", p, folder)
            session.set_aside_damaged()
            return session
        raise AssertionError("unreachable")  # pragma: no cover

    @staticmethod
    def _read_settings(path: Path) -> dict:
        try:
            settings = json.loads(path.read_text(encoding="utf-8"))
        except (ValueError, OSError) as exc:
            raise SessionError(errno.EIO, f"{path}: unreadable session settings ({exc})") from exc
        if not isinstance(settings, dict):
            raise SessionError(errno.EIO, f"{path}: unreadable session settings (not a JSON object)")
        return settings

    def close(self) -> None:
        """Give the writer lock back (the session object can still be read)."""
        if self._finalizer is not None:
            self._finalizer()
        self.readonly = True

    def __enter__(self) -> CaptureSession:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- what defines the frames ----
    @property
    def definition(self) -> dict:
        return dict(self.settings.get("definition") or {})

    def check_definition(self, wanted: dict, *, hint: str = "") -> None:
        """Refuse (:class:`DefinitionMismatch`) a run whose ``wanted`` definition differs from the session's;
        top-level keys the session does not have yet are added (see :meth:`extend_definition`)."""
        wanted = normalise(wanted)
        stored = self.definition
        common = {k: stored[k] for k in wanted if k in stored}
        diffs = definition_differences(common, {k: wanted[k] for k in common})
        if diffs:
            more = f" (and {len(diffs) - 1} more)" if len(diffs) > 1 else ""
            raise DefinitionMismatch(f"{self.path}: the session was made with other settings: {diffs[0]}{more}; "
                                     f"{hint or 'resume with the same settings or start a new session'}", diffs)
        new = {k: v for k, v in wanted.items() if k not in stored}
        if new:
            if stored:
                log.info("%s: adding %s to the session definition", self.path, ", ".join(sorted(new)))
            else:
                log.warning("%s: the session has no recorded definition; adopting this run's", self.path)
            self._write_definition({**stored, **new})

    def extend_definition(self, **items: Any) -> None:
        """Add what is decided during a run (e.g. ``exposures=...``); an item already recorded must match."""
        self.check_definition(items)

    def _write_definition(self, definition: dict) -> None:
        if self.readonly:
            self.settings = {**self.settings, "definition": definition}
            return
        self.update_settings(definition=definition)

    # ---- queries ----
    def entries(self, role: str | None = None, *, include_superseded: bool = False) -> list[SessionEntry]:
        """Entries in recording order; a retaken step (same step_id recorded again) shows only its last take;
        frames set aside (missing or damaged on resume) are left out."""
        out = [e for e in self._entries if e.seq not in self._aside_seqs]
        if not include_superseded:
            last = {e.step_id: e.seq for e in out if e.step_id}
            out = [e for e in out if not e.step_id or last[e.step_id] == e.seq]
        if role is not None:
            out = [e for e in out if e.role == role]
        return out

    def has_step(self, step_id: str) -> bool:
        return any(e.step_id == step_id and e.seq not in self._aside_seqs for e in self._entries)

    def entry(self, step_id: str) -> SessionEntry:
        for e in reversed(self._entries):
            if e.step_id == step_id and e.seq not in self._aside_seqs:
                return e
        raise KeyError(f"step {step_id!r} not recorded in {self.path}")

    def file_path(self, entry: SessionEntry) -> Path:
        return self.path / entry.file

    def doses(self) -> list[DoseRecord]:
        return list(self._doses)

    def light_dose(self):
        """The session's whole light dose (core.session.light_dose.LightDose) summed from its dose lines."""
        from dualrgb.core.session.light_dose import LightDose, light_from_record

        total = LightDose()
        for d in self._doses:
            try:
                total.add(light_from_record(d.light), d.on_s)
            except ValueError as exc:           # an LED or level out of range: reported, never fatal
                log.warning("%s: dose line for step %s not counted: %s", self.path / MANIFEST, d.step_id, exc)
        return total

    def __len__(self) -> int:
        return len(self.entries())

    # ---- writing ----
    def _require_writer(self) -> None:
        if self.readonly:
            raise SessionError(errno.EROFS, f"{self.path}: session opened read-only (or closed); open it to write")

    def _next_seq(self) -> int:
        return max((e.seq for e in self._entries), default=0) + 1

    def _file_name(self, seq: int, role: str, camera_name: str, stem: str = "") -> str:
        """``0062_original_VIRT_0062.DNG``; a frame of an original carries its file stem after the number
        (``0062_ACC-1_original_VIRT_0062.DNG``: core.metadata.frame_stem). Names are only written: the
        manifest names every file, so sessions with the older names read as before."""
        middle = f"{_safe(stem)}_{_safe(role)}" if stem else _safe(role)
        name = f"{seq:04d}_{middle}_{_safe(Path(camera_name).name or 'capture.raw')}"
        while (self.path / name).exists() or (self.path / DAMAGED_DIR / name).exists():
            seq += 100000                        # an orphan from a killed run may hold the name
            name = f"{seq:04d}_{middle}_{_safe(Path(camera_name).name or 'capture.raw')}"
        return name

    def record(self, raw: RawCapture, role: str, *, step_id: str | None = None, light: Any = None,
               sphere_temperature_c: float | None = None, settings: dict | None = None,
               captured_at: str | None = None, **meta: Any) -> SessionEntry:
        """Write one downloaded raw file durably and log it; returns its manifest entry.

        ``light`` is a :class:`simulation.lightsource.LightSource` (or its dict); ``settings`` the camera
        settings at capture time; extra keyword arguments go to ``entry.meta`` (must be JSON-serialisable).
        """
        self._require_writer()
        if not role or not isinstance(role, str):
            raise ValueError(f"role must be a non-empty string, got {role!r}")
        data = bytes(raw.data)
        if not data:
            raise SessionError(errno.EINVAL, f"{raw.filename or 'capture'}: the camera returned an empty file")
        seq = self._next_seq()
        name = self._file_name(seq, role, raw.filename, frame_stem(meta.get("subject")))
        final = self.path / name
        entry = SessionEntry(
            seq=seq, file=name, role=role, sha256=hashlib.sha256(data).hexdigest(), size=len(data),
            step_id=step_id, exposure_s=raw.exposure_s, iso=raw.iso, aperture=raw.aperture, camera=raw.camera,
            camera_filename=raw.filename, light=_light_dict(light), sphere_temperature_c=sphere_temperature_c,
            settings=dict(settings or {}), captured_at=captured_at or str(raw.extra.get("captured_at", "")) or now(),
            recorded_at="", meta={**{k: v for k, v in raw.extra.items() if k != "captured_at"}, **meta})
        try:                                     # fail on unstorable meta before anything is written
            strict_dumps(entry.to_dict(), default=json_default)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name}: session metadata is not JSON-serialisable: {exc}") from exc
        # 1. the raw file, durable under its final name
        atomic_write(final, data, exclusive=True)
        # 2. the manifest line, durable
        entry.recorded_at = now()
        try:
            self._append_manifest(self._line(entry.to_dict()))
        except OSError as exc:
            remove_quietly(final)                # no manifest line: do not leave an unexplained file
            try:
                fsync_dir(self.path)
            except OSError:  # pragma: no cover
                pass
            raise _session_error(exc, self.path / MANIFEST) from exc
        self._entries.append(entry)
        log.debug("recorded %s (%s, %d bytes)", name, role, len(data))
        return entry

    def record_dose(self, light: Any, on_s: float, *, step_id: str | None = None, **meta: Any) -> DoseRecord:
        """Log one lit period as it ends: ``light`` (a LightSource or its dict, exact levels) on for ``on_s``.

        Never raises for a failed write (the light was on whatever the disk says): the line is kept and written
        before the next manifest line; :meth:`light_dose` counts it either way.
        """
        self._require_writer()
        if isinstance(light, dict):
            light_d = dict(light)
        else:
            light_d = light_definition(light)
        on = float(on_s)
        if not on >= 0 or on == float("inf"):
            raise ValueError(f"light-on time {on_s!r} s: expected a finite number >= 0")
        record = DoseRecord(light_d, on, step_id, now(), normalise(meta))
        self._doses.append(record)
        try:
            self._append_manifest(self._line(record.to_dict()))
        except OSError as exc:
            self._pending.append(self._line(record.to_dict()))
            log.error("%s: could not log the light dose yet (%s); it is kept and written with the next line",
                      self.path / MANIFEST, exc)
        return record

    @staticmethod
    def _line(obj: dict) -> bytes:
        return (strict_dumps(obj, default=json_default, separators=(",", ":")) + "\n").encode()

    def _append_manifest(self, line: bytes) -> None:
        path = self.path / MANIFEST
        data = b"".join(self._pending) + line
        fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            size = os.fstat(fd).st_size
            prefix = b""
            if size:
                os.lseek(fd, size - 1, os.SEEK_SET)
                if os.read(fd, 1) != b"\n":
                    prefix = b"\n"              # a killed append left a partial line: start a fresh one
            try:
                write_all(fd, prefix + data)
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
        self._pending.clear()

    def update_settings(self, **values: Any) -> None:
        """Merge ``values`` into session.json (atomic rewrite)."""
        self._require_writer()
        new = {**self.settings, **values}
        atomic_write(self.path / SETTINGS, _settings_bytes(new))
        self.settings = new

    # ---- checking ----
    def _check_file(self, e: SessionEntry, check_hashes: bool) -> str | None:
        """None when the entry's file is intact, else 'missing' / 'damaged: ...'."""
        p = self.path / e.file
        if not p.is_file():
            return "missing"
        size = p.stat().st_size
        if size != e.size:
            return f"damaged: {size} bytes, the manifest says {e.size}"
        if check_hashes and _sha256_file(p) != e.sha256:
            return "damaged: its sha256 differs from the manifest's"
        return None

    def verify(self, *, check_hashes: bool = True) -> VerifyReport:
        """Check that every recorded file exists with its size and sha256; list orphans and bad lines."""
        report = VerifyReport(skipped_lines=list(self._skipped_lines),
                              set_aside=[x.file for x in self._set_aside])
        named = {e.file for e in self._entries}
        for e in self._entries:
            if e.seq in self._aside_seqs:
                continue
            problem = self._check_file(e, check_hashes)
            if problem is None:
                report.ok.append(e.file)
            else:
                (report.missing if problem == "missing" else report.corrupted).append(e.file)
        for p in sorted(self.path.iterdir()):
            if p.name in (MANIFEST, SETTINGS) or p.name.startswith(".") or p.is_dir() or p.name in named:
                continue
            report.orphans.append(p.name)
        level = logging.INFO if report.valid else logging.WARNING
        log.log(level, "verify %s: %s", self.path, report.summary())
        return report

    def damaged(self, entries: list[SessionEntry] | None = None) -> list[tuple[SessionEntry, str]]:
        """(entry, problem) for every current frame (or of ``entries``) that is missing or damaged."""
        out = []
        for e in self.entries() if entries is None else entries:
            problem = self._check_file(e, True)
            if problem is not None:
                out.append((e, problem))
        return out

    def require_intact(self, entries: list[SessionEntry] | None = None) -> None:
        """Before processing: raise :class:`DamagedFramesError` naming the first missing or damaged frame."""
        bad = self.damaged(entries)
        if bad:
            e, problem = bad[0]
            more = f" ({len(bad) - 1} more)" if len(bad) > 1 else ""
            raise DamagedFramesError(f"{self.file_path(e)}: {problem}; not processed{more}. Resume the session to "
                                     f"shoot {'it' if len(bad) == 1 else 'them'} again", [x.file for x, _ in bad])

    def set_aside_damaged(self) -> list[SetAside]:
        """On resume: move every missing/damaged current frame's file to ``damaged/`` (never deleted) and log
        it, so its step counts as not done and is shot again. Returns what was set aside."""
        self._require_writer()
        out = []
        for e, problem in self.damaged():
            moved = None
            src = self.path / e.file
            if src.exists():
                dest_dir = self.path / DAMAGED_DIR
                dest_dir.mkdir(exist_ok=True)
                dest = dest_dir / e.file
                n = 1
                while dest.exists():
                    dest, n = dest_dir / f"{e.file}.{n}", n + 1
                os.replace(src, dest)
                fsync_dir(dest_dir)
                fsync_dir(self.path)
                moved = f"{DAMAGED_DIR}/{dest.name}"
            record = SetAside(e.seq, e.file, problem, moved, e.step_id, now())
            self._append_manifest(self._line(record.to_dict()))
            self._set_aside.append(record)
            self._aside_seqs.add(e.seq)
            log.warning("%s: %s; set aside%s, step %s will be shot again", e.file, problem,
                        f" to {moved}" if moved else "", e.step_id)
            out.append(record)
        return out


def _sha256_file(path: Path, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while True:
            block = fh.read(chunk)
            if not block:
                break
            h.update(block)
    return h.hexdigest()


__all__ = ["CaptureSession", "DamagedFramesError", "DefinitionMismatch", "DoseRecord", "SessionEntry",
           "SessionError", "SessionLockedError", "SetAside", "VerifyReport", "atomic_write", "camera_definition",
           "light_definition", "MANIFEST", "SETTINGS"]
