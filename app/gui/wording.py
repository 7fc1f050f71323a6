"""The window's words (issue 42): a message from the workflow or a driver, written for the command line, said in
the window's own terms - no CLI flag, no shell command, no clause repeated.

The workflow's messages name what a CLI user types ("or --force to use this one", "connect it: Devices, or
--port"); the window shows them through :func:`in_window_words`, which says what to press instead (*Capture
anyway*, *Devices*) or leaves the clause out where the window has nothing to press. A flag no rule knows is named
as an option in words, never as ``--flag``. tests/gui/test_words.py runs every message the workflow can raise
through it. The window's own questions whose words depend on a count or a state (the re-shoot question, the
*Import CSV…* button) are made here too, with the one plural rule (common.formatting.counted).
"""
from __future__ import annotations

import re

from dualrgb.common.formatting import counted

# (pattern, replacement), in order: the specific sentences first, the generic flag last
REWRITES: tuple[tuple[str, str], ...] = (
    (r"\s*\(dualrgb calibrate --mode \w+\)", ""),
    (r",? or --force to use (?:this one|it anyway)", ", or choose Capture anyway"),
    (r"\s*\(--force to use it anyway\)", " (Originals: tick 'use it although it does not match the stand')"),
    (r"\(--force\)", "(Capture anyway)"),
    (r"recalibrate with --hdr auto", "calibrate again with 'also the longer exposures HDR originals may need'"),
    (r"a shorter --settle", "a shorter Settle (Calibrate & capture)"),
    (r"\s*\(--frame-size on the virtual lab\)", ""),
    (r",? or --(?:port|camera)\b", ""),
    (r"choose another --out", "choose another folder"),
    (r"\s*\(capture --ppi sets the sampling\)", " (the deliverables' sampling is set in Originals > Options)"),
    (r"pass one with --calibration|pass --calibration FILE", "choose one in Tools > Re-deliver"),
    (r"with --mode and their own targets", "on their own, with their own targets"),
    (r"\s*\(--spectral or the delivery settings\)", " (the delivery settings)"),
    (r"deliver without --spectral", "deliver without the spectral cube"),
    (r"--no-spectral or ", ""),
    (r"--render-illuminant (\S+):", r"rendering light \1:"),
    (r"add --spectral to write", "ask for the spectral cube in the delivery settings to write"),
    (r"or leave the option out", "or choose the default rendering light"),
    (r"or choose with --column \S+", "or name the column in Originals > Options: CSV columns"),
    (r"name it with --column \S+", "name it in Originals > Options: CSV columns"),
    (r"check --column", "check Originals > Options: CSV columns"),
    (r"without --preset", "without a preset"),
    (r"(?:a new|another) --session(?: folder)?", "a new session"),
    (r"new or empty --session folder", "new or empty session folder"),
    (r"\s*\(--out\)", ""),
    (r"`dualrgb simulate --stand-dir`", "Simulate & optimise on the measured stand"),
    (r"\s*\(ls /dev/tty[^)]*\)", " (Refresh lists the ports)"),
    (r"\[Errno \d+\] could not open port [^:]+: \[Errno \d+\] ([^:;]+): '[^']*'", r"\1"),
)
_COMPILED = tuple((re.compile(p), r) for p, r in REWRITES)
FLAG = re.compile(r"`?(?:dualrgb [a-z-]+ )?(?<![\w-])--([a-z][a-z-]*)(?:[ =](?:FILE|NAME|X=NAME))?`?")
CLI_FLAG = re.compile(r"(?<![\w-])--[a-z][a-z-]+")


def _flag_words(match: re.Match[str]) -> str:
    return f"the '{match.group(1).replace('-', ' ')}' option"


def _one_each(message: str) -> str:
    """``message`` without a clause said twice in a row ('port X: port X: ...' -> 'port X: ...')."""
    parts = message.split(": ")
    kept = [p for i, p in enumerate(parts) if i == 0 or p.strip() != parts[i - 1].strip()]
    return ": ".join(kept)


def in_window_words(message: str) -> str:
    """``message`` as the window says it: no CLI flag, no repeated clause (see the module docstring)."""
    text = message
    for pattern, replacement in _COMPILED:
        text = pattern.sub(replacement, text)
    text = FLAG.sub(_flag_words, text)
    return re.sub(r"  +", " ", _one_each(text))


def has_cli_flag(text: str) -> bool:
    """Whether ``text`` names a CLI flag (``--force``)."""
    return CLI_FLAG.search(text) is not None


# ---------------------------------------------------------------- the window's own questions, counted right
def reshoot_question(identifier: str, takes: list[int], delivered: bool) -> str:
    """The question for an original already in the session (``takes``: the take of each of its frames there): the
    frames of its last take counted, 'deliver it again' only when it was delivered (a take cut short was not)."""
    take = max(takes)
    n = takes.count(take)
    its, old = ("its frame", "the old frame stays") if n == 1 else ("its frames", "the old frames stay")
    if delivered:
        return (f"{identifier} is already delivered in this session ({counted(n, 'frame')}, take {take}). Re-shoot "
                f"it (a new take; {old} in the session), keep {its} and deliver it again, or cancel (nothing is "
                "lit)?")
    return (f"{identifier}: {counted(n, 'frame')} already captured (take {take}), never delivered. Re-shoot it (a "
            f"new take; {old} in the session), keep {its} and shoot only what is missing, or cancel (nothing is "
            "lit)?")


def add_valid(n: int) -> str:
    """The *Import CSV…* question's button: 'Add the valid row', 'Add the 6 valid rows'."""
    return "Add the valid row" if n == 1 else f"Add the {counted(n, 'valid row')}"
