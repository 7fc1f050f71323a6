"""The stand model: what the simulation predicts with for one copy stand - the nominal model, with measurements
and fitted parameters where they exist (the one place that assembles it).

Layers, each replacing the one before where given:

* nominal: the LEDs of thesis Table 4.2 (resources/leds/sphere10_relative.csv, 1 nm), 'Nikon 5100 (NPL)' for the
  camera, an ideal LED driver with the assumed 1 % minimum stable level (:class:`simulation.sphere.SphereProperties`);
* measurements: a measured camera CSV (``dualrgb measure csrf``), measured LED spectra (``dualrgb measure leds``:
  the stand folder's leds.csv), the measured minimum stable level and each LED's measured level -> output curve
  (its stand.json): :meth:`StandModel.sphere` is the sphere's one level model (simulation.sphere) that the fit,
  the calibration's prediction and the optimiser all use;
* fitted parameters (:class:`StandParameters`, simulation/stand_fit.py from a calibration's captures): per LED an
  output scale and a peak shift (and a width scale a world may set), per camera channel a gain, optionally a
  shift and width of its curve, and the veiling flare.

LED spectra are moved, stretched and scaled by :func:`simulation.led_shapes.shaped_led_spectra` on their own table
(the virtual lab's worlds render with the same function), then resampled to the simulation grid; the camera's
curves likewise (shift and width about each channel's peak), then multiplied by the channel gains. The flare is
carried by the :class:`simulation.datasets.SimulationSetup` (``flare``: the fraction of the frame's mean signal
added to every patch, the frame's mean taken as the target's mean patch), so :meth:`StandModel.setup` drops
straight into the optimisers (simulation.runner) and the expected-captured objective.
"""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb import resources
from dualrgb.simulation.capture_model import CaptureModel
from dualrgb.simulation.choices import N_SPHERE_LEDS
from dualrgb.simulation.datasets import SimulationSetup, check_setup, default_setup
from dualrgb.simulation.grid import DEFAULT_GRID, SpectralGrid, resample
from dualrgb.simulation.led_shapes import shaped_led_spectra
from dualrgb.simulation.spectral_io import SpectralDataError, read_spectral_csv, require_response
from dualrgb.simulation.sphere import LevelCurves, SphereProperties, curves_from_dict, curves_to_dict

log = logging.getLogger(__name__)

NOMINAL_CAMERA = ("cameras", "nikon_5100_npl.csv")
NOMINAL_LEDS = ("leds", "sphere10_relative.csv")


def _ones(n: int) -> tuple[float, ...]:
    return (1.0,) * n


@dataclass(frozen=True)
class StandParameters:
    """How the stand differs from its (nominal or measured) curves; the defaults change nothing."""

    led_output_scale: tuple[float, ...] = field(default_factory=lambda: _ones(N_SPHERE_LEDS))
    led_peak_shift_nm: tuple[float, ...] = (0.0,) * N_SPHERE_LEDS
    led_width_scale: tuple[float, ...] = field(default_factory=lambda: _ones(N_SPHERE_LEDS))
    channel_gain: tuple[float, ...] = (1.0, 1.0, 1.0)
    camera_shift_nm: tuple[float, ...] = (0.0, 0.0, 0.0)
    camera_width_scale: tuple[float, ...] = (1.0, 1.0, 1.0)
    flare: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(self).items()}

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> StandParameters:
        """The parameters a profile stored (keys left out keep their default); ValueError names a bad one."""
        base = cls()
        values: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            if f.name not in doc:
                continue
            v = doc[f.name]
            want = getattr(base, f.name)
            if isinstance(want, tuple):
                if not isinstance(v, list) or len(v) != len(want) or not all(_finite(x) for x in v):
                    raise ValueError(f"stand parameter {f.name!r}: expected {len(want)} numbers, found {v!r}")
                values[f.name] = tuple(float(x) for x in v)
            elif not _finite(v):
                raise ValueError(f"stand parameter {f.name!r}: expected a number, found {v!r}")
            else:
                values[f.name] = float(v)
        return cls(**values)


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


def _table(path: str, what: str) -> tuple[np.ndarray, np.ndarray]:
    """(wavelengths, (n, n_wl)) of a spectral CSV, read once per file version (a re-measured file is read again)."""
    try:
        stamp = Path(path).stat().st_mtime_ns
    except OSError:
        stamp = 0                        # read_spectral_csv names the missing file
    return _read_table(path, what, stamp)


@lru_cache(maxsize=16)
def _read_table(path: str, what: str, stamp: int) -> tuple[np.ndarray, np.ndarray]:
    table = read_spectral_csv(path)
    values = table.values.T.copy()
    if what == "camera":
        values = values[:3]
        if values.shape[0] != 3:
            raise SpectralDataError(f"{table.source}: a camera CSV needs red, green and blue columns")
        require_response(table, 3, "camera channel")
    return table.wavelengths.copy(), values


@dataclass(frozen=True)
class StandModel:
    """The stand's model (module docstring): ``camera_csv`` / ``leds_csv`` measured files (None: nominal),
    ``min_stable_level`` measured (None: the sphere default), ``level_curves`` each LED's measured level ->
    output curve (empty: proportional), ``params`` fitted; ``sources`` says where each part came from, for
    people."""

    camera_csv: str | None = None
    leds_csv: str | None = None
    min_stable_level: float | None = None
    params: StandParameters = field(default_factory=StandParameters)
    sources: dict[str, str] = field(default_factory=dict)
    level_curves: LevelCurves = ()

    @property
    def camera_measured(self) -> bool:
        return self.camera_csv is not None

    def led_table(self) -> tuple[np.ndarray, np.ndarray]:
        """(wavelengths, (n_leds, n_wl)) the LED spectra at full output before any fitted change."""
        return _table(self.leds_csv or str(resources.path(*NOMINAL_LEDS)), "leds")

    def camera_table(self) -> tuple[np.ndarray, np.ndarray]:
        """(wavelengths, (3, n_wl)) the camera's R, G, B curves before any fitted change."""
        return _table(self.camera_csv or str(resources.path(*NOMINAL_CAMERA)), "camera")

    def leds(self, grid: SpectralGrid = DEFAULT_GRID, *, unperturbed: bool = False) -> np.ndarray:
        """(n_leds, n_wl) the LEDs on ``grid``: shifted, stretched and scaled (``unperturbed``: as tabulated)."""
        wl, table = self.led_table()
        p = self.params
        if not unperturbed:
            table = shaped_led_spectra(wl, table, p.led_peak_shift_nm, p.led_width_scale, p.led_output_scale)
        return resample(wl, table.T, grid).T

    def camera(self, grid: SpectralGrid = DEFAULT_GRID, *, gains: bool = True, unperturbed: bool = False
               ) -> np.ndarray:
        """(n_wl, 3) the camera on ``grid``: each curve shifted and stretched about its peak, times its gain
        (``gains`` False: without; ``unperturbed``: as tabulated)."""
        wl, table = self.camera_table()
        p = self.params
        if not unperturbed:
            table = shaped_led_spectra(wl, table, p.camera_shift_nm, p.camera_width_scale)
        out = resample(wl, table.T, grid)
        return out * np.asarray(p.channel_gain, dtype=float) if gains and not unperturbed else out

    def with_params(self, params: StandParameters) -> StandModel:
        return dataclasses.replace(self, params=params)

    def setup(self, mode: str = "reflective", grid: SpectralGrid | None = None, **targets: Any) -> SimulationSetup:
        """The simulation setup of this stand: the packaged targets, CMFs and D65 of ``mode`` (``targets``:
        default_setup's train_csv / test_csv / reference_xyz), with this model's LEDs, camera and flare, on
        ``grid`` (None: the mode's grid, as the optimiser and the virtual lab use: film's 380-780 nm; a fixed
        410-780 nm here made film predictions miss their captures by 10-12 %)."""
        base = default_setup(mode, grid, **targets)
        grid = base.grid
        setup = dataclasses.replace(base, leds=self.leds(grid), camera=self.camera(grid), flare=self.params.flare,
                                    camera_name=self.describe_camera())
        check_setup(setup)
        return setup

    def sphere(self, base: SphereProperties | None = None) -> SphereProperties:
        """The sphere's level model of this stand: ``base`` (default the nominal sphere) with the measured minimum
        stable level and level curves."""
        return (base or SphereProperties()).measured(self.min_stable_level, self.level_curves)

    def emitted(self, levels: np.ndarray) -> np.ndarray:
        """(..., n_leds) each LED's output relative to its full output at ``levels`` as the sphere set them."""
        return self.sphere().emitted(levels)

    def capture(self, capture: CaptureModel) -> CaptureModel:
        """``capture`` with this stand's measured minimum stable level and level curves (unchanged without)."""
        if self.min_stable_level is None and not self.level_curves:
            return capture
        return dataclasses.replace(capture, sphere=self.sphere(capture.sphere))

    def describe_camera(self) -> str:
        name = Path(self.camera_csv).stem if self.camera_csv else "Nikon 5100 (NPL)"
        return f"{name} (fitted)" if self.params != StandParameters() else name

    def to_dict(self) -> dict[str, Any]:
        return {"camera_csv": self.camera_csv, "leds_csv": self.leds_csv, "min_stable_level": self.min_stable_level,
                "params": self.params.to_dict(), "sources": dict(self.sources),
                **({"level_curves": curves_to_dict(self.level_curves)} if self.level_curves else {})}

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> StandModel:
        level = doc.get("min_stable_level")
        if level is not None and (not _finite(level) or not 0.0 <= level <= 1.0):
            raise ValueError(f"min_stable_level {level!r}: expected a level from 0 to 1")
        return cls(doc.get("camera_csv"), doc.get("leds_csv"), None if level is None else float(level),
                   StandParameters.from_dict(doc.get("params") or {}), dict(doc.get("sources") or {}),
                   curves_from_dict(doc.get("level_curves"), N_SPHERE_LEDS))
