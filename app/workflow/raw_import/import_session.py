"""An import's session: its definition, the step each imported file is recorded under, the copy of the files into
the session, and the calibration profile made from them (app.workflow.raw_import.raw_import runs them in that order).

The session is new, or one this same import made (same definition: mode, preset and lights, camera, sensor,
charts): a resumed import keeps every frame the session already holds (by step id, checked by sha256) and copies
the rest, so an import killed half-way is simply run again.
"""
from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dualrgb.app.workflow.calibration.profile import CalibrationProfile, CameraIdentity, SphereIdentity, new_profile_id
from dualrgb.app.workflow.raw_import.import_checks import (
    UNKNOWN_PRESET,
    ImportFrame,
    ImportSettings,
    lights_known,
)
from dualrgb.app.workflow.raw_import.import_roles import RolesTable
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.core.vocabulary import NamedLight, Role, Subject, step_id

if TYPE_CHECKING:
    from dualrgb.app.workflow.calibration.session_processing import SessionResult
    from dualrgb.app.workflow.calibration.targets import TargetSpec
    from dualrgb.core.metadata import Original
    from dualrgb.core.session.capture_session import CaptureSession

log = logging.getLogger(__name__)

IMPORT_WORKFLOW = "raw import"       # the session definition's workflow (a captured day's is another)


@dataclass
class ImportPlan:
    """A checked import: the frames in capture order, the step each is recorded under, the calibration's lights,
    the targets' specs, the camera; nothing has been written."""

    folder: Path
    roles: RolesTable
    settings: ImportSettings
    frames: list[ImportFrame]
    steps: dict[str, str]                      # file -> step id
    lights: list[NamedLight]
    specs: dict[str, TargetSpec]
    camera: CameraIdentity
    notes: list[str] = field(default_factory=list)

    @property
    def originals(self) -> list[Original]:
        """The originals in the order they were shot."""
        order = list(dict.fromkeys(f.row.identifier for f in self.frames if f.row.role is Role.ORIGINAL))
        return [self.roles.originals[i] for i in order if i in self.roles.originals]

    @property
    def preset_name(self) -> str:
        return self.settings.preset.name if self.settings.preset is not None else UNKNOWN_PRESET


def camera_of(frames: list[ImportFrame]) -> CameraIdentity:
    """The camera the files name (model, serial, ISO, aperture: one for all, checked)."""
    if not frames:
        return CameraIdentity()
    first = frames[0].meta
    return CameraIdentity(first.camera, first.serial, "", int(first.iso) if first.iso else None,
                          float(first.aperture) if first.aperture else None)


def _subject(frame: ImportFrame) -> Subject | None:
    row = frame.row
    if row.role is Role.TARGET:
        return Subject.target(row.identifier)
    return Subject.original(row.identifier) if row.role is Role.ORIGINAL else None


def _light(frame: ImportFrame, lights: list[NamedLight]) -> NamedLight | None:
    return lights[frame.row.light - 1] if frame.row.light is not None and frame.row.light <= len(lights) else None


def frame_steps(frames: list[ImportFrame], lights: list[NamedLight]) -> dict[str, str]:
    """File -> the step id a captured frame of its kind gets (role, subject, light, exposure, frame number in
    capture order), so the processing groups imported frames as it groups captured ones."""
    out: dict[str, str] = {}
    counts: dict[tuple, int] = {}
    for f in frames:
        nl = _light(f, lights)
        key = (f.row.role, _subject(f), nl.name if nl else None, f"{f.exposure_s:.6g}" if f.meta.exposure_s else "")
        i = counts.get(key, 0)
        counts[key] = i + 1
        out[f.row.file] = step_id(f.row.role, subject=_subject(f), light=nl.name if nl else None,
                                  exposure_s=f.exposure_s if f.meta.exposure_s else None, frame=i)
    return out


def import_definition(plan: ImportPlan) -> dict:
    """What defines the import's frames (a resume asking for anything else is refused naming the difference)."""
    from dualrgb.app.workflow.calibration.charts import definition as chart_definition
    from dualrgb.core.session.manifest import light_definition

    c, first = plan.camera, plan.frames[0].meta if plan.frames else None
    lights = ([light_definition(nl.light, nl.name) for nl in plan.lights] if lights_known(plan.lights)
              else [{"name": nl.name, "leds": [], "levels": []} for nl in plan.lights])
    return {"workflow": IMPORT_WORKFLOW, "mode": plan.settings.mode, "preset": plan.preset_name, "lights": lights,
            "camera": {"model": c.model, "serial": c.serial, "iso": c.iso, "aperture": c.aperture},
            **({"image_area": f"{first.width}x{first.height} {first.cfa}"} if first is not None else {}),
            **chart_definition(plan.settings.charts or {})}


def session_problems(plan: ImportPlan) -> list[str]:
    """Why the plan's session folder cannot take the import (new, or a session of this same import whose frames
    are the same files); read only."""
    from dualrgb.common.atomic_files import InsufficientSpaceError, require_free_space
    from dualrgb.core.session.capture_session import SETTINGS, CaptureSession, SessionError
    from dualrgb.core.session.manifest import definition_differences, normalise

    folder = plan.settings.session
    out: list[str] = []
    if folder is None:
        return out
    if folder.exists() and not folder.is_dir():
        return [f"{folder}: exists and is not a folder (the session goes there)"]
    if (folder / SETTINGS).exists():
        try:
            session = CaptureSession.open(folder, readonly=True, clean_temp=False)
        except (SessionError, ValueError) as exc:
            return [str(exc)]
        wanted = normalise(import_definition(plan))
        diffs = definition_differences(session.definition, wanted)
        if diffs:
            return [f"{folder}: a session made otherwise ({diffs[0]}); import into a new --session"]
        for f in plan.frames:
            step = plan.steps[f.row.file]
            if session.has_step(step) and session.entry(step).sha256 != f.sha256:
                out.append(f"{f.path}: the session already holds another file for its step {step} "
                           f"({session.entry(step).camera_filename}); import into a new --session")
    elif folder.is_dir() and any(folder.iterdir()):
        return [f"{folder}: holds files but no session; choose a new or empty --session folder"]
    try:
        existing = next(p for p in (folder, *folder.parents) if p.exists())
        require_free_space(existing, sum(f.size for f in plan.frames), "the imported raw files")
    except (InsufficientSpaceError, StopIteration) as exc:
        out.append(str(exc))
    return out


def open_import_session(plan: ImportPlan) -> CaptureSession:
    """The plan's session: created (or the same import's resumed); a new dated one when the plan names none."""
    from dualrgb.app.workflow.stand.defaults import captures_dir
    from dualrgb.app.workflow.stand.folders import new_session
    from dualrgb.core.session.capture_session import CaptureSession

    meta = {"mode": plan.settings.mode, "imported": {"folder": str(plan.folder), "roles": plan.roles.source}}
    if plan.settings.session is None:
        return new_session(captures_dir(), meta, import_definition(plan))
    return CaptureSession.resume(plan.settings.session, import_definition(plan), meta,
                                 hint="import into a new --session")


def check_copy(frame: ImportFrame) -> bytes:
    """The file's bytes, refused (ValueError naming it) when they are not the ones checked (changed since)."""
    data = frame.path.read_bytes()
    if hashlib.sha256(data).hexdigest() != frame.sha256:
        raise ValueError(f"{frame.path}: changed since it was checked (its sha256 differs); nothing more imported "
                         "(what was copied stays in the session): check the folder and import again")
    return data


def copy_frames(session: CaptureSession, plan: ImportPlan, progress: ProgressCallback | None = None,
                cancel: CancelToken | None = None) -> tuple[int, int]:
    """Each file copied into the session (read, its sha256 checked, written durably, one manifest line under its
    original name), in capture order; a step the session holds already is kept. Returns (copied, kept)."""
    from dualrgb.drivers.camera.base import RawCapture

    copied = kept = 0
    for i, f in enumerate(plan.frames):
        check(cancel)
        step = plan.steps[f.row.file]
        if session.has_step(step):
            kept += 1
            continue
        nl = _light(f, plan.lights)
        subject = _subject(f)
        raw = RawCapture(check_copy(f), f.row.file, f.exposure_s, int(f.meta.iso) if f.meta.iso else None,
                         f.meta.aperture, f.meta.camera)
        meta: dict[str, Any] = {"imported": {"roles_row": f.row.row, "sha256": f.sha256}}
        if nl is not None:
            meta["light_name"] = nl.name
        if subject is not None:
            meta["subject"] = subject.key
        shot = {"serial": f.meta.serial, "format": f.meta.format, "iso": f.meta.iso, "aperture": f.meta.aperture}
        session.record(raw, f.row.role.value, step_id=step, light=nl.light if nl and nl.light.leds else None,
                       captured_at=f.meta.captured_at.isoformat() if f.meta.captured_at else None,
                       settings={k: v for k, v in shot.items() if v}, **meta)
        copied += 1
        report(progress, (i + 1) / len(plan.frames), f"copied {f.row.file}")
    return copied, kept


def imported_profile(session: CaptureSession, plan: ImportPlan, result: SessionResult, ppi: float | None
                     ) -> CalibrationProfile:
    """The calibration profile of an import (as a captured calibration's: app.workflow.stand.copystand), its camera the
    files', its sphere unknown, its exposures per light those of its flats and targets (the targets' shortest
    first: the base)."""
    from dualrgb.app.workflow.stand.copystand import _spectral_fields, _stand_fields
    from dualrgb.core.vocabulary import role_of

    proc = result.processor
    entries = [e for e in session.entries() if role_of(e) in (Role.DARK, Role.FLAT, Role.TARGET)]
    sources = {e.file: e.sha256 for e in entries}
    created = datetime.now(UTC)
    c = result.characterisation
    plan_t, base = exposure_plan(plan)
    first = next(iter(proc._whites.values()))
    return CalibrationProfile(
        id=new_profile_id(created, sources), created_at=created.isoformat(timespec="seconds"),
        mode=plan.settings.mode, camera=plan.camera, sphere=SphereIdentity(), preset=plan.preset_name,
        lights=plan.lights, exposures=plan_t, base_exposures=base, matrix=c.matrix,
        statistics={**c.to_dict(), "report": str(result.files["report"])}, white_xyz=[float(v) for v in c.white],
        sources=sources, ppi=ppi,
        raw={"white_level": proc.white_level, "black_level": proc.black_level, "cfa": proc.cfa,
             "linear_limit": proc.linear_limit, "shape": list(first.white.shape), "ppi_grid": "sensor"},
        targets={"train": result.report.get("train"), "test": result.report.get("test")},
        darks=proc.darks, whites=dict(proc._whites), **_spectral_fields(result), **_stand_fields(result),
        charts={k: spec.chart.record() for k, spec in plan.specs.items() if spec.chart is not None})


def exposure_plan(plan: ImportPlan) -> tuple[dict[str, list[float]], dict[str, float]]:
    """Per light: every exposure of its flats and targets, the base (the targets' shortest) first; and the base."""
    plan_t, base = {}, {}
    for nl in plan.lights:
        mine = [f for f in plan.frames if f.row.role in (Role.FLAT, Role.TARGET) and _light(f, plan.lights) == nl]
        targets = [f.exposure_s for f in mine if f.row.role is Role.TARGET]
        base[nl.name] = min(targets)
        plan_t[nl.name] = [base[nl.name]] + sorted({f.exposure_s for f in mine} - {base[nl.name]})
    return plan_t, base


__all__ = ["IMPORT_WORKFLOW", "ImportPlan", "camera_of", "check_copy", "copy_frames", "exposure_plan",
           "frame_steps", "import_definition", "imported_profile", "open_import_session", "session_problems"]

