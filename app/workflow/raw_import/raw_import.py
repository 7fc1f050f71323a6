"""Raw files shot by another program (Capture One, digiCamControl, a script) taken through the copy-stand day:
``dualrgb import FOLDER --roles ROLES.csv --session DIR`` and the window's *Import raw files...*.

    roles = read_roles(Path("ROLES.csv"), default_mode="reflective")        # app.workflow.raw_import.import_roles
    plan = plan_import(Path("raw"), roles, ImportSettings("reflective", preset=preset, session=Path("day3")))
    result = run_import(plan, progress=print_progress)                       # copy, calibrate, deliver

:func:`plan_import` checks everything before anything is written (app.workflow.raw_import.import_checks; ImportRefused
lists
one line per problem). :func:`run_import` then takes the path of a captured day: each file is copied into the
session (never moved or changed: its bytes' sha256 checked against the one checked before), recorded in the
manifest under its original name with its sha256, its role, its light and the step id a captured frame of that kind
gets (core.vocabulary), in capture order; the calibration is processed from the imported darks, flats and
targets exactly as ``calibrate`` processes its own (app.workflow.calibration.session_processing), with the patches
where the
grids given place them (or found in the image); every original is delivered as ``capture`` delivers it
(app.workflow.delivery.delivery: deliverables, sidecar with fixity, QA line) and remembered in session.json, so
``dualrgb
process DIR`` delivers it again like any other session's.

Without a preset the lights are unknown: the calibration's lights have no LEDs or levels, the profile's
``unavailable`` section and every sidecar say so, and what needs the light model is not made (the stand model's
fit and prediction, the model-based spectral estimate: the spectral estimator is then fitted to the training
target alone). The light dose of imported frames is unknown too (another program switched the light): the QA line
says so instead of counting zero.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dualrgb.app.processing.hdr import LINEAR_LIMIT_DN
from dualrgb.app.processing.masters import FULL
from dualrgb.app.processing.pipeline import sub_progress
from dualrgb.app.processing.render import DEFAULT_RENDER_ILLUMINANT
from dualrgb.app.workflow.raw_import.import_checks import (
    DOSE_UNKNOWN,
    UNKNOWN_PRESET,
    ImportRefused,
    ImportSettings,
    dark_problems,
    import_lights,
    light_problems,
    lights_known,
    mode_problems,
    read_frames,
    sha256_of,
    shot_problems,
    target_specs,
    unlisted_files,
)
from dualrgb.app.workflow.raw_import.import_roles import RolesTable, roles_from_table
from dualrgb.app.workflow.raw_import.import_session import (
    ImportPlan,
    camera_of,
    copy_frames,
    frame_steps,
    imported_profile,
    open_import_session,
    session_problems,
)
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.core.vocabulary import Role

if TYPE_CHECKING:
    from dualrgb.app.workflow.calibration.profile import CalibrationProfile
    from dualrgb.app.workflow.delivery.delivery import Delivery
    from dualrgb.core.metadata import Original
    from dualrgb.core.session.capture_session import CaptureSession

log = logging.getLogger(__name__)

D610_WHITE_DN = 15520.0             # the D610's white level, where LINEAR_LIMIT_DN was measured (thesis Fig 4.2)
STAND_UNAVAILABLE = ("the lights are unknown (imported without --preset): the stand model's fit and prediction "
                     "need each light's LEDs and levels")
SPECTRAL_MODEL_UNAVAILABLE = ("the lights are unknown (imported without --preset): the model-based spectral estimate "
                              "(Wiener, from the lights' spectra) is not made; the spectral estimator is fitted to the "
                              "training target alone")


@dataclass
class ImportOptions:
    """How the calibration and the deliveries are made (``calibrate`` and ``capture``'s options)."""

    optimise_matrix: bool | None = None        # None: resources/parsimony.json's choice for the mode
    ppi: float | None = None                   # the sensor's sampling (else from --target-width-mm and the grid)
    target_width_mm: float | None = None
    resolution: str = FULL
    render_illuminant: str = DEFAULT_RENDER_ILLUMINANT


@dataclass
class ImportResult:
    session: Path
    profile: CalibrationProfile
    deliveries: list[Delivery]
    copied: int
    kept: int


def plan_import(folder: Path, roles: RolesTable, settings: ImportSettings,
                progress: ProgressCallback | None = None) -> ImportPlan:
    """Read every file and check the whole import (app.workflow.raw_import.import_checks); ImportRefused lists every
    problem,
    one line each, and nothing is written."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ImportRefused([f"{folder}: not a folder of raw files"])
    problems = list(roles.problems)
    if not roles.rows and not problems:
        problems.append(f"{roles.source}: no rows (one row per raw file: file,role,light,identifier)")
    frames, found = read_frames(folder, roles.rows, roles.where, progress)
    problems += found
    shot, notes = shot_problems(frames)
    problems += shot + dark_problems(frames)
    lights = import_lights(settings.preset, [f.row.light for f in frames if f.row.light])
    problems += light_problems(frames, lights, settings.preset, roles.where)
    specs, found = target_specs(settings)
    problems += found + mode_problems(roles, settings.mode)
    plan = ImportPlan(folder, roles, settings, frames, frame_steps(frames, lights), lights, specs, camera_of(frames),
                      notes + roles.notes + unlisted_files(folder, roles.rows))
    if not problems:
        problems += session_problems(plan)
    if problems:
        raise ImportRefused(problems)
    return plan


def plan_table(folder: Path, header: Sequence[str], rows: Sequence[Sequence[str]], settings: ImportSettings,
               progress: ProgressCallback | None = None) -> ImportPlan:
    """:func:`plan_import` of a roles table as the window holds it
    (app.workflow.raw_import.import_roles.roles_from_table)."""
    out_dir = settings.out_dir or (settings.session / "deliverables" if settings.session else None)
    roles = roles_from_table(header, rows, default_mode=settings.mode, out_dir=out_dir)
    return plan_import(folder, roles, settings, progress)


def linear_limit(white_level: float) -> float:
    """The DN up to which the sensor is taken as linear: the D610's measured limit (thesis 4.1.2), in proportion
    to the white level of a camera that is not a D610."""
    return min(LINEAR_LIMIT_DN, round(float(white_level) * LINEAR_LIMIT_DN / D610_WHITE_DN, 1))


def run_import(plan: ImportPlan, options: ImportOptions | None = None, *, progress: ProgressCallback | None = None,
               cancel: CancelToken | None = None) -> ImportResult:
    """Copy, calibrate, deliver (module docstring) into the plan's session; the session is closed on return."""
    options = options or ImportOptions()
    session = open_import_session(plan)
    with closing(session):
        copied, kept = copy_frames(session, plan, sub_progress(progress, 0.0, 0.2), cancel)
        profile = calibrate_imported(session, plan, options, sub_progress(progress, 0.2, 0.6), cancel)
        deliveries = deliver_imported(session, plan, profile, options, sub_progress(progress, 0.6, 1.0), cancel)
    report(progress, 1.0, f"imported {copied} new, {kept} kept; calibration {profile.id}; "
                          f"{len(deliveries)} original{'s' if len(deliveries) != 1 else ''} delivered")
    return ImportResult(session.path, profile, deliveries, copied, kept)


def calibrate_imported(session: CaptureSession, plan: ImportPlan, options: ImportOptions,
                       progress: ProgressCallback | None = None, cancel: CancelToken | None = None
                       ) -> CalibrationProfile:
    """The calibration from the imported darks, flats and targets (the processing ``calibrate`` runs), saved in
    ``<session>/calibration/``."""
    from dualrgb.app.workflow.calibration.session_processing import process_session
    from dualrgb.app.workflow.calibration.targets import reference_white
    from dualrgb.app.workflow.stand.defaults import workflow_defaults

    mode = plan.settings.mode
    optimise = options.optimise_matrix
    if optimise is None:
        optimise = workflow_defaults(mode).optimise_matrix
    white = max(f.meta.white_level for f in plan.frames)
    preset = plan.settings.preset.name if plan.settings.preset is not None else UNKNOWN_PRESET
    result = process_session(session, session.path / "calibration" / "report", plan.specs["train"], plan.specs["test"],
                             lights=[nl.name for nl in plan.lights], optimise=optimise, white_xyz=reference_white(mode),
                             linear_limit=linear_limit(white), title=f"calibration (imported raw files), {preset}",
                             progress=progress, cancel=cancel, mode=mode)
    profile = imported_profile(session, plan, result, ppi_of(plan, options))
    if not lights_known(plan.lights):
        profile.unavailable = {"stand_model": STAND_UNAVAILABLE, "spectral_model": SPECTRAL_MODEL_UNAVAILABLE}
    check(cancel)                 # a cancel during the processing never makes a calibration
    profile.save(session.path / "calibration")
    report(progress, 1.0, f"calibration {profile.id} saved")
    return profile


def ppi_of(plan: ImportPlan, options: ImportOptions) -> float | None:
    """The sensor's sampling: ``--ppi``, else from the test target's width and its grid (as ``calibrate``)."""
    if options.ppi:
        return float(options.ppi)
    grid = plan.specs["test"].grid
    if not options.target_width_mm or grid is None:
        return None
    tl, tr = np.asarray(grid.corners[0]), np.asarray(grid.corners[1])
    return round(2.0 * float(np.hypot(*(tr - tl))) / (options.target_width_mm / 25.4), 2)


def deliver_imported(session: CaptureSession, plan: ImportPlan, profile: CalibrationProfile, options: ImportOptions,
                     progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> list[Delivery]:
    """Every original delivered with the calibration, as ``capture`` delivers it, and remembered in session.json."""
    from dualrgb.app.workflow.calibration.session_processing import select_lights, session_frames
    from dualrgb.app.workflow.delivery.delivery import deliver
    from dualrgb.app.workflow.delivery.delivery_folder import prepare
    from dualrgb.app.workflow.stand.copystand import channels_of, original_dose, profile_processor

    out_dir = Path(plan.settings.out_dir or session.path / "deliverables")
    frames = session_frames(session)
    done = []
    originals = plan.originals
    for i, original in enumerate(originals):
        check(cancel)
        prepare(out_dir, original)
        light_frames = select_lights(frames.subject(original.subject), [nl.name for nl in profile.lights])
        dose = original_dose(session, original.subject)
        with closing(channels_of(profile_processor(profile), light_frames, options.resolution, cancel)) as source:
            delivery = deliver(source, profile, original, out_dir, camera=profile.camera, dose=dose, ppi=None,
                               exposures={n: sorted(r.exposure_s for r in refs) for n, refs in light_frames.items()},
                               warnings=[DOSE_UNKNOWN], render_illuminant=options.render_illuminant, cancel=cancel,
                               extra={"session": str(session.path), "take": 1,
                                      "imported": imported_from(plan, original)})
        remember(session, original, delivery, profile)
        done.append(delivery)
        report(progress, (i + 1) / len(originals), delivery.qa.text())
    return done


def imported_from(plan: ImportPlan, original: Original) -> dict:
    """The sidecar's word on where an original's frames came from: the folder, each file's name and sha256."""
    return {"folder": str(plan.folder), "files": [{"file": f.row.file, "sha256": f.sha256} for f in plan.frames
                                                  if f.row.role is Role.ORIGINAL
                                                  and f.row.identifier == original.identifier]}


def remember(session: CaptureSession, original: Original, delivery: Delivery, profile: CalibrationProfile) -> None:
    """The original's metadata in session.json (``dualrgb process`` re-delivers from it), as ``capture`` keeps it."""
    originals = dict(session.settings.get("originals", {}))
    originals[original.identifier] = {**original.to_dict(), "take": 1, "light_dose": delivery.qa.dose.to_dict(),
                                      "sidecar": str(delivery.sidecar), "calibration": str(profile.path or "")}
    session.update_settings(originals=originals)


__all__ = ["DOSE_UNKNOWN", "ImportOptions", "ImportPlan", "ImportRefused", "ImportResult", "ImportSettings",
           "calibrate_imported", "deliver_imported", "linear_limit", "plan_import", "plan_table", "run_import",
           "sha256_of"]
