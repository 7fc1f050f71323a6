"""A run is accepted before its session is touched: what the CLI (and any front end) checks with the devices open
but before the session's folder, definition, lock or log is written, and the guard that puts the folder back as it
was when a run is refused before its first frame.

    with open_devices(args, mode) as dev:
        check_capture_run(dev.camera, dev.sphere, profile, settings, folder, definition)    # refused: nothing written
        with undone_if_refused(folder):
            with open_session(folder, definition, dev.camera) as session:
                ...

:func:`check_capture_run` answers, read-only, what the stand would refuse before its light: the calibration's
lights and exposures under the light-on cap, the camera's frame size, the reuse checks (camera, sphere,
temperature, age; ``force`` makes them warnings), the session folder's recorded definition against this run's
(camera and image area included) and free space. :func:`check_session_run` is the definition check alone (what
``calibrate`` needs). :func:`undone_if_refused` is the second line: a refusal raised inside the run before any
frame or dose line reached the manifest (a check only the running stand can make) removes what the run created
in the folder and restores the session files it changed, so a refused run leaves the folder as it found it.
"""
from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from dualrgb.app.workflow.calibration.profile import CalibrationProfile, ReuseCheck
    from dualrgb.app.workflow.stand.copystand import StandSettings
    from dualrgb.core.protocols import Sphere
    from dualrgb.drivers.camera.base import Camera

log = logging.getLogger(__name__)

# what opening or making a session writes in its folder (core.session): restored or removed by undone_if_refused
SESSION_FILES = ("session.json", "manifest.jsonl", "session.log", ".session.lock", ".session.holder")
HINT = "use the same options and camera, or another --session"


def check_session_run(folder: Path | None, definition: dict, camera: Camera | None, hint: str = HINT) -> None:
    """DefinitionMismatch (one line, as resuming says it) when ``folder`` holds a session made with another
    definition than this run's ``definition`` with ``camera``'s identity and image area; nothing is written."""
    from dualrgb.app.workflow.stand.defaults import DAY_WORKFLOW, day_workflow
    from dualrgb.app.workflow.stand.folders import is_session, stored_definition
    from dualrgb.app.workflow.stand.stand_devices import camera_definition_of
    from dualrgb.core.session.manifest import DefinitionMismatch, definition_differences, normalise

    if folder is None or not is_session(Path(folder)):
        return
    stored = stored_definition(Path(folder))
    wanted = dict(definition)
    if wanted.get("workflow") == DAY_WORKFLOW:
        wanted["workflow"] = day_workflow(stored.get("workflow"))
    if camera is not None:
        wanted.update(camera_definition_of(camera))
    wanted = normalise(wanted)
    common = [k for k in wanted if k in stored]
    diffs = definition_differences({k: stored[k] for k in common}, {k: wanted[k] for k in common})
    if diffs:
        more = f" (and {len(diffs) - 1} more)" if len(diffs) > 1 else ""
        raise DefinitionMismatch(f"{folder}: the session was made with other settings: {diffs[0]}{more}; {hint}",
                                 diffs)


def check_capture_run(camera: Camera, sphere: Sphere, profile: CalibrationProfile, settings: StandSettings,
                      folder: Path | None, definition: dict, out_dir: Path | None = None,
                      originals: int = 1) -> ReuseCheck:
    """Every check the stand makes before its light for capturing ``originals`` originals with ``profile``, made
    before the session is opened (see the module docstring); returns the reuse check (its warnings)."""
    from dualrgb.app.workflow.calibration.profile import CameraIdentity, SphereIdentity, check_reuse
    from dualrgb.app.workflow.calibration.profile_check import ProfileError
    from dualrgb.app.workflow.stand.copystand import safety_of
    from dualrgb.app.workflow.stand.preflight import check_exposures, check_frame_shape, check_lights
    from dualrgb.core.engine import facts_of

    check_session_run(folder, definition, camera)        # a session resumed at another size says so first
    check_lights(profile.lights, f"calibration {profile.id}")
    check_frame_shape(camera, profile)
    check_exposures(facts_of(camera, safety_of(settings)).safety, profile)
    result = check_reuse(profile, CameraIdentity.of(camera), SphereIdentity.of(sphere), profile.lights,
                         settings.limits)
    if not result.ok and not settings.force:
        raise ProfileError(f"calibration {profile.id} refused: {result.message()} (--force to use it anyway)")
    if folder is not None:
        _check_space(camera, profile, settings, Path(folder), out_dir or Path(folder) / "deliverables", originals)
    return result


def _check_space(camera: Camera, profile: CalibrationProfile, settings: StandSettings, folder: Path,
                 out_dir: Path, originals: int) -> None:
    from dualrgb.app.workflow.stand.defaults import study_defaults
    from dualrgb.app.workflow.stand.preflight import capture_frames, check_capture_space, deliverable_bytes

    frame_bytes = getattr(camera, "frame_bytes", None)
    per_frame = int(frame_bytes()) if callable(frame_bytes) else 0
    frames = capture_frames(profile, settings.original_frames,
                            int(settings.hdr_exposures or study_defaults(profile.mode)["hdr_exposures"]))
    bands = profile.estimator.n_wavelengths if profile.estimator is not None else 0
    check_capture_space(folder, out_dir, originals * frames * per_frame, originals * deliverable_bytes(profile, bands),
                        f"{originals} original{'s' if originals > 1 else ''}")


@contextlib.contextmanager
def undone_if_refused(folder: Path | None, entries: Any = None) -> Iterator[None]:
    """On an error before the run's first frame (the session's manifest and ``session.json`` hold no new frame or
    dose), the session files in ``folder`` are put back as they were and what the run created there is removed
    (only the session's own files and empty folders: anything else is left and logged). ``folder`` None: nothing
    to guard (a new dated session is named by its opening)."""
    if folder is None:
        yield
        return
    folder = Path(folder)
    existed = folder.exists()
    before = _snapshot(folder)
    try:
        yield
    except BaseException:
        if _manifest_bytes(folder) == before.get("manifest.jsonl", b""):
            _restore(folder, before, existed)
        raise


def _snapshot(folder: Path) -> dict[str, bytes | None]:
    out: dict[str, bytes | None] = {}
    for name in SESSION_FILES:
        try:
            out[name] = (folder / name).read_bytes()
        except FileNotFoundError:
            out[name] = None
        except OSError as exc:
            log.debug("%s: %s", folder / name, exc)
    out["//dirs"] = "\n".join(sorted(_dirs(folder))).encode() if folder.is_dir() else None
    return out


def _dirs(folder: Path) -> set[str]:
    return {os.path.relpath(os.path.join(root, d), folder) for root, dirs, _ in os.walk(folder) for d in dirs}


def _manifest_bytes(folder: Path) -> bytes:
    try:
        return (folder / "manifest.jsonl").read_bytes()
    except OSError:
        return b""


def _restore(folder: Path, before: dict[str, bytes | None], existed: bool) -> None:
    """Put the session files back (``before``), remove the folders the run made when empty."""
    for name in SESSION_FILES:
        if name not in before:
            continue
        path, old = folder / name, before[name]
        try:
            if old is None:
                path.unlink(missing_ok=True)
            elif path.read_bytes() != old:
                path.write_bytes(old)
        except OSError as exc:
            log.warning("%s: not restored after the refusal (%s)", path, exc)
    old_dirs = set((before.get("//dirs") or b"").decode().split("\n")) if before.get("//dirs") else set()
    for rel in sorted(_dirs(folder) - old_dirs, key=len, reverse=True) if folder.is_dir() else []:
        with contextlib.suppress(OSError):
            (folder / rel).rmdir()                # only an empty one
    if not existed:
        with contextlib.suppress(OSError):
            folder.rmdir()
    log.info("%s: the refused run's session files removed; the folder is as it was", folder)
