"""The defaults of the copy-stand day, in one place (Qt-free). The GUI, the CLI (``calibrate``, ``capture``,
``demo`` and the device options) and the demo read them here, so a fresh window starts from the same lights,
exposure plan, frame counts, matrix and folders as ``dualrgb calibrate``:

* **lights** per mode: the packaged preset of the default optimiser (``<mode>_pso``; expected captured error
  0.42 / 0.30 mean ΔE00 reflective, against 0.67 / 0.49 for the full-intensity exhaustive pair);
* **HDR plan**: calibrate the longer exposures HDR originals may need too (as many as the parsimony study found
  worth it), so a dark original can be captured without recalibrating;
* **darks and flats** per exposure: the capture protocol the presets' expected figures assume
  (``simulation.choices``);
* **matrix**: every model the processing delivers (least squares, ΔE00-optimised, root-polynomial 2 and 3) in both
  modes, the calibration's cross-validation choosing (issue 40);
* **folders**: sessions and their deliverables under ``<per-user data folder>/captures`` (``resources.user_path``:
  ``~/.local/share/dualrgb/captures`` on Linux; ``DUALRGB_DATA_DIR`` moves it), never beside the settings file;
* the study-chosen defaults (spectral step, characterisation model, HDR exposures, HDR merge) come from
  ``resources/parsimony.json`` through :func:`study_defaults`, the workflow's one reader of that file.

This module imports nothing heavy: the CLI's parser shows these defaults in its help.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from dualrgb import resources
from dualrgb.core.light_timing import SETTLE_S
from dualrgb.simulation.choices import CALIBRATION_DARK_FRAMES, CALIBRATION_FLAT_FRAMES, MODES

log = logging.getLogger(__name__)

DEFAULT_MODE = MODES[0]                              # reflective: prints and paintings on the stand
# the packaged preset (resources/presets/<name>.json) whose lights a mode uses unless another is chosen
PRESETS = {"reflective": "reflective_pso", "transmissive": "transmissive_pso"}
HDR_AUTO = True                                      # calibrate the HDR bracket's longer exposures too
DARK_FRAMES = CALIBRATION_DARK_FRAMES                # per exposure (the capture protocol, simulation.choices)
FLAT_FRAMES = CALIBRATION_FLAT_FRAMES                # per light and exposure
VIRTUAL_FRAME_SIZE = (600, 400)                      # the virtual lab's frames (the presets' patch sizes assume it)
VIRTUAL_ORIGINALS = {"reflective": "painting", "transmissive": "film"}   # the virtual stand-in per mode
CAPTURES = "captures"                                # under the per-user data folder
# The session definition's workflow of the copy-stand day: `calibrate` and `capture` share it, so a session made
# by `calibrate --session day1` takes that day's originals (`capture --session day1`). Sessions made before issue
# 27 recorded 'calibrate' or 'originals'; either is read as this one (day_workflow).
DAY_WORKFLOW = "copy-stand"
LEGACY_DAY_WORKFLOWS = ("calibrate", "originals")


def day_workflow(stored: object = None) -> str:
    """The workflow a copy-stand run records in a session whose definition says ``stored``: the session's own
    spelling when it is an older name of the same day (so it resumes), else :data:`DAY_WORKFLOW`."""
    return str(stored) if stored in LEGACY_DAY_WORKFLOWS else DAY_WORKFLOW


@dataclass(frozen=True)
class WorkflowDefaults:
    """Every default of the day for one mode (see the module docstring)."""

    mode: str
    preset: str                    # packaged preset name (file stem)
    hdr_auto: bool
    hdr_exposures: int             # most exposures per light an HDR bracket may use
    dark_frames: int
    flat_frames: int
    optimise_matrix: bool
    spectral_grid: tuple[float, float, float]     # start, end, step in nm (simulation.grid.SpectralGrid)
    settle_s: float
    captures: Path
    virtual_original: str

    @property
    def hdr(self) -> str:
        """The CLI's ``--hdr`` value: 'auto' or 'off'."""
        return "auto" if self.hdr_auto else "off"


def check_mode(mode: str | None) -> str:
    """``mode``, or the default mode when None; anything else is one line naming the choices."""
    mode = mode or DEFAULT_MODE
    if mode not in MODES:
        raise ValueError(f"mode {mode!r}: expected {' or '.join(MODES)}")
    return mode


def study_defaults(mode: str | None = None) -> dict:
    """The parsimony study's choices for ``mode`` (``spectral_start_nm`` / ``_end_nm`` / ``_step_nm``,
    ``characterisation_model``, ``hdr_exposures``, ``hdr_merge``): the user's parsimony.json when there is one,
    else the packaged one (simulation.defaults.load_defaults). The workflow reads that file only here."""
    from dualrgb.simulation.defaults import load_defaults

    return load_defaults(check_mode(mode))


def default_preset_name(mode: str | None = None) -> str:
    """The packaged preset a mode's lights come from unless another is chosen (e.g. 'reflective_pso')."""
    return PRESETS[check_mode(mode)]


def default_preset_path(mode: str | None = None) -> Path:
    """The file of :func:`default_preset_name` in the installed package."""
    return resources.path("presets", f"{default_preset_name(mode)}.json")


def captures_dir() -> Path:
    """Where sessions (raw frames, calibrations, deliverables) go unless the technician chose a folder."""
    return resources.user_path(CAPTURES)


def workflow_defaults(mode: str | None = None) -> WorkflowDefaults:
    """The defaults of the day for ``mode`` (default: :data:`DEFAULT_MODE`)."""
    mode = check_mode(mode)
    study = study_defaults(mode)
    return WorkflowDefaults(
        mode=mode, preset=default_preset_name(mode), hdr_auto=HDR_AUTO, hdr_exposures=int(study["hdr_exposures"]),
        dark_frames=DARK_FRAMES, flat_frames=FLAT_FRAMES,
        # every model the processing delivers is a candidate in both modes: the calibration's own 5-fold
        # cross-validation with the one-standard-error rule chooses (issue 40); the parsimony study's
        # characterisation_model is the evidence it was checked with, no longer a restriction
        optimise_matrix=True,
        spectral_grid=(float(study["spectral_start_nm"]), float(study["spectral_end_nm"]),
                       float(study["spectral_step_nm"])),
        settle_s=SETTLE_S, captures=captures_dir(),
        virtual_original=VIRTUAL_ORIGINALS[mode])
