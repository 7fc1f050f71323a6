"""What a killed writer leaves behind, recognised by its owner and removed by the next writer.

Every partial file and folder the product writes is named by the process that writes it:

* temp files ``.<name>.<pid>.tmp`` (:func:`common.atomic_files.temp_path`): renamed over ``<name>`` when complete;
* staging folders ``.<name>.<pid>.<token>.new`` (:func:`stage_name`): an original's deliverables, swapped in
  whole when complete (app.workflow.delivery.delivery_folder).

:func:`sweep` (called by every writer of a session folder and of a deliverables folder before it writes) removes
those whose owner process is gone (killed, crashed, the machine restarted) and leaves alone those of a process
still running (another writer, this one). A staging folder named the older way, without its owner, is reported
(a warning naming it), never removed: it may be another running program's. At full resolution each is hundreds
of MB, so they are not left for long.
"""
from __future__ import annotations

import logging
import os
import re
import secrets
import shutil
from dataclasses import dataclass, field
from pathlib import Path

log = logging.getLogger(__name__)

TEMP = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)\.tmp$")
STAGE = re.compile(r"^\.(?P<name>.+?)\.(?:(?P<pid>\d+)\.)?(?P<token>[0-9a-f]{8})\.new$")


def stage_name(name: str) -> str:
    """The hidden staging folder name for ``name``, owned by this process."""
    return f".{name}.{os.getpid()}.{secrets.token_hex(4)}.new"


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` runs (this one always does); psutil, so no signal is ever sent (Windows)."""
    if pid == os.getpid():
        return True
    import psutil

    return bool(psutil.pid_exists(pid))


@dataclass
class Sweep:
    """What :func:`sweep` found: ``removed`` (owner gone), ``kept`` (owner running), ``unowned`` (no owner named:
    reported only)."""

    removed: list[Path] = field(default_factory=list)
    kept: list[Path] = field(default_factory=list)
    unowned: list[Path] = field(default_factory=list)


def sweep(folder: Path, depth: int = 3) -> Sweep:
    """Remove the temp files and staging folders under ``folder`` (``depth`` levels down) whose owner is gone."""
    out = Sweep()
    _walk(Path(folder), depth, out)
    if out.removed:
        log.warning("%s: removed %d file(s) / folder(s) left by a writer that was killed: %s", folder,
                    len(out.removed), ", ".join(str(p.relative_to(folder)) for p in out.removed[:5]))
    for p in out.unowned:
        log.warning("%s: an unfinished delivery from an older dualrgb (or another program); remove it once "
                    "nothing writes there", p)
    return out


def _walk(folder: Path, depth: int, out: Sweep) -> None:
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return
    for entry in entries:
        is_dir = entry.is_dir(follow_symlinks=False)
        stage = STAGE.match(entry.name) if is_dir else None
        temp = TEMP.match(entry.name) if not is_dir else None
        if stage is not None:
            _judge(Path(entry.path), stage.group("pid"), out, folder_=True)
        elif temp is not None:
            _judge(Path(entry.path), temp.group("pid"), out, folder_=False)
        elif is_dir and depth > 1:
            _walk(Path(entry.path), depth - 1, out)


def _judge(path: Path, pid: str | None, out: Sweep, folder_: bool) -> None:
    if pid is None:
        out.unowned.append(path)
        return
    if process_alive(int(pid)):
        out.kept.append(path)
        return
    try:
        if folder_:
            shutil.rmtree(path)
        else:
            path.unlink()
    except FileNotFoundError:
        return
    except OSError as exc:
        log.warning("could not remove %s (left by a killed writer): %s", path, exc)
        return
    out.removed.append(path)
