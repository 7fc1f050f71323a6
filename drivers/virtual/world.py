"""Worlds: what the virtual lab renders, which may differ from the nominal model the simulation predicts with.

Every figure dualrgb predicts comes from a nominal model (the LEDs of thesis Table 4.2, 'Nikon 5100 (NPL)' for the
camera, exact target references). A virtual lab that renders through the same model cannot show that model to be
wrong, so the lab renders a *world*: a JSON file saying how the stand really is.

=======================  ===============================================================================
key                      meaning (default: the nominal model)
=======================  ===============================================================================
``format``               ``"dualrgb-world/1"`` (optional)
``name``                 short name (recorded in sessions and calibration profiles)
``description``          one or two sentences for people
``seed``                 seeds the world's random parts (the reference error); deterministic
``camera_csv``           the camera's spectral sensitivities: a spectral CSV (wavelength_nm, red, green, blue;
                         ``simulation.spectral_io``); a relative path resolves against the JSON's folder, else a
                         packaged name in resources/cameras/ (default ``nikon_5100_npl.csv``)
``led_peak_shift_nm``    10 numbers: each LED's peak moved by this many nm (+ = redder), -20..20
``led_width_scale``      10 numbers: each LED's spectrum stretched about its peak (FWHM x this), 0.5..2
``led_output_scale``     10 numbers: each LED's radiant output x this (ageing, binning), 0..2
``led_low_level``        {``dead_band``, ``knee``, ``exponent``}: how the PWM level maps to output near the
                         bottom (:class:`simulation.sphere.LowLevelResponse`)
``flare``                veiling glare: this fraction of the frame's mean signal added to every pixel, 0..0.2
``reference_error_sd``   relative sd of each target patch's true spectrum against the packaged reference data
                         the calibration uses (a gain per patch, as a spectrophotometer's error), 0..0.2
``chart_pose``           {``rotation_deg``, ``shift_x``, ``shift_y``, ``scale``}: how the charts lie on the stand
                         (drivers.virtual.chart_pose.ChartPose): turned counter-clockwise by -180..180 degrees,
                         moved by -0.5..0.5 of the frame's width (right) and height (down), scaled 0.2..2 about
                         their centre; keys left out keep square, centred, full size
``camera_timing``        ``"d610"`` or {``shutter_lag_s``, ``download_s``}: the camera's shutter lag and USB
                         download, waited in real time (drivers.virtual.camera_timing); default none
=======================  ===============================================================================

Keys left out keep the nominal value; an unknown key or a bad value is a :class:`WorldError` naming the file,
the key and what was expected. The nominal world renders bit for bit what the lab rendered before worlds (save the
ColorChecker Classic, drawn in its real geometry since issue 36: drivers/virtual/scene.py).
Packaged worlds live in resources/worlds/ (``packaged_worlds()``); ``load_world`` takes a packaged name or a
file. The world's LEDs are rendered by :class:`drivers.virtual.sphere_light.SphereLight` (the sphere emulator's
drift stays on top), its camera by the virtual camera (``VirtualCamera.camera_sensitivities``), its flare in the
camera's render, its reference error on the targets the lab places (:meth:`World.true_target`) and its chart pose
on every chart scene the lab places.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import math
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb import resources
from dualrgb.drivers.virtual.camera_timing import CameraTiming, parse_timing
from dualrgb.drivers.virtual.chart_pose import ChartPose
from dualrgb.simulation.datasets import Target, load_camera
from dualrgb.simulation.grid import DEFAULT_GRID, SpectralGrid
from dualrgb.simulation.sphere import LowLevelResponse

log = logging.getLogger(__name__)

WORLD_FORMAT = "dualrgb-world/1"
NOMINAL = "nominal"
N_LEDS = 10
DEFAULT_CAMERA_CSV = "nikon_5100_npl.csv"
MAX_WORLD_BYTES = 1 << 20


class WorldError(ValueError):
    """A world file that cannot be used (one line: file, key, what was expected)."""


def _ones() -> tuple[float, ...]:
    return (1.0,) * N_LEDS


@dataclass(frozen=True)
class World:
    """One world (module docstring). Read the parameters directly (``world.led_peak_shift_nm`` ...), e.g. to
    compare a fitted stand model with the truth; ``camera_path`` is the resolved ``camera_csv``."""

    name: str = NOMINAL
    description: str = "The nominal model: what the simulation predicts with."
    seed: int = 0
    camera_csv: str = DEFAULT_CAMERA_CSV
    camera_path: Path = field(default_factory=lambda: resources.path("cameras", DEFAULT_CAMERA_CSV))
    led_peak_shift_nm: tuple[float, ...] = (0.0,) * N_LEDS
    led_width_scale: tuple[float, ...] = field(default_factory=_ones)
    led_output_scale: tuple[float, ...] = field(default_factory=_ones)
    led_low_level: LowLevelResponse = LowLevelResponse()
    flare: float = 0.0
    reference_error_sd: float = 0.0
    chart_pose: ChartPose = ChartPose()
    camera_timing: CameraTiming = CameraTiming()
    source: str = ""                                  # the file it was read from ('' = built in)

    @property
    def leds_nominal(self) -> bool:
        """True when the LEDs are the nominal ones (no shift, width or output change, ideal low end)."""
        return (not any(self.led_peak_shift_nm) and all(w == 1.0 for w in self.led_width_scale)
                and all(o == 1.0 for o in self.led_output_scale) and self.led_low_level.identity)

    def camera_sensitivities(self, grid: SpectralGrid = DEFAULT_GRID) -> np.ndarray:
        """(n_wl, 3) the world camera's R, G, B sensitivities on ``grid`` (what the virtual camera renders with)."""
        return load_camera(self.camera_path, grid)

    def true_target(self, target: Target) -> Target:
        """The target as it really is in this world: each patch's spectrum times ``1 + reference_error_sd * z``
        (z standard normal, seeded by the world's seed and the target's name); the same object when exact."""
        if self.reference_error_sd <= 0.0:
            return target
        rng = np.random.default_rng([self.seed, zlib.crc32(target.name.encode())])
        gain = 1.0 + self.reference_error_sd * rng.standard_normal(len(target))
        spectra = np.clip(np.asarray(target.spectra, float) * gain[:, None], 0.0, None)
        return dataclasses.replace(target, spectra=spectra, measured=None)

    def to_dict(self) -> dict[str, Any]:
        """The world as its JSON file states it (``camera_csv`` as written; ``chart_pose`` only when the charts are
        not square and centred, so the worlds without one keep their identity)."""
        pose: dict[str, Any] = {} if self.chart_pose.identity else {"chart_pose": self.chart_pose.to_dict()}
        if not self.camera_timing.identity:
            pose["camera_timing"] = self.camera_timing.to_dict()
        return {"format": WORLD_FORMAT, "name": self.name, "description": self.description, "seed": self.seed,
                "camera_csv": self.camera_csv, "led_peak_shift_nm": list(self.led_peak_shift_nm),
                "led_width_scale": list(self.led_width_scale), "led_output_scale": list(self.led_output_scale),
                "led_low_level": self.led_low_level.to_dict(), "flare": self.flare,
                "reference_error_sd": self.reference_error_sd, **pose}

    @cached_property
    def identity(self) -> str:
        """``name (digest)``: the name and a digest of every parameter and of the camera file's bytes, so two
        worlds that render differently never share an identity (sessions and calibration profiles record it)."""
        doc = {k: v for k, v in self.to_dict().items() if k not in ("description", "camera_csv")}
        h = hashlib.sha256(json.dumps(doc, sort_keys=True).encode())
        h.update(self.camera_path.read_bytes())
        return f"{self.name} ({h.hexdigest()[:12]})"


# ---- reading ---------------------------------------------------------------------------------------------
def _fail(source: str, key: str, expected: str, value: Any) -> WorldError:
    shown = json.dumps(value) if not isinstance(value, str) else repr(value)
    if len(shown) > 60:
        shown = shown[:57] + "..."
    return WorldError(f"{source}: key {key!r}: expected {expected}, found {shown}")


def _number(lo: float, hi: float, unit: str = "") -> Callable[[str, str, Any], float]:
    def check(source: str, key: str, value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or not lo <= value <= hi:
            raise _fail(source, key, f"a number from {lo:g} to {hi:g}{unit}", value)
        return float(value)
    return check


def _per_led(lo: float, hi: float, unit: str = "") -> Callable[[str, str, Any], tuple[float, ...]]:
    one = _number(lo, hi, unit)

    def check(source: str, key: str, value: Any) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != N_LEDS:
            raise _fail(source, key, f"a list of {N_LEDS} numbers (LED 1 first) from {lo:g} to {hi:g}{unit}", value)
        return tuple(one(source, f"{key}[{i}]", v) for i, v in enumerate(value))
    return check


def _text(max_len: int) -> Callable[[str, str, Any], str]:
    def check(source: str, key: str, value: Any) -> str:
        if not isinstance(value, str) or not value.strip() or len(value) > max_len or not value.isprintable():
            raise _fail(source, key, f"a non-empty line of text (at most {max_len} characters)", value)
        return value.strip()
    return check


def _seed(source: str, key: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 2**32:
        raise _fail(source, key, "a whole number from 0 to 4294967295", value)
    return value


def _format(source: str, key: str, value: Any) -> str:
    if value != WORLD_FORMAT:
        raise _fail(source, key, repr(WORLD_FORMAT), value)
    return value


_LOW_LEVEL = {"dead_band": _number(0.0, 0.2, " (level)"), "knee": _number(0.0, 0.5, " (level)"),
              "exponent": _number(0.2, 5.0)}


def _low_level(source: str, key: str, value: Any) -> LowLevelResponse:
    if not isinstance(value, dict):
        raise _fail(source, key, "an object with dead_band, knee, exponent", value)
    for k in value:
        if k not in _LOW_LEVEL:
            raise WorldError(f"{source}: unknown key '{key}.{k}'; expected one of {', '.join(_LOW_LEVEL)}")
    parsed = {k: _LOW_LEVEL[k](source, f"{key}.{k}", v) for k, v in value.items()}
    resp = LowLevelResponse(**parsed)
    if resp.knee and resp.knee <= resp.dead_band:
        raise _fail(source, f"{key}.knee", f"a level above dead_band {resp.dead_band:g} (or 0)", resp.knee)
    return resp


_POSE = {"rotation_deg": _number(-180.0, 180.0, " degrees"), "shift_x": _number(-0.5, 0.5, " of the frame's width"),
         "shift_y": _number(-0.5, 0.5, " of the frame's height"), "scale": _number(0.2, 2.0)}


def _chart_pose(source: str, key: str, value: Any) -> ChartPose:
    if not isinstance(value, dict):
        raise _fail(source, key, "an object with rotation_deg, shift_x, shift_y, scale", value)
    for k in value:
        if k not in _POSE:
            raise WorldError(f"{source}: unknown key '{key}.{k}'; expected one of {', '.join(_POSE)}")
    return ChartPose(**{k: _POSE[k](source, f"{key}.{k}", v) for k, v in value.items()})


def _timing(source: str, key: str, value: Any) -> CameraTiming:
    try:
        return parse_timing(source, key, value)
    except ValueError as exc:
        raise WorldError(str(exc)) from None


_KEYS: dict[str, Callable[[str, str, Any], Any]] = {
    "format": _format, "name": _text(64), "description": _text(1000), "seed": _seed, "camera_csv": _text(300),
    "led_peak_shift_nm": _per_led(-20.0, 20.0, " nm"), "led_width_scale": _per_led(0.5, 2.0),
    "led_output_scale": _per_led(0.0, 2.0), "led_low_level": _low_level, "flare": _number(0.0, 0.2),
    "reference_error_sd": _number(0.0, 0.2), "chart_pose": _chart_pose, "camera_timing": _timing,
}


def _camera_path(source: str, folder: Path | None, name: str) -> Path:
    """A camera CSV named in a world: relative to the world file's folder, else a packaged name."""
    p = Path(name).expanduser()
    candidates = [p] if p.is_absolute() else [*([folder / p] if folder is not None else []),
                                              resources.path("cameras", name)]
    for c in candidates:
        if c.is_file():
            return c
    packaged = ", ".join(sorted(f.name for f in resources.path("cameras").glob("*.csv")))
    raise WorldError(f"{source}: key 'camera_csv': expected a spectral CSV (relative to the world file's folder) or "
                     f"a packaged camera ({packaged}), found {name!r}")


def parse_world(doc: Any, source: str = "<world>", folder: Path | None = None) -> World:
    """A :class:`World` from a decoded JSON object; ``folder`` resolves a relative ``camera_csv``."""
    if not isinstance(doc, dict):
        raise WorldError(f"{source}: expected a JSON object with the world's keys, found {type(doc).__name__}")
    values: dict[str, Any] = {}
    for key, value in doc.items():
        if key not in _KEYS:
            raise WorldError(f"{source}: unknown key {key!r}; expected one of {', '.join(_KEYS)}")
        values[key] = _KEYS[key](source, key, value)
    if "name" not in values:
        raise WorldError(f"{source}: key 'name': expected a non-empty line of text, found nothing")
    values.pop("format", None)
    camera = values.get("camera_csv", DEFAULT_CAMERA_CSV)
    world = World(**values, camera_path=_camera_path(source, folder, camera), source=source)
    _check_camera(world)
    return world


def _check_camera(world: World) -> None:
    """The camera CSV must read as three channels covering the simulation grid (one line naming it)."""
    from dualrgb.simulation.spectral_io import SpectralDataError

    try:
        world.camera_sensitivities()
    except SpectralDataError as exc:
        raise WorldError(f"{world.source}: key 'camera_csv': {exc}") from None


def read_world(path: str | Path) -> World:
    """Read and check a world JSON file."""
    from dualrgb.simulation.spectral_io import read_json_file

    path = Path(path)
    doc = read_json_file(path, "world JSON", WorldError, MAX_WORLD_BYTES)
    return parse_world(doc, str(path), path.parent)


def packaged_worlds() -> list[str]:
    """Names of the packaged worlds (resources/worlds/*.json), nominal first."""
    return resources.world_names()


def load_world(spec: str | Path | World | None = None) -> World:
    """A world by packaged name (``nominal``, ``mismatched-d700`` ...) or file path; None: the built-in nominal
    world (the packaged ``nominal`` has the same parameters and identity)."""
    if isinstance(spec, World):
        return spec
    if spec is None:
        return World()
    text = str(spec)
    path = Path(text).expanduser()
    if text.endswith(".json") or path.is_file() or len(path.parts) > 1:
        return read_world(path)
    packaged = resources.path("worlds", f"{text}.json")
    if packaged.is_file():
        return read_world(packaged)
    raise WorldError(f"world {text!r}: no such file and not a packaged world (expected a JSON file or one of "
                     f"{', '.join(packaged_worlds())})")

