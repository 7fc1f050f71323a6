"""Each preset's expected captured error, as ``dualrgb simulate`` reports it for those lights, so that choosing
lights other than the recommended ones is an informed choice (the GUI shows it beside each preset's name).

The figure is the float64 expected captured mean ΔE00 on the training and test targets of the preset's mode, and
per pixel on the test target (the matrix fitted on the patch means applied to one pixel of each patch)
(simulation.search.evaluate_candidate with simulation.expected_error.ExpectedErrorEvaluator) under the setup
and capture model ``dualrgb simulate`` uses by default: the packaged data on the parsimony study's spectral step
and the virtual lab's capture (simulation.capture_model.CaptureModel.virtual_lab). Every preset is judged by
the same model, whatever its file says it was made with (a preset made with measured CSVs carries figures for
those), so the figures compare. About 20 ms per preset once the setup is loaded (a second or two, once): run
it off the GUI thread; results are cached per process.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from dualrgb.app.workflow.stand.defaults import workflow_defaults

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PresetFigures:
    """Expected captured mean ΔE00 of a preset's lights in its mode."""

    mode: str
    train: float
    test: float
    pixel_test: float | None = None          # per pixel (the matrix on one pixel of each test patch), issue 40

    def text(self) -> str:
        pixel = "" if self.pixel_test is None else f", per pixel {self.pixel_test:.2f}"
        return f"expected ΔE00 {self.train:.2f} / {self.test:.2f}{pixel}"


@lru_cache(maxsize=4)
def _evaluator(mode: str, grid: tuple[float, float, float]) -> Any:
    from dualrgb.simulation.capture_model import CaptureModel
    from dualrgb.simulation.datasets import default_setup
    from dualrgb.simulation.expected_error import ExpectedErrorEvaluator
    from dualrgb.simulation.grid import SpectralGrid

    setup = default_setup(mode, SpectralGrid(*grid))          # the mode's grid, as `dualrgb simulate`
    return ExpectedErrorEvaluator(setup, CaptureModel.virtual_lab(mode))


@lru_cache(maxsize=256)
def _figures(mode: str, grid: tuple[float, float, float], lights: tuple[tuple[tuple[int, ...], tuple[float, ...]], ...]
             ) -> PresetFigures:
    from dualrgb.simulation.lightsource import LightSource
    from dualrgb.simulation.search import Candidate, evaluate_candidate

    cand = Candidate(tuple(LightSource(leds, levels) for leds, levels in lights), 0.0)
    evaluate_candidate(_evaluator(mode, grid), cand)
    pixel = cand.per_pixel["test"]["mean"] if cand.per_pixel else None
    return PresetFigures(mode, float(cand.expected_train_errors.mean), float(cand.expected_test_errors.mean), pixel)


def preset_figures(preset: Any) -> PresetFigures:
    """The expected captured figures of ``preset`` (a simulation.presets.Preset) in its own mode."""
    lights = tuple((tuple(s.leds), tuple(float(v) for v in s.levels)) for s in preset.sources)
    return _figures(preset.mode, workflow_defaults(preset.mode).spectral_grid, lights)


def figures_of(presets: Sequence[Any]) -> list[PresetFigures | None]:
    """:func:`preset_figures` of each preset; None for one that cannot be judged (logged)."""
    out: list[PresetFigures | None] = []
    for p in presets:
        try:
            out.append(preset_figures(p))
        except (ValueError, KeyError) as exc:
            log.warning("preset %s: no expected figures (%s)", getattr(p, "name", p), exc)
            out.append(None)
    return out
