"""Lights re-chosen for one stand: the stand model assembled from a calibration's fit and the stand's measurements,
then the same optimisers and objective as ``dualrgb simulate`` on it (``simulate --stand CAL.json``, the GUI's
"Re-optimise for this stand").

:func:`assemble` is the one place the CLI and the GUI get "the stand model" from: nominal, with the measurements
given (a measured camera CSV, measured LED spectra, the measured minimum stable level; a stand folder from ``dualrgb
measure leds`` gives the last two) replacing the nominal curves, with the calibration's fitted parameters on top. A
calibration fitted from other curves than the measurements given now is refitted from the observations its profile
keeps (simulation.stand_fit: well under a second), so the fitted parameters always belong to the curves used.
"""
from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dualrgb.app.workflow.calibration.profile import CalibrationProfile, ProfileError
from dualrgb.common.progress import CancelToken, ProgressCallback
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.lightsource import LightSource
from dualrgb.simulation.sphere import LevelCurves
from dualrgb.simulation.stand_fit import fit_stand
from dualrgb.simulation.stand_model import StandModel

log = logging.getLogger(__name__)

NOMINAL_CAMERA_NOTE = ("the camera is the nominal one with its curves' shift and width fitted: in the virtual lab's "
                       "mismatched world lights re-optimised on such a model captured worse than the nominal preset "
                       "(docs: explanation/stand-model); measure the camera (`dualrgb measure csrf`) and give its CSV")


@dataclass(frozen=True)
class Measurements:
    """Measured curves that replace the nominal ones (None or empty: nominal)."""

    camera_csv: str | None = None
    leds_csv: str | None = None
    min_stable_level: float | None = None
    level_curves: LevelCurves = ()

    @classmethod
    def of(cls, camera_csv: str | Path | None = None, leds_csv: str | Path | None = None,
           stand_dir: str | Path | None = None, min_level: float | None = None) -> Measurements:
        """From the options: an explicit LED CSV or minimum level wins over the stand folder's; the level curves
        come from the stand folder."""
        curves: LevelCurves = ()
        if stand_dir is not None:
            from dualrgb.app.workflow.calibration.led_stand import load_stand

            stand = load_stand(stand_dir)
            leds_csv = leds_csv or stand.leds_csv
            min_level = stand.min_stable_level if min_level is None else min_level
            curves = stand.level_curves
        return cls(_resolved(camera_csv), _resolved(leds_csv), min_level, curves)


def _resolved(path: str | Path | None) -> str | None:
    return None if path is None else str(Path(path).expanduser().resolve())


def _same_curves(a: StandModel, b: StandModel) -> bool:
    """Whether two models predict the captures from the same curves (camera, LED spectra, LED level curves)."""
    return ((_resolved(a.camera_csv), _resolved(a.leds_csv), a.level_curves)
            == (_resolved(b.camera_csv), _resolved(b.leds_csv), b.level_curves))


def assemble(profile: CalibrationProfile | None, measured: Measurements = Measurements()
             ) -> tuple[StandModel, list[str]]:
    """The stand model (module docstring) and lines for people saying what it is made of. A measurement not given
    is the calibration's own (what its fit started from), else nominal."""
    stored = _stored(profile)
    inherit = stored or StandModel()
    start = StandModel(measured.camera_csv or inherit.camera_csv, measured.leds_csv or inherit.leds_csv,
                       inherit.min_stable_level if measured.min_stable_level is None else measured.min_stable_level,
                       level_curves=measured.level_curves or inherit.level_curves)
    start = dataclasses.replace(start, sources={"camera": start.camera_csv or "nominal",
                                                "leds": start.leds_csv or "nominal",
                                                "level_curves": "measured" if start.level_curves else "proportional"})
    level = start.min_stable_level
    notes = [f"camera {start.camera_csv or 'nominal (Nikon 5100 NPL)'}, LEDs {start.leds_csv or 'nominal'}, "
             f"minimum stable level {level if level is not None else 'nominal'}, level -> output "
             f"{'measured per LED' if start.level_curves else 'proportional'}"]
    if profile is None or stored is None:
        return start, notes
    if _same_curves(stored, start):
        model = dataclasses.replace(stored, min_stable_level=level)
        notes.append(f"fitted parameters of calibration {profile.id}")
    else:
        if profile.stand_observations is None:
            raise ProfileError(f"calibration {profile.id}: its stand observations are missing (its .npz); cannot refit "
                               "the model to the curves given")
        model = fit_stand(profile.stand_observations, start).model
        notes.append(f"refitted to calibration {profile.id}'s captures from the curves given (it was fitted from "
                     f"camera {stored.camera_csv or 'nominal'}, LEDs {stored.leds_csv or 'nominal'})")
    if not model.camera_measured:
        notes.append(f"warning: {NOMINAL_CAMERA_NOTE}")
    return dataclasses.replace(model, sources={**start.sources, "calibration": profile.id}), notes


def measured_start(camera_csv: str | Path | None, stand_dir: str | Path | None) -> StandModel | None:
    """The measured curves a calibration's stand fit starts from (``calibrate --camera-csv / --stand-dir``; None:
    nominal), read and checked now, before any device acts (finite, not negative, every camera channel
    responding: simulation.spectral_io; ValueError naming the file)."""
    if not (camera_csv or stand_dir):
        return None
    start = assemble(None, Measurements.of(camera_csv or None, None, stand_dir or None))[0]
    start.camera_table()
    start.led_table()
    return start


def _stored(profile: CalibrationProfile | None) -> StandModel | None:
    """The calibration's fitted stand model (None without a calibration); ProfileError when it has none."""
    if profile is None:
        return None
    if not profile.stand:
        raise ProfileError(f"calibration {profile.id}: no stand model in it (made before the stand fit, or without "
                           "the targets' spectra); calibrate again")
    return StandModel.from_dict(profile.stand["model"])


def reoptimise(model: StandModel, mode: str, *, method: str | None = None, objective: str | None = None,
               seed: int = 0, top: int = 5, capture: CaptureModel | None = None, grid: Any = None,
               targets: dict | None = None, progress: ProgressCallback | None = None,
               cancel: CancelToken | None = None, evaluator_factory: Any = None,
               incumbents: Sequence[Sequence[LightSource]] = (), **run_options: Any) -> Any:
    """The optimiser (simulation.runner.run: default method and objective as ``dualrgb simulate``) on the stand
    model's setup; returns its RunResult. ``capture`` defaults to the virtual lab's for ``mode``, with the stand's
    minimum stable level; ``targets``: default_setup's train_csv / test_csv / reference_xyz; ``evaluator_factory``
    (setup, capture) -> an evaluator to use (the GUI's live plot); ``incumbents``: the lights in use (the
    calibration's: :func:`calibration_lights`), kept when the search finds nothing better on the stand model."""
    from dualrgb.simulation.defaults import default_grid
    from dualrgb.simulation.runner import DEFAULT_METHOD, DEFAULT_OBJECTIVE, run

    setup = model.setup(mode, grid or default_grid(mode), **(targets or {}))
    cap = model.capture(capture or CaptureModel.virtual_lab(mode))
    evaluator = evaluator_factory(setup, cap) if evaluator_factory is not None else None
    result = run(setup, method or DEFAULT_METHOD, seed=seed, top=top, objective=objective or DEFAULT_OBJECTIVE,
                 capture=cap, progress=progress, cancel=cancel, evaluator=evaluator, incumbents=incumbents,
                 **run_options)
    result.extra["stand"] = {"model": model.to_dict()}
    return result


def calibration_lights(profile: CalibrationProfile) -> tuple[LightSource, ...]:
    """The light set a calibration profile was made with (one light source per named light)."""
    return tuple(nl.light for nl in profile.lights)


def stand_preset(result: Any, model: StandModel, name: str | None = None) -> Any:
    """The best light set of a re-optimisation as a preset that names the stand model it was chosen on."""
    preset = result.preset(name=name)
    preset.model["stand"] = model.to_dict()
    return preset
