"""The robust objective: the expected captured error over an ensemble of plausible worlds.

What the lab does not know exactly: each LED's peak (a few nm) and width (a few %), each camera channel's
position (its measured CSRF off by a few nm) and the target reference (a patch's measured spectrum off by a
gain and a smooth spectral error). A world draws all of these; the camera sees the world's LEDs, sensitivities
and true spectra, while the reference XYZ stay the nominal (measured) ones and the characterisation is fitted
on the world's capture, as in the lab. The robust cost of a light set is the mean (or a quantile) of its
expected captured training error over the worlds (the nominal world first), so a preset is chosen to survive
what the simulation gets wrong, at ``worlds`` times the cost of one evaluation. ``per_pixel``: each world's figure
is that of one pixel of each patch (the fit still on the patch means; simulation.expected_error), as a delivered
master is judged.
"""
from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, replace

import numpy as np

from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.datasets import SimulationSetup, Target
from dualrgb.simulation.expected_error import ExpectedErrorEvaluator

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RobustSettings:
    """The ensemble: ``worlds`` draws (the first is the nominal world) and how the mean is taken."""

    worlds: int = 8
    seed: int = 2024
    led_peak_sd_nm: float = 2.0
    led_width_sd: float = 0.03           # relative
    camera_shift_sd_nm: float = 2.0
    reference_gain_sd: float = 0.01
    reference_spectral_sd: float = 0.01
    quantile: float | None = None     # None: the mean over worlds; else this quantile (e.g. 0.9)

    def to_dict(self) -> dict:
        return asdict(self)


def _shift_stretch(wl: np.ndarray, values: np.ndarray, shift: float, stretch: float = 1.0) -> np.ndarray:
    """values(lambda) moved by ``shift`` nm and widened by ``stretch`` about its peak, on the same grid."""
    peak = wl[np.argmax(values)]
    src = peak + (wl - shift - peak) / stretch
    return np.interp(src, wl, values, left=0.0, right=0.0)


def _perturbed_target(target: Target, wl: np.ndarray, rng: np.random.Generator, s: RobustSettings) -> Target:
    n = len(target)
    gain = 1.0 + s.reference_gain_sd * rng.standard_normal((n, 1))
    knots = np.linspace(wl[0], wl[-1], 6)
    smooth = np.stack([np.interp(wl, knots, rng.standard_normal(6)) for _ in range(n)]) * s.reference_spectral_sd
    return replace(target, spectra=np.clip(target.spectra * gain * (1.0 + smooth), 0.0, None))


def plausible_worlds(setup: SimulationSetup, settings: RobustSettings = RobustSettings()) -> list[SimulationSetup]:
    """``settings.worlds`` setups: the nominal one, then random draws of LEDs, camera and true target spectra."""
    rng = np.random.default_rng(settings.seed)
    wl = setup.grid.wavelengths
    worlds = [setup]
    for _ in range(settings.worlds - 1):
        leds = np.stack([_shift_stretch(wl, led, rng.normal(0.0, settings.led_peak_sd_nm),
                                        max(0.5, 1.0 + rng.normal(0.0, settings.led_width_sd)))
                         for led in setup.leds])
        camera = np.stack([np.interp(wl - rng.normal(0.0, settings.camera_shift_sd_nm), wl, setup.camera[:, c],
                                     left=0.0, right=0.0) for c in range(3)], axis=1)
        worlds.append(replace(setup, leds=leds, camera=camera, train=_perturbed_target(setup.train, wl, rng, settings),
                              test=_perturbed_target(setup.test, wl, rng, settings)))
    return worlds


class RobustEvaluator(ExpectedErrorEvaluator):
    """The optimisers' interface over an ensemble: ``cost_indexed`` = mean (or quantile) over the worlds of the
    expected captured training error; reports (noise-free and expected) are the nominal world's."""

    objective = "robust"

    def __init__(self, setup: SimulationSetup, capture: CaptureModel | None = None,
                 settings: RobustSettings = RobustSettings(), *, per_pixel: bool = False) -> None:
        super().__init__(setup, capture, per_pixel=per_pixel)
        self.objective = "robust-per-pixel" if per_pixel else "robust"
        self.settings = settings
        self.worlds = [self] + [ExpectedErrorEvaluator(w, self.capture, reference=setup, per_pixel=per_pixel)
                                for w in plausible_worlds(setup, settings)[1:]]

    def cost_indexed(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        costs = np.stack([super().cost_indexed(idx, w)]
                         + [ev.cost_indexed(idx, w) for ev in self.worlds[1:]])
        self.evaluations += w.shape[0] * (len(self.worlds) - 1)     # one kernel evaluation per world
        if self.settings.quantile is None:
            return costs.mean(axis=0)
        return np.quantile(costs, self.settings.quantile, axis=0)

    def world_costs(self, W: np.ndarray) -> np.ndarray:
        """Float64 expected captured training error of one light set W (L, K) in every world."""
        W = self.model.emitted(np.asarray(W, dtype=float)[None])
        return np.array([ev.model.train_errors(W, pixel=self.per_pixel).mean[0] for ev in self.worlds])

    def for_captured(self) -> RobustEvaluator:
        """This ensemble for lights already captured (ExpectedErrorEvaluator.for_captured), every world's too."""
        twin = super().for_captured()
        assert isinstance(twin, RobustEvaluator)
        twin.worlds = [twin] + [ev.for_captured() for ev in self.worlds[1:]]
        return twin
