"""Refusals the command line makes before anything heavy is imported or any device opens: an unknown option with
the closest valid one, options that do not apply together, a missing calibration or session named at once.

Everything here imports only the standard library (``dualrgb --help`` and a refusal stay fast: bench/refusals.py
measures the time to a refusal).
"""
from __future__ import annotations

import argparse
import difflib
import json
from collections.abc import Sequence
from pathlib import Path

CALIBRATIONS = "calibration"              # <session>/calibration/cal-*.json (app.workflow.calibration.profile)


def innermost_parser(parser: argparse.ArgumentParser, found: argparse.Namespace) -> argparse.ArgumentParser:
    """The (sub)parser of the command ``found`` names (``calibration show``: show's), else ``parser``."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            chosen = getattr(found, action.dest, None)
            sub = action.choices.get(chosen) if chosen is not None else None
            if sub is not None:
                return innermost_parser(sub, found)
    return parser


def option_strings(parser: argparse.ArgumentParser) -> list[str]:
    """Every long option of ``parser`` (``--session``, ``--virtual-lab`` ...)."""
    return sorted({o for a in parser._actions for o in a.option_strings if o.startswith("--")})


def unrecognised(parser: argparse.ArgumentParser, extras: Sequence[str]) -> str:
    """argparse's 'unrecognized arguments' line, with the closest valid option for each unknown one."""
    valid = option_strings(parser)
    hints = []
    for word in extras:
        if not word.startswith("-"):
            continue
        close = difflib.get_close_matches(word.split("=", 1)[0], valid, n=1, cutoff=0.6)
        if close:
            hints.append((word.split("=", 1)[0], close[0]))
    line = f"unrecognized arguments: {' '.join(extras)}"
    if len(hints) == 1:
        return f"{line} (did you mean {hints[0][1]}?)"
    return f"{line} ({'; '.join(f'{w}: did you mean {c}?' for w, c in hints)})" if hints else line


def calibrations_of(session: Path) -> list[Path]:
    """The session's calibration profiles, oldest first (their names start with the UTC time they were made)."""
    return sorted((Path(session) / CALIBRATIONS).glob("cal-*.json"))


def newest_calibration(session: Path | None, mode: str | None = None) -> Path:
    """The session's newest calibration (of ``mode``'s when one is), or ValueError (one line) naming what to do."""
    if session is None:
        raise ValueError("name the calibration: --calibration FILE (or --session DAY holding one: `dualrgb calibrate "
                         "--session DAY` makes it)")
    if not Path(session).is_dir():
        raise ValueError(f"{session}: no such session folder (`dualrgb calibrate --session {session}` makes it); or "
                         "pass --calibration FILE")
    found = calibrations_of(Path(session))
    if mode:
        found = [f for f in found if _mode_of(f) == mode] or found
    if not found:
        raise ValueError(f"{session}: no calibration in it yet (dualrgb calibrate --session {session}); or pass "
                         "--calibration FILE")
    return found[-1]


def _mode_of(profile: Path) -> str | None:
    """The mode a calibration profile records (its JSON's ``mode``), None when it cannot be read."""
    try:
        doc = json.loads(profile.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return doc.get("mode") if isinstance(doc, dict) else None


def check_sessions(sessions: Sequence[Path], calibration: Path | None) -> None:
    """``process``'s inputs, read without any heavy import: each SESSION a session folder, and a calibration for
    it (``--calibration``, else one in the session: its calibration/ folder or named by its originals)."""
    for session in sessions:
        folder = Path(session)
        if not folder.is_dir():
            raise ValueError(f"{session}: no such session folder")
        if not (folder / "session.json").is_file():
            raise ValueError(f"{session}: not a capture session (no session.json)")
        if calibration is None and not calibrations_of(folder) and not _named_calibrations(folder):
            raise ValueError(f"{session}: no calibration in it or named by its originals; pass --calibration FILE")


def _named_calibrations(session: Path) -> list[str]:
    """The calibrations the session's originals were delivered with (session.json), as recorded."""
    try:
        doc = json.loads((session / "session.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return ["?"]                     # unreadable: opening the session says why
    originals = doc.get("originals") if isinstance(doc, dict) else None
    return [str(o["calibration"]) for o in (originals or {}).values() if isinstance(o, dict) and o.get("calibration")]
