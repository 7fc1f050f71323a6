"""Known before the light, said before the light: the checks of a calibration or a capture that depend only on
their inputs, run before any device acts (the GUI, the CLI and the demo go through app.workflow.copystand, which
calls them).

* :func:`check_lights`: every light of a preset can light a target (some LED above the sphere's smallest step);
* :func:`check_frame_shape`: the camera's frames are the size the calibration was made at;
* :func:`check_exposures`: every exposure a capture may use, with this session's settle time and this camera's
  latency, within the light-on cap (app.workflow.light_safety.SafetySettings);
* :func:`check_capture_space`: free space for an original's frames AND its deliverables (the frames in the
  session folder, the deliverables in their folder; one requirement when both are on the same disk).
"""
from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from dualrgb.app.workflow.light_safety import LightSafetyError, SafetySettings
from dualrgb.app.workflow.vocabulary import NamedLight
from dualrgb.common.atomic_files import require_free_space

log = logging.getLogger(__name__)

PWM_STEP = 1 / 65535                 # the sphere's smallest level above 0 (16-bit PWM)
SIDECAR_BYTES = 1 << 20              # the sidecar, ICC profiles, the ENVI header: far less than this


def check_lights(lights: Sequence[NamedLight], what: str) -> None:
    """ValueError (one line) when a light would light nothing: every level below the sphere's smallest step."""
    for nl in lights:
        if max(nl.light.levels, default=0.0) < PWM_STEP / 2:
            raise ValueError(f"{what}: {nl.name} ({nl.light.label()}) has every LED level at 0, so it lights "
                             "nothing and no target could be measured under it; use a preset whose lights are on")


def check_exposures(safety: SafetySettings, profile: Any) -> None:
    """LightSafetyError naming the calibration and light when an exposure the capture may use (every calibrated
    exposure: metering may ask for any) does not fit the light-on cap with this settle time and camera."""
    for name, times in profile.exposures.items():
        for t in times:
            try:
                safety.check(t)
            except LightSafetyError as exc:
                raise LightSafetyError(f"calibration {profile.id}, {name}: {exc}; refused before anything was lit "
                                       "(a shorter --settle, or calibrate again)") from None


def check_frame_shape(camera: Any, profile: Any) -> None:
    """ValueError (one line) when the camera's frames (Camera.frame_shape, where known before a frame) are not
    the size the calibration's darks and flats were made at."""
    shape = getattr(camera, "frame_shape", None)
    have = shape() if callable(shape) else None
    want = tuple(int(v) for v in profile.raw["shape"])
    if have is not None and tuple(have) != want:
        raise ValueError(f"the camera's frames are {have[1]}x{have[0]} px but calibration {profile.id} was made at "
                         f"{want[1]}x{want[0]} px: set the same image size and area (--frame-size on the virtual "
                         "lab), or calibrate again")


def deliverable_bytes(profile: Any, spectral_bands: int) -> int:
    """The deliverables of one original: 16-bit images at the processed stack's size (half the raw frame each way:
    app.processing.pipeline) - ProPhoto, sRGB, XYZ, the camera channels, and with a spectral estimator the cube
    and its rendering - plus the sidecar."""
    h, w = profile.raw["shape"]
    pixels = (int(h) // 2) * (int(w) // 2)
    samples = 3 + 3 + 3 + len(profile.matrix.channels) + (spectral_bands + 3 if spectral_bands else 0)
    return 2 * pixels * samples + SIDECAR_BYTES


def capture_frames(profile: Any, frames_per_exposure: int, metering_frames: int) -> int:
    """Most raw frames one original may take: metering, then every calibrated exposure of every light."""
    n = 0
    for times in profile.exposures.values():
        n += metering_frames + len(times) * frames_per_exposure
    return n


def check_capture_space(session_path: Path, out_dir: Path, frames_bytes: int, deliverables_bytes: int,
                        what: str) -> None:
    """InsufficientSpaceError (one line) unless the frames fit in the session folder and the deliverables in
    theirs (together, when both folders are on one disk)."""
    out_disk = _existing(out_dir)
    if _device(session_path) == _device(out_disk):
        require_free_space(session_path, frames_bytes + deliverables_bytes,
                           f"{what} (its raw frames and its deliverables)")
        return
    require_free_space(session_path, frames_bytes, f"{what} (its raw frames)")
    require_free_space(out_disk, deliverables_bytes, f"{what} (its deliverables)")


def _existing(path: Path) -> Path:
    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _device(path: Path) -> int:
    return os.stat(_existing(path)).st_dev
