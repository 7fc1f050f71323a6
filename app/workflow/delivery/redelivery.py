"""``dualrgb process``: deliver every original of a session again, with one calibration or one per mode.

Each original goes through the mode rule (app.workflow.stand.mode_rule) and is delivered from its frames in the session
(app.workflow.stand.copystand's channel builders) at the chosen resolution; one that cannot be delivered (frames missing
or damaged, a folder of another original, a refused delivery) is listed with its reason and the others go on.
"""
from __future__ import annotations

import logging
from contextlib import closing
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from dualrgb.app.processing.masters import FULL
from dualrgb.app.workflow.calibration.profile import CalibrationProfile, load_profile
from dualrgb.app.workflow.delivery.delivery import Delivery, Original, deliver
from dualrgb.app.workflow.delivery.delivery_folder import prepare
from dualrgb.app.workflow.delivery.delivery_settings import DeliverySettings
from dualrgb.app.workflow.raw_import.import_checks import imported_warnings
from dualrgb.app.workflow.stand.copystand import channels_of, original_dose, profile_processor
from dualrgb.app.workflow.stand.mode_rule import check_mode
from dualrgb.common.errors import ReportedError, one_line
from dualrgb.common.progress import CancelToken, ProgressCallback, report
from dualrgb.core.metadata import MetadataError
from dualrgb.core.session.manifest import DamagedFramesError
from dualrgb.core.session.paths import inside
from dualrgb.core.vocabulary import Role, Subject

log = logging.getLogger(__name__)


@dataclass
class Undelivered:
    """An original ``dualrgb process`` could not deliver, and why (one line)."""

    identifier: str
    reason: str


@dataclass
class Redelivered:
    """A re-delivery as it goes, filled in place so that a cancelled one still says what it did: the originals it
    takes in order (``planned``), those delivered again, those it could not deliver (why), the mode rule's refusals
    (one line each, the identifier first) and every original it finished with (``finished``)."""

    planned: list[str] = field(default_factory=list)
    delivered: list[Delivery] = field(default_factory=list)
    undelivered: list[Undelivered] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)
    finished: list[str] = field(default_factory=list)

    def not_done(self) -> list[str]:
        """The planned originals it did not get to (a cancelled re-delivery: they keep their deliverables)."""
        finished = set(self.finished)
        return [i for i in self.planned if i not in finished]


def redeliver(session: Any, profiles: CalibrationProfile | dict[str, CalibrationProfile], out_dir: Path, *,
              ppi: float | None = None, progress: ProgressCallback | None = None, cancel: CancelToken | None = None,
              render_illuminant: str | None = None, force: bool = False, resolution: str = FULL,
              settings: DeliverySettings | None = None, tally: Redelivered | None = None
              ) -> tuple[list[Delivery], list[Undelivered]]:
    """Deliver every original of a session again (``dualrgb process``) at ``resolution``: with ``profiles`` (one
    calibration, or one per mode), the mode rule applied to each (app.workflow.stand.mode_rule: an original without a
    calibration of its mode is left out, its line in ``tally.refused``, unless ``force`` with one calibration);
    each original's current deliverables move to its ``previous/`` folder. Every original that can be is
    delivered; one whose frames are missing or damaged, whose folder is another's or whose delivery fails is
    listed with its reason (issue 28). The spectral rendering is seen under ``render_illuminant``; ``settings``:
    the delivery settings (None: the settings file's, app.workflow.delivery.delivery_settings). ``tally`` is filled
    as it goes (:class:`Redelivered`: what a cancelled run did before it stopped)."""
    from dualrgb.app.workflow.calibration.session_processing import session_frames

    frames = session_frames(session, intact=False)
    damaged = {e.file: problem for e, problem in session.damaged()}
    known = session.settings.get("originals", {})
    out = tally if tally is not None else Redelivered()
    subjects = [s for s in frames.subjects if s.role is Role.ORIGINAL]
    out.planned[:] = [s.name for s in subjects]
    for i, subject in enumerate(subjects):
        if cancel is not None:
            cancel.check()
        try:
            original = _known_original(session, known, subject.name)
            profile, override = _profile_for(original, profiles, force)
            if profile is None:
                out.refused.append(override)
            else:
                out.delivered.append(_redeliver_one(session, frames, subject, original, profile, damaged, out_dir,
                                                    ppi, cancel, render_illuminant, override, resolution, settings))
        except (ValueError, OSError, ReportedError) as exc:
            log.warning("%s: not delivered: %s", subject.name, exc)
            out.undelivered.append(Undelivered(subject.name, one_line(exc)))
        out.finished.append(subject.name)
        report(progress, (i + 1) / len(subjects), f"{subject.name} done")
    return out.delivered, out.undelivered


def _profile_for(original: Original, profiles: CalibrationProfile | dict[str, CalibrationProfile],
                 force: bool) -> tuple[CalibrationProfile | None, str]:
    """(the calibration ``original`` is delivered with, the override text) or (None, why not) by the mode rule."""
    if isinstance(profiles, dict):
        if original.mode in profiles:
            return profiles[original.mode], ""
        have = ", ".join(sorted(profiles)) or "none"
        return None, (f"{original.identifier}: {original.mode} original, and no {original.mode} calibration "
                      f"(the session's: {have}); pass one with --calibration")
    try:
        return profiles, check_mode(original, profiles, force=force)
    except ValueError as exc:
        return None, str(exc)


def _redeliver_one(session: Any, frames: Any, subject: Subject, original: Original, profile: CalibrationProfile,
                   damaged: dict[str, str], out_dir: Path, ppi: float | None, cancel: CancelToken | None,
                   render_illuminant: str | None, override: str, resolution: str = FULL,
                   settings: DeliverySettings | None = None, *, extra: dict | None = None,
                   now: datetime | None = None) -> Delivery:
    from dualrgb.app.workflow.calibration.session_processing import select_lights
    from dualrgb.app.workflow.delivery.previous_request import previous_request

    if settings is None or ppi is None:             # what is not asked for now: as the last delivery asked
        record = (session.settings.get("originals") or {}).get(original.identifier) or {}
        before = previous_request(session.path, record, resolution)
        if before is not None:
            settings, ppi = settings or before.settings, ppi or before.ppi
            log.info("%s: delivered again %s", original.identifier, before.said())
    prepare(Path(out_dir), original)
    light_frames = select_lights(frames.subject(subject), [nl.name for nl in profile.lights])
    for refs in light_frames.values():
        for ref in refs:
            if ref.label in damaged:
                raise DamagedFramesError(f"{session.path / ref.label}: {damaged[ref.label]}; resume the session to "
                                         "shoot it again", [ref.label])
    with closing(channels_of(profile_processor(profile), light_frames, resolution, cancel)) as source:
        return deliver(source, profile, original, out_dir, camera=profile.camera, ppi=ppi,
                       dose=original_dose(session, subject),
                       exposures={n: sorted(r.exposure_s for r in refs) for n, refs in light_frames.items()},
                       extra={"session": str(session.path), "reprocessed": True, **(extra or {})},
                       warnings=imported_warnings(session.settings), render_illuminant=render_illuminant,
                       overrides=[override] if override else [], cancel=cancel, settings=settings, now=now,
                       captured_at=captured_at(session, light_frames))


def captured_at(session: Any, light_frames: dict) -> datetime | None:
    """When the frames of an original were captured: the first of them (the manifest's captured_at)."""
    labels = {ref.label for refs in light_frames.values() for ref in refs}
    times = sorted(e.captured_at for e in session.entries() if e.file in labels and e.captured_at)
    try:
        return datetime.fromisoformat(times[0]) if times else None
    except ValueError:
        return None


def _known_original(session: Any, known: dict, identifier: str) -> Original:
    """An original as session.json remembers it, validated again (MetadataError naming the original)."""
    try:
        return Original.from_dict(known.get(identifier, {}), identifier=identifier)
    except MetadataError as exc:
        raise MetadataError(f"{session.path / 'session.json'}: original {identifier!r}: {exc.field}",
                            exc.problem) from None


# ---------------------------------------------------------------- the session's calibrations (process, the GUI)
def session_calibrations(session: Any) -> list[Path]:
    """The session's own calibrations, then those its originals were captured with that lie in its folder (oldest
    first): a calibration outside the session folder is never taken from session.json (core.session.paths: in a
    copied session it would be the original session's), it is passed with ``--calibration``."""
    found = sorted((session.path / "calibration").glob("cal-*.json"))
    named = [inside(session.path, o.get("calibration")) for o in _originals(session)]
    return found + [p for p in named if p is not None and p.exists() and p not in found]


def _originals(session: Any) -> list[dict]:
    return [o for o in (session.settings.get("originals") or {}).values() if isinstance(o, dict)]


def _outside(session: Any) -> str:
    """The calibrations the session's originals name outside its folder (for the refusal's advice)."""
    named = sorted({str(o["calibration"]) for o in _originals(session)
                    if o.get("calibration") and inside(session.path, o["calibration"]) is None})
    if not named:
        return ""
    return (f" (its originals were captured with {', '.join(named[:3])}{' ...' if len(named) > 3 else ''}, outside "
            "the session folder: never used from session.json)")


def newest_calibration(session: Any) -> Path:
    """The session's own newest calibration, else the one its latest original was captured with."""
    found = session_calibrations(session)
    if not found:
        raise ValueError(f"{session.path}: no calibration in it or named by its originals{_outside(session)}; pass "
                         "--calibration FILE")
    return found[-1]


def newest_by_mode(session: Any) -> dict[str, CalibrationProfile]:
    """Mode -> the newest calibration of that mode among :func:`session_calibrations` (loaded)."""
    out = {}
    for path in session_calibrations(session):
        profile = load_profile(path, arrays=False)
        out[profile.mode] = path
    if not out:
        raise ValueError(f"{session.path}: no calibration in it or named by its originals{_outside(session)}; pass "
                         "--calibration FILE")
    return {mode: load_profile(path) for mode, path in out.items()}
