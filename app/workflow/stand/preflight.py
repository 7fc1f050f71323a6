"""Known before the light, said before the light: the checks of a calibration or a capture that depend only on
their inputs, run before any device acts (the GUI, the CLI and the demo go through app.workflow.stand.copystand, which
calls them).

* :func:`check_lights`: every light of a preset can light a target (some LED above the sphere's smallest step);
* :func:`check_conditioning`: the lights with the camera model give channels the matrix can separate (the
  condition number of the 3L-channel camera values of the training reflectances, simulation.colour_models): above
  :data:`CONDITION_LIMIT` refused, above :data:`CONDITION_WARN` warned, naming the lights' LEDs;
* :func:`check_frame_shape`: the camera's frames are the size the calibration was made at;
* :func:`check_exposures`: every exposure a capture may use, with this session's settle time and this camera's
  latency, within the light-on cap (core.light_safety.SafetySettings);
* :func:`check_capture_space`: free space for an original's frames AND its deliverables (the frames in the
  session folder, the deliverables in their folder; one requirement when both are on the same disk).
"""
from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dualrgb.common.atomic_files import require_free_space
from dualrgb.core.light_safety import LightSafetyError, SafetySettings
from dualrgb.core.vocabulary import NamedLight

if TYPE_CHECKING:
    from dualrgb.simulation.stand_model import StandModel

log = logging.getLogger(__name__)

PWM_STEP = 1 / 65535                 # the sphere's smallest level above 0 (16-bit PWM)
# Conditioning of a light set (condition number of its equilibrated camera values on the training reflectances).
# Of the 630 binned light pairs at full level, the best above 1e4 captures a pixel at best as well as the 3-channel
# camera (expected per-pixel test dE00 on the virtual lab's capture: reflective 2.9 against 1.4, film 1.9 against
# 2.0), and above 1e3 nearly all are worse than it (docs/data/study_objectives.json, "conditioning"); the shipped
# presets are at 78-140 (tests/faults/test_fault_conditioning.py checks they pass).
CONDITION_LIMIT = 1.0e4
CONDITION_WARN = 1.0e3
SIDECAR_BYTES = 1 << 20              # the sidecar, ICC profiles, the ENVI header: far less than this


def check_lights(lights: Sequence[NamedLight], what: str) -> None:
    """ValueError (one line) when a light would light nothing: every level below the sphere's smallest step."""
    for nl in lights:
        if max(nl.light.levels, default=0.0) < PWM_STEP / 2:
            raise ValueError(f"{what}: {nl.name} ({nl.light.label()}) has every LED level at 0, so it lights "
                             "nothing and no target could be measured under it; use a preset whose lights are on")


class ConditioningError(ValueError):
    """Lights whose channels the characterisation cannot separate: refused before any light."""


def light_set_conditioning(lights: Sequence[NamedLight], mode: str, stand: StandModel | None = None
                           ) -> tuple[float, list[str]]:
    """(condition number, the channels its weakest combination ties) of ``lights`` with the camera model on the
    mode's training reflectances: the stand model's camera and LEDs when measured, else the nominal ones."""
    import numpy as np

    from dualrgb.simulation.camera_model import channel_names, led_responses, with_flare
    from dualrgb.simulation.colour_models import condition_number, weakest_direction
    from dualrgb.simulation.datasets import default_setup

    setup = stand.setup(mode) if stand is not None else default_setup(mode)
    W = np.stack([nl.light.weights(setup.leds.shape[0]) for nl in lights])
    R = with_flare(led_responses(setup.leds, setup.train.spectra, setup.camera), setup.flare)   # (K, n, 3)
    values = np.einsum("lk,knc->nlc", W, R).reshape(R.shape[1], -1)
    w = np.abs(weakest_direction(values))
    names = channel_names(len(lights))
    return condition_number(values), [names[i] for i in np.flatnonzero(w >= 0.25 * w.max())]


def check_conditioning(lights: Sequence[NamedLight], mode: str, what: str, stand: StandModel | None = None,
                       *, say: bool = True) -> tuple[float, str | None]:
    """ConditioningError (one line, naming the condition number, the limit and each light's LEDs) above
    :data:`CONDITION_LIMIT`; above :data:`CONDITION_WARN` the warning line (logged with ``say``: a pre-check whose
    run checks again passes False, so the line is said once); else (value, None)."""
    if len(lights) < 2:
        return float("nan"), None                # one light: the camera's own 3 channels, nothing to tie
    cond, tied = light_set_conditioning(lights, mode, stand)
    value = "infinite" if cond == float("inf") else f"{cond:.3g}"
    leds = "; ".join(f"{nl.name} LEDs {nl.light.label()}" for nl in lights)
    said = (f"{what}: condition number {value} of the {3 * len(lights)} channels on the {mode} training "
            f"reflectances with the {'measured' if stand is not None and stand.camera_measured else 'nominal'} "
            f"camera ({leds}; nearly tied: {', '.join(tied)})")
    if cond > CONDITION_LIMIT:
        raise ConditioningError(f"{said} is above the limit {CONDITION_LIMIT:g}: the lights give nearly proportional "
                                "channels (one light a dimmed copy of another, or sharing their LEDs), so the "
                                "matrix would amplify the camera's noise into every pixel; refused before any light "
                                "was switched on: choose other lights (dualrgb simulate)")
    if cond > CONDITION_WARN:
        line = (f"{said} is above {CONDITION_WARN:g} (limit {CONDITION_LIMIT:g}): expect per-pixel colour noise; "
                "lights with fewer LEDs in common do better")
        if say:
            log.warning("%s", line)
        return cond, line
    return cond, None


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
