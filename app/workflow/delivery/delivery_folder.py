"""Where an original's deliverables go, and how a re-delivery replaces them without losing the previous set.

* ``<out>/<stem>/`` holds one original's current deliverables (``stem``: core.metadata.file_stem, distinct
  for distinct identifiers, also on case-insensitive file systems), its sidecar ``<stem>.json`` naming the
  identifier. Where ``<out>``'s file system refuses Unicode names (core.metadata.unicode_names_work, probed once
  per deliverables folder: :func:`stem_of`), the stem is its documented reversible ASCII form
  (core.metadata.ascii_stem, ``xn--`` + Punycode), said in one log line; the sidecar and the XMP keep the
  exact identifier.
* :func:`check_folder` (run before the light goes on, and again just before a delivery lands) refuses in one line
  a folder whose sidecar names another identifier, a folder without a sidecar that holds files (not ours to
  write into), and a file where the folder should be.
* :func:`staged` writes a delivery into a fresh hidden folder beside it (``.<stem>.<pid>.<random>.new``, named by
  its writer: what a killed writer left is removed by the next one, common.debris); only when
  every file is complete is it swapped in with renames: the current set moves, whole, to
  ``<stem>/previous/<its creation time>/`` (older ones stay there too), then the new folder takes the name. A
  reader sees the old set or the new one, never a mix (for the instant between the two renames, neither); an
  error removes the new folder and leaves the current set as it was; a crash leaves both complete sets on disk.
"""
from __future__ import annotations

import json
import logging
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from dualrgb.common.atomic_files import fsync_dir
from dualrgb.common.debris import stage_name, sweep
from dualrgb.core.metadata import Original, ascii_stem, unicode_names_work

log = logging.getLogger(__name__)

SIDECAR_FORMAT = "dualrgb-delivery/1"
PREVIOUS = "previous"


class DeliveryFolderError(ValueError):
    """A deliverables folder that must not be written into; ``str()`` is one line naming it."""


def read_sidecar(path: Path) -> dict[str, Any]:
    """A delivery sidecar's JSON (ValueError when it is not one)."""
    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    if not isinstance(doc, dict) or doc.get("format") != SIDECAR_FORMAT:
        fmt = doc.get("format") if isinstance(doc, dict) else None
        raise ValueError(f"{path}: not a dualrgb delivery sidecar (format {fmt!r})")
    return doc


def sidecar_identifier(path: Path) -> str | None:
    """The identifier a sidecar names (None: no sidecar there); DeliveryFolderError when it cannot be read."""
    if not path.exists():
        return None
    try:
        ident = (read_sidecar(path).get("original") or {}).get("identifier")
    except (OSError, ValueError) as exc:
        raise DeliveryFolderError(f"{path}: cannot read this delivery's sidecar ({exc}); not written into") from exc
    if not isinstance(ident, str):
        raise DeliveryFolderError(f"{path}: the sidecar names no identifier; not written into")
    return ident


_UNICODE_NAMES: dict[Path, bool] = {}       # deliverables folder -> whether its file system keeps Unicode names


def unicode_names(out_dir: Path) -> bool:
    """Whether ``out_dir``'s file system keeps Unicode file names: probed once per folder (the nearest existing
    folder while it is not made yet; a folder that cannot be written is not probed: its write fails and says so)."""
    key = Path(out_dir).absolute()
    if key in _UNICODE_NAMES:
        return _UNICODE_NAMES[key]
    probe = key
    while not probe.is_dir() and probe != probe.parent:
        probe = probe.parent
    if not os.access(probe, os.W_OK | os.X_OK):
        return True
    works = _UNICODE_NAMES[key] = unicode_names_work(probe)
    if not works:
        log.warning("%s: this file system refuses Unicode file names; an identifier that is not ASCII names its "
                    "folder and files by its reversible ASCII form (xn-- + Punycode, RFC 3492); the sidecar and "
                    "XMP keep the exact identifier", out_dir)
    return works


def stem_of(out_dir: Path, original: Original) -> str:
    """The stem of ``original``'s deliverables in ``out_dir``: its file stem (core.metadata.file_stem), or that
    stem's reversible ASCII form where the file system refuses Unicode names (:func:`unicode_names`)."""
    stem = original.file_stem
    return stem if stem.isascii() or unicode_names(out_dir) else ascii_stem(stem)


def folder_of(out_dir: Path, original: Original) -> Path:
    return Path(out_dir) / stem_of(out_dir, original)


def sidecar_of(out_dir: Path, original: Original) -> Path:
    return folder_of(out_dir, original) / f"{stem_of(out_dir, original)}.json"


def check_folder(out_dir: Path, original: Original) -> None:
    """Refuse (DeliveryFolderError, one line) to deliver ``original`` where another original's files are."""
    folder = folder_of(out_dir, original)
    if not folder.exists():
        if Path(out_dir).exists() and not Path(out_dir).is_dir():
            raise DeliveryFolderError(f"{out_dir}: is a file, not a deliverables folder")
        return
    if not folder.is_dir():
        raise DeliveryFolderError(f"{folder}: is a file where {original.identifier!r}'s deliverables folder goes")
    owner = sidecar_identifier(sidecar_of(out_dir, original))
    if owner is None:
        if any(p.name != PREVIOUS for p in folder.iterdir()):
            raise DeliveryFolderError(f"{folder}: holds files but no sidecar {folder.name}.json (not a "
                                      f"delivery of {original.identifier!r}); move it away or choose another --out")
        return
    if owner != original.identifier:
        raise DeliveryFolderError(f"{folder} holds the deliverables of {owner!r} (its sidecar); "
                                  f"{original.identifier!r} is not written into it")


def prepare(out_dir: Path, original: Original) -> None:
    """What must hold before an original is shot (nothing is created): its deliverables folder is not another
    original's, and the deliverables folder (or the folder it will be made in) is writable."""
    check_folder(out_dir, original)
    existing = Path(out_dir).absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        raise DeliveryFolderError(f"{out_dir}: the deliverables folder cannot be written ({existing} is not a "
                                  "writable folder)")


@contextmanager
def staged(out_dir: Path, original: Original) -> Iterator[Path]:
    """A fresh folder to write ``original``'s new deliverables into, swapped in when the block ends without error
    (the previous set kept in ``previous/``; see the module docstring); removed on error."""
    prepare(out_dir, original)
    try:
        Path(out_dir).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DeliveryFolderError(f"{out_dir}: cannot create the deliverables folder ({exc.strerror or exc})") from exc
    sweep(Path(out_dir), depth=2)                   # what a killed delivery left (common.debris)
    stage = Path(out_dir) / stage_name(stem_of(out_dir, original))
    stage.mkdir()                                   # (not tempfile.mkdtemp: its 0700 would stay on the folder)
    try:
        yield stage
        check_folder(out_dir, original)             # nothing else took the name while the files were written
        _swap_in(stage, folder_of(out_dir, original))
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise


def _swap_in(stage: Path, final: Path) -> None:
    if final.exists():
        history = stage / PREVIOUS
        if (final / PREVIOUS).is_dir():
            os.replace(final / PREVIOUS, history)
        history.mkdir(exist_ok=True)
        kept = _free(history / _version_name(final))
        os.replace(final, kept)
        log.info("previous deliverables of %s kept in %s", final.name, kept.relative_to(stage))
    os.replace(stage, final)
    fsync_dir(final.parent)


def _version_name(folder: Path) -> str:
    """The name a replaced set is kept under: its sidecar's creation time (UTC, ``20261124T101112Z``)."""
    when = None
    try:
        created = read_sidecar(folder / f"{folder.name}.json").get("created_at")
        when = datetime.fromisoformat(str(created)) if created else None
    except (OSError, ValueError) as exc:
        log.debug("%s: no readable creation time (%s); its modification time names it", folder, exc)
    if when is None:
        when = datetime.fromtimestamp(folder.stat().st_mtime, UTC)
    if when.tzinfo is not None:
        when = when.astimezone(UTC)
    return when.strftime("%Y%m%dT%H%M%SZ")


def _free(path: Path) -> Path:
    n, out = 1, path
    while out.exists():
        n += 1
        out = path.with_name(f"{path.name}-{n}")
    return out


def previous_sets(out_dir: Path, original: Original) -> list[Path]:
    """The earlier deliveries of ``original`` kept in its folder, oldest first."""
    history = folder_of(out_dir, original) / PREVIOUS
    return sorted(p for p in history.iterdir() if p.is_dir()) if history.is_dir() else []


__all__ = ["PREVIOUS", "SIDECAR_FORMAT", "DeliveryFolderError", "check_folder", "folder_of", "prepare",
           "previous_sets", "read_sidecar", "sidecar_identifier", "sidecar_of", "staged", "stem_of", "unicode_names"]
