"""The mode rule (Qt-free; the CLI's capture and process, the GUI and the demo all ask it): an original is
captured and delivered only with a calibration of its own mode - a film (transmissive) with a transmissive
calibration, a painting or print (reflective) with a reflective one - because the matrix and the spectral
estimate are fitted to that mode's charts under that mode's lights. It is checked before any device acts.
The user may override it explicitly (``--force``, the GUI's "capture anyway"); the override is then said in the
sidecar (``overrides``) and at the front of the QA line.

    override = check_mode(original, profile, force=args.force)    # ModeMismatch (one line) unless forced
"""
from __future__ import annotations

import logging
from typing import Any

log = logging.getLogger(__name__)


class ModeMismatch(ValueError):
    """An original whose mode differs from the calibration's (one line: what, and what to do)."""


def mode_problem(original_mode: str, calibration_mode: str, calibration_id: str) -> str:
    """Why the original may not be captured with this calibration ('' when the modes agree)."""
    if original_mode == calibration_mode:
        return ""
    return (f"{original_mode} original, {calibration_mode} calibration {calibration_id}: capture it with a "
            f"{original_mode} calibration (dualrgb calibrate --mode {original_mode}), or --force to use this one")


def override_text(original_mode: str, calibration_mode: str, calibration_id: str) -> str:
    """What the sidecar and the QA line say of a forced mode mismatch."""
    return (f"mode overridden (--force): {original_mode} original with {calibration_mode} calibration "
            f"{calibration_id}, colour not characterised for it")


def check_mode(original: Any, profile: Any, *, force: bool = False) -> str:
    """'' when ``original``'s mode is the calibration's; the override text when it is not and ``force``; else
    :class:`ModeMismatch` naming the original."""
    problem = mode_problem(original.mode, profile.mode, profile.id)
    if not problem:
        return ""
    if not force:
        raise ModeMismatch(f"{original.identifier}: {problem}")
    text = override_text(original.mode, profile.mode, profile.id)
    log.warning("%s: %s", original.identifier, text)
    return text
