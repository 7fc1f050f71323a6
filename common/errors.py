"""The mark of an error meant for the person at the stand, and the last-resort report of one that is not.

:class:`ReportedError` is mixed into every device and workflow error whose message is one line saying what
happened, to which device or file, and what to do (drivers.led_sphere.SphereError, drivers.camera.CameraError,
drivers.monochromator.MonochromatorError, core.light_safety.LightSafetyError, ...): front ends (the CLI, the
GUI) show such an error as it is. Anything else that reaches a front end is a bug: :func:`write_crash_report`
keeps its traceback in a file and the front end says, in one line, what failed and where that file is.

It lives in ``common`` so that drivers/ and app/ mark their errors without importing each other.
"""
from __future__ import annotations

import logging
import os
import sys
import traceback
from datetime import UTC, datetime
from pathlib import Path

log = logging.getLogger(__name__)

CRASH_PREFIX = "dualrgb-crash-"


class ReportedError(Exception):
    """An error whose ``str()`` is one line for the user (device or file, what happened, what to do)."""


def one_line(exc: BaseException) -> str:
    """``str(exc)`` on one line, with its notes (PEP 678: e.g. what state the light was left in) after it."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    notes = [" ".join(str(n).split()) for n in getattr(exc, "__notes__", ()) or ()]
    return "; ".join([text, *[n for n in notes if n and n not in text]])


def write_crash_report(exc: BaseException, folder: Path, argv: list[str] | None = None) -> Path | None:
    """Write ``exc``'s traceback (and the command line) to a new file in ``folder``; its path, or None when even
    that failed (then the traceback goes to the log)."""
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    path = Path(folder) / f"{CRASH_PREFIX}{stamp}-{os.getpid()}.txt"
    text = (f"dualrgb crash report, {stamp}\ncommand: {' '.join(argv if argv is not None else sys.argv)}\n"
            f"python {sys.version.split()[0]}\n\n" + "".join(traceback.format_exception(exc)))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "x", encoding="utf-8", errors="backslashreplace") as fh:
            fh.write(text)
    except OSError as err:
        log.error("could not write the crash report %s (%s):\n%s", path, err, text)
        return None
    return path
