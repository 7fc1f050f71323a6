"""The virtual lab camera: a Nikon D610 stand-in that photographs the virtual copy stand under the sphere.

It renders what the real camera would record, with the same simulation the optimiser uses:

* world: what the stand really is (drivers/virtual/world.py; default the nominal model, rendered bit for bit as
  before worlds): the camera's sensitivities (:attr:`VirtualCamera.camera_sensitivities`), the LEDs, the flare;
* light: the sphere emulator's *current* state through ``light()`` (a snapshot with ``.levels`` (10,) emitted
  levels 0..1, ``.peak_shift_nm`` (10,) LED drift (thesis 4.3.2) and ``.light_on``). Each LED's 1 nm spectrum
  (resources/leds/sphere10_relative.csv) is shaped as the world's LED and shifted by its drift
  (drivers/virtual/sphere_light.py), brought to the simulation grid and, by superposition (thesis 3.1.2), mixed
  with the levels through the world's low-level response;
* scene: :class:`drivers.virtual.scene.Scene` (a target, the open gate, the lens cap; ND 2.0 over half the
  target; vignetting; or a uniform field emitting its own light, a monochromator's band: ``field_response``);
  the world's flare adds a fraction of the frame's mean signal to every pixel;
* responses: eq 5.10 per pixel *class* (patch, surround, gap; see scene.py), never per pixel. Per-LED class
  responses are cached per scene and drift, so a new light costs an (n_classes x 10) @ (10,) product;
* sensor: Bayer RGGB, 14-bit, DN = black + gain * t * ISO/100 * response; shot noise on electrons, read noise,
  dark current, a few hot pixels; linear to ~11 000 DN then a soft knee up to the white level 15520 where
  it clips (thesis 4.1); optional exposure-time "bumps" of the mechanical shutter (appendix A);
* file: an uncompressed 16-bit DNG (14-bit data; drivers.virtual.dng, tifffile) that rawpy reads back bit-exact.

``expose()`` takes the light as it is then and lasts the exposure time while the sphere is lit (dose = exposure;
``realtime=True``: unlit too); ``fetch()`` renders and writes the DNG, so the light is off during the "download" as
on the real camera. Every exposure is logged in ``exposure_log`` on the camera's ``clock`` (the virtual lab gives it
the sphere emulator's, so tests can set exposures against the emulator's record of lit periods). Faults for
tests (:meth:`VirtualCamera.inject`): ``latency`` (the exposure starts ``delay_s`` late: shutter lag, a slow
USB), ``hang`` (``expose()`` blocks until the faults are cleared), ``slow_fetch`` (``delay_s``), ``error`` (``expose()``
raises a CameraError). A world's ``camera_timing`` (drivers.virtual.camera_timing) adds a real body's shutter lag
and download time, in real time.

The radiometric scale is calibrated so that the open gate under the full-intensity light (1, 6, 8) of
Table 7.1 reaches ``SensorModel.open_gate_dn`` (~10 500 DN, just under the knee) in its brightest channel
at 1/60 s, ISO 50, f/8, at the centre of the frame.
"""
from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.integrate import trapezoid

from dualrgb.drivers.camera.base import Camera, CameraError, CameraSettings, Exposure, RawCapture
from dualrgb.drivers.virtual.dng import DngInfo, dng_bytes
from dualrgb.drivers.virtual.scene import Scene
from dualrgb.drivers.virtual.sphere_light import SphereLight
from dualrgb.drivers.virtual.world import World, load_world
from dualrgb.simulation.camera_model import led_responses
from dualrgb.simulation.datasets import default_setup, load_camera
from dualrgb.simulation.grid import SpectralGrid, resample

log = logging.getLogger(__name__)

CAMERA_NAME = "dualrgb virtual D610"
IMAGE_QUALITY = "NEF (Raw)"
VIRTUAL_SERIAL = "VD610-000001"
VIRTUAL_LENS = "virtual 60 mm f/2.8 macro"
CAPTURE_TARGETS = ("Internal RAM", "Memory card")
ISO_VALUES = (50, 64, 80, 100, 125, 160, 200, 250, 320, 400, 500, 640, 800, 1000, 1250, 1600, 2000, 2500,
              3200, 4000, 5000, 6400)
APERTURES = (2.8, 3.2, 3.5, 4.0, 4.5, 5.0, 5.6, 6.3, 7.1, 8.0, 9.0, 10.0, 11.0, 13.0, 14.0, 16.0, 18.0, 20.0, 22.0)
# The Nikon third-stop shutter list, as the camera labels it; longer exposures are bulb.
SHUTTER_LABELS = (
    "1/4000", "1/3200", "1/2500", "1/2000", "1/1600", "1/1250", "1/1000", "1/800", "1/640", "1/500", "1/400",
    "1/320", "1/250", "1/200", "1/160", "1/125", "1/100", "1/80", "1/60", "1/50", "1/40", "1/30", "1/25",
    "1/20", "1/15", "1/13", "1/10", "1/8", "1/6", "1/5", "1/4", "1/3", "1/2.5", "1/2", "1/1.6", "1/1.3",
    "1", "1.3", "1.6", "2", "2.5", "3", "4", "5", "6", "8", "10", "13", "15", "20", "25", "30",
)
BULB_ABOVE_S = 30.0
CFA_RGGB = (0, 1, 1, 2)                     # channel index of Bayer positions (0,0), (0,1), (1,0), (1,1)
# Appendix A: the D610's mechanical shutter delivers a few % more / less light at some exposure times.
DEFAULT_BUMPS: dict[float, float] = {1 / 60: +0.03, 1 / 8: -0.02}
REFERENCE_LIGHT = (1, 6, 8)                 # Table 7.1 "full intensity light source 1"
CAMERA_FAULTS = ("latency", "hang", "slow_fetch", "error")


def parse_shutter(label: str) -> float:
    """'1/60' -> 0.01667, '2.5' -> 2.5, '30,0000s' -> 30.0 (localised gphoto2 strings accepted)."""
    num, _, den = label.strip().rstrip("s").replace(",", ".").partition("/")
    return float(num) / float(den) if den else float(num)


SHUTTER_SPEEDS: tuple[float, ...] = tuple(parse_shutter(s) for s in SHUTTER_LABELS)


def _nearest(values: tuple[float, ...], x: float) -> float:
    """Nearest offered value on a log scale (stops), as a photographer would round."""
    return min(values, key=lambda v: abs(math.log(v / x)))


@dataclass
class StaticLight:
    """A fixed sphere state for the ``light`` callable when no emulator runs (benchmarks, patch checks):
    ``VirtualCamera(lambda: state, ...)``; change ``levels`` between captures."""

    levels: np.ndarray
    peak_shift_nm: np.ndarray = field(default_factory=lambda: np.zeros(10))
    light_on: bool = True


@dataclass
class SensorModel:
    """Sensor and readout constants (D610-like: black 600, white 15520, 14-bit; thesis 4.1)."""

    black_level: int = 600
    white_level: int = 15520
    linear_limit_dn: float = 11000.0         # raw DN where the response stops being linear (thesis 4.1)
    knee_softness: float = 1.3               # >1: the knee reaches the white level at a finite signal
    electrons_per_dn_iso100: float = 4.0     # conversion gain; ISO 50 -> 8 e-/DN
    read_noise_dn: float = 2.5
    dark_current_e_per_s: float = 0.3
    hot_pixels: int | None = None         # default: a few (3 + 1 per 2 MP)
    hot_current_e_per_s: tuple[float, float] = (2e3, 2e5)   # log-uniform range of the hot pixels' dark current
    open_gate_dn: float = 10500.0            # raw DN of the open gate, brightest channel, at the reference
    reference_exposure_s: float = 1 / 60
    reference_iso: int = 50
    reference_aperture: float = 8.0
    poisson_below_e: float = 100.0           # exact Poisson below this many electrons, Gaussian limit above

    def knee(self, signal: np.ndarray) -> np.ndarray:
        """In place: DN above black -> DN above black with the soft compressive knee; linear below the limit."""
        lin = self.linear_limit_dn - self.black_level
        a = self.knee_softness * (self.white_level - self.linear_limit_dn)
        over = signal > lin
        if over.any():
            x = signal[over] - lin
            signal[over] = lin + a * (1.0 - np.exp(-x / a))
        return signal


@dataclass(frozen=True)
class ExposureRecord:
    """One exposure on the camera's clock: the shutter open from ``t_open`` to ``t_close``; ``lit``: the sphere
    emitted light while it was open."""

    t_open: float
    t_close: float
    exposure_s: float
    lit: bool


@dataclass(frozen=True)
class _SetTo:
    """What the virtual camera is set to: every field known (a CameraSettings' fields may each be None)."""

    iso: int
    shutter_s: float
    aperture: float
    capture_target: str

    def as_settings(self) -> CameraSettings:
        return CameraSettings(self.iso, self.shutter_s, self.aperture, IMAGE_QUALITY, self.capture_target)


@dataclass
class _Cache:
    scene: Scene | None = None
    drift: tuple[float, ...] | None = None
    per_led: np.ndarray | None = None               # (n_leds, n_classes, 3)
    planes: dict = field(default_factory=dict)          # (py, px) -> uint16 label plane
    profiles: dict = field(default_factory=dict)        # (py, px) -> (vy, vx)
    preview: dict = field(default_factory=dict)         # step -> (labels, vy, vx)
    fractions: np.ndarray | None = None                 # (n_classes,) frame coverage (flare)


class VirtualCamera(Camera):
    """A virtual D610 on the copy stand. ``scene`` is settable (place a target, open the gate, cap the lens)."""

    name = "Virtual D610"
    # its latency allowance: expose() returns as the exposure ends (no shutter lag, no USB), so this is only the
    # margin for a host whose threads are scheduled late under load
    latency_s = 1.0

    def __init__(
        self,
        light: Callable[[], Any],
        scene: Scene | None = None,
        *,
        mode: str = "reflective",
        grid: SpectralGrid | None = None,
        camera_csv: str | Path | None = None,
        leds_csv: str | Path | None = None,
        sensor: SensorModel | None = None,
        seed: int | None = 0,
        bumps: dict[float, float] | None = None,
        bumps_enabled: bool = False,
        iso: int = 50,
        shutter_s: float = 1 / 60,
        aperture: float = 8.0,
        serial: str = VIRTUAL_SERIAL,
        clock: Callable[[], float] = time.monotonic,
        realtime: bool = False,
        world: World | str | None = None,
    ) -> None:
        self._light = light
        self.serial = serial                                     # what a real body reports as serialnumber
        self._clock = clock
        self.realtime = realtime
        self.exposure_log: list[ExposureRecord] = []
        self._faults: dict[str, dict[str, Any]] = {}
        self._released = threading.Event()
        self.mode = mode
        setup = default_setup(mode, grid)                       # grid None: the mode's default grid
        self.grid = setup.grid
        self.world = load_world(world)
        # (n_wl, 3) on the grid: what every frame is rendered with (the world's camera, or ``camera_csv``)
        self.camera_sensitivities = load_camera(camera_csv or self.world.camera_path, self.grid)
        self.sphere_light = SphereLight(self.world, leds_csv)   # the world's LEDs (shape, output, low end)
        self.sensor = sensor or SensorModel()
        self.bumps = dict(DEFAULT_BUMPS if bumps is None else bumps)
        self.bumps_enabled = bumps_enabled
        self.seed = seed
        noise_seq, sensor_seq = np.random.SeedSequence(seed).spawn(2)
        self._rng = np.random.default_rng(noise_seq)
        self._sensor_seq = sensor_seq                            # hot pixels: a property of this sensor
        self._scene = scene if scene is not None else Scene.with_target(setup.test)
        self._cache = _Cache()
        self._settings = _SetTo(iso=int(_nearest(ISO_VALUES, iso)), shutter_s=_nearest(SHUTTER_SPEEDS, shutter_s),
                                aperture=_nearest(APERTURES, aperture), capture_target=CAPTURE_TARGETS[0])
        self._open = False
        self._counter = 0
        self._scale = self._calibrate()
        self._cm = self._color_matrix()

    @property
    def n_leds(self) -> int:
        return self.sphere_light.n_leds

    # --- the copy stand -----------------------------------------------------------------------------------
    @property
    def scene(self) -> Scene:
        return self._scene

    @scene.setter
    def scene(self, scene: Scene) -> None:
        if not isinstance(scene, Scene):
            raise TypeError(f"scene must be a drivers.virtual.scene.Scene, not {type(scene).__name__}")
        self._scene = scene

    # --- Camera interface ---------------------------------------------------------------------------------
    def open(self) -> None:
        self._open = True
        log.info("virtual camera open (%s, seed %s)", self.mode, self.seed)

    def close(self) -> None:
        self._open = False

    @property
    def is_open(self) -> bool:
        return self._open

    def _require_open(self) -> None:
        if not self._open:
            raise CameraError("the virtual camera is not open: call open() (or use it in a with-block) first")

    def settings(self) -> CameraSettings:
        return self._settings.as_settings()

    def apply(self, settings: CameraSettings) -> CameraSettings:
        self._require_open()
        new = self._settings
        if settings.iso is not None:
            new = replace(new, iso=int(_nearest(ISO_VALUES, float(settings.iso))))
        if settings.shutter_s is not None:
            new = replace(new, shutter_s=self._snap_shutter(settings.shutter_s))
        if settings.aperture is not None:
            new = replace(new, aperture=_nearest(APERTURES, float(settings.aperture)))
        if settings.image_quality is not None and settings.image_quality != IMAGE_QUALITY:
            raise CameraError(f"image quality {settings.image_quality!r}: the virtual D610 records "
                              f"{IMAGE_QUALITY!r} only")
        if settings.capture_target is not None:
            if settings.capture_target not in CAPTURE_TARGETS:
                raise CameraError(f"capture target {settings.capture_target!r}: expected one of "
                                  f"{', '.join(CAPTURE_TARGETS)}")
            new = replace(new, capture_target=settings.capture_target)
        self._settings = new
        return self.settings()

    def shutter_speeds(self) -> list[float]:
        return list(SHUTTER_SPEEDS)

    def iso_values(self) -> list[int]:
        return list(ISO_VALUES)

    @staticmethod
    def _snap_shutter(exposure_s: float) -> float:
        t = float(exposure_s)
        if not t > 0 or not math.isfinite(t):
            raise CameraError(f"exposure time {exposure_s!r} s: expected a positive number of seconds")
        if t > BULB_ABOVE_S:
            return t                                            # bulb: timed by the host, taken as given
        return _nearest(SHUTTER_SPEEDS, t)

    def inject(self, fault: str | None, **params: Any) -> None:
        """Start a fault (module docstring), or clear them all with None (which also ends a ``hang``)."""
        if fault is None:
            self._faults.clear()
            self._released.set()
            return
        if fault not in CAMERA_FAULTS:
            raise ValueError(f"unknown camera fault {fault!r}; expected one of {', '.join(CAMERA_FAULTS)} or None")
        if fault == "hang":
            self._released.clear()
        self._faults[fault] = dict(params)
        log.info("virtual camera: inject %s %s", fault, params)

    def expose(self, exposure_s: float | None = None) -> Exposure:
        self._require_open()
        if exposure_s is not None:
            self._settings = replace(self._settings, shutter_s=self._snap_shutter(exposure_s))
        s = self._settings                                       # frozen: the exposure keeps what it was taken with
        t = float(s.shutter_s)
        started = self._clock()
        self.world.camera_timing.lag()                         # a real body's shutter lag (none: nominal)
        if "latency" in self._faults:
            time.sleep(float(self._faults["latency"].get("delay_s", 1.0)))
        if "hang" in self._faults:
            self._released.wait()
        if "error" in self._faults:
            raise CameraError(self._faults["error"].get("message", "capture: the virtual camera failed (injected)"),
                              self._faults["error"].get("code"))
        t_open = self._clock()
        levels, drift = self._levels(self._light())
        snap = StaticLight(levels.copy(), np.array(drift))       # what the sensor saw, frozen
        scene = self._scene.at_exposure()                       # a field's light as it is now, frozen
        lit = bool(np.any(levels > 0)) or (scene.kind == "field" and scene.shown_field.emits())
        if self.realtime or levels.any():                      # the sphere lights the stand: its dose is real
            self._hold(t)
        ended = self._clock()
        self.exposure_log.append(ExposureRecord(t_open, ended, t, lit))
        return Exposure(exposure_s=t, started=started, ended=ended, bulb=t > BULB_ABOVE_S,
                        handle=(snap, s, scene))

    def _hold(self, seconds: float) -> None:
        """The exposure lasts ``seconds`` on the camera's clock: skipped on a skippable clock, else waited."""
        skip = getattr(self._clock, "skip", None)
        skip(seconds) if callable(skip) and not self.realtime else time.sleep(seconds)

    def fetch(self, exposure: Exposure) -> RawCapture:
        self._require_open()
        if "slow_fetch" in self._faults:
            time.sleep(float(self._faults["slow_fetch"].get("delay_s", 1.0)))
        snap, s, scene = exposure.handle
        t = exposure.exposure_s
        t0 = time.perf_counter()
        now_settings, now_scene = self._settings, self._scene
        self._settings, self._scene = s, scene          # render what the exposure saw
        try:
            mosaic, info = self._render(t, snap)
            neutral = self._neutral(snap)
        finally:
            self._settings, self._scene = now_settings, now_scene
        data = dng_bytes(mosaic, DngInfo(exposure_s=t, iso=int(s.iso), aperture=float(s.aperture), serial=self.serial,
                                         black_level=self.sensor.black_level, white_level=self.sensor.white_level,
                                         color_matrix=self._cm, as_shot_neutral=neutral, model=CAMERA_NAME))
        self._counter += 1
        self.world.camera_timing.download(t0)                    # at least the body's download time
        name = f"VIRT_{self._counter:04d}.DNG"
        log.info("virtual capture %s: %s, %.6g s%s, ISO %d, f/%g, %.2f s", name, scene.kind, t,
                 " (bulb)" if t > BULB_ABOVE_S else "", s.iso, s.aperture, time.perf_counter() - t0)
        return RawCapture(data=data, filename=name, exposure_s=t, iso=int(s.iso), aperture=float(s.aperture),
                          camera=CAMERA_NAME, extra=info)

    def frame_shape(self) -> tuple[int, int]:
        return (self._scene.height, self._scene.width)

    def image_area(self) -> str:                # the rendered frame's size (--frame-size)
        return f"{self._scene.width}x{self._scene.height} px"

    def frame_bytes(self) -> int:
        """An uncompressed 16-bit DNG of the current scene's size plus its tags."""
        return 2 * self._scene.width * self._scene.height + 64 * 1024

    def preview(self, max_width: int = 640) -> np.ndarray:
        """Live view: the scene under the current light at the current settings, small, sRGB-ish uint8.

        Rendered per class like a capture (no Bayer sampling, no noise) and scaled like the raw data, so
        an over-exposed setting shows clipped highlights.
        """
        self._require_open()
        sc = self._scene
        step = max(1, int(math.ceil(sc.width / max_width)))
        if step not in self._cache.preview or self._cache.scene is not sc:
            self._sync_scene()
            rows, cols = np.arange(0, sc.height, step), np.arange(0, sc.width, step)
            self._cache.preview[step] = (sc.labels(rows, cols), *sc.vignetting_profiles(rows, cols))
        labels, vy, vx = self._cache.preview[step]
        s = self._settings
        signal = self._expected_dn(float(s.shutter_s), self._light())                       # (n_classes, 3)
        img = signal.astype(np.float32)[labels] * vy[:, None, None] * vx[None, :, None]
        img = self.sensor.knee(img.reshape(-1)).reshape(img.shape)
        span = self.sensor.white_level - self.sensor.black_level
        img = np.clip(img / span, 0.0, 1.0) ** (1 / 2.2)
        return (img * 255 + 0.5).astype(np.uint8)

    def config_summary(self) -> dict[str, object]:
        d: dict[str, object] = {"camera": CAMERA_NAME, "serial": self.serial, "lens": VIRTUAL_LENS,
                                **super().config_summary()}
        d.update(world=self.world.identity, scene=self._scene.describe(), mode=self.mode, grid=self.grid.label(),
                 bumps="on" if self.bumps_enabled else "off", seed=self.seed,
                 sensor=f"{self._scene.width}x{self._scene.height} RGGB 14-bit, black {self.sensor.black_level},"
                        f" white {self.sensor.white_level}")
        return d

    # --- simulation ---------------------------------------------------------------------------------------
    def led_spectra(self, peak_shift_nm: np.ndarray | None = None, *, nominal: bool = False) -> np.ndarray:
        """(n_leds, n_wl) relative LED spectra on the grid as the world's sphere emits them at full output, each
        shifted by its drift (nm, + = redder; drivers.virtual.sphere_light); ``nominal``: the nominal LEDs."""
        light = self.sphere_light
        return resample(light.wavelengths, light.spectra(peak_shift_nm, nominal=nominal).T, self.grid).T

    def _sync_scene(self) -> None:
        if self._cache.scene is not self._scene:
            self._cache = _Cache(scene=self._scene)

    def _per_led(self, drift: tuple[float, ...]) -> np.ndarray:
        """(n_leds, n_classes, 3): eq 5.10 for each LED alone, cached per scene and drift."""
        self._sync_scene()
        if self._cache.per_led is None or self._cache.drift != drift:
            spectra = self._scene.class_spectra(len(self.grid))
            self._cache.per_led = led_responses(self.led_spectra(np.array(drift)), spectra, self.camera_sensitivities)
            self._cache.drift = drift
        return self._cache.per_led

    def _levels(self, snap: Any) -> tuple[np.ndarray, tuple[float, ...]]:
        levels = np.asarray(snap.levels, dtype=float).reshape(-1)
        if levels.shape != (self.n_leds,):
            raise ValueError(f"light snapshot has {levels.size} levels; expected {self.n_leds}")
        if not getattr(snap, "light_on", True):
            levels = np.zeros(self.n_leds)
        shift = getattr(snap, "peak_shift_nm", None)
        drift = tuple(float(v) for v in (np.zeros(self.n_leds) if shift is None else np.asarray(shift, float)))
        return levels, drift

    def class_responses(self, snap: Any = None) -> np.ndarray:
        """Relative eq 5.10 responses (n_classes, 3) of the scene's pixel classes under ``snap`` (default: now)."""
        levels, drift = self._levels(self._light() if snap is None else snap)
        return np.tensordot(self.sphere_light.output(levels), self._per_led(drift), axes=1)

    def simulated_patch_responses(self, snap: Any = None) -> np.ndarray:
        """(n_patches, 3) relative responses of the target's patches (ND applied where it covers them).

        What the optimiser's simulation predicts; compare with measured patch means (thesis Fig 7.4).
        """
        resp = self.class_responses(snap)
        n = self._scene.n_patches
        idx = np.arange(n) + np.where(self._scene.nd_patches(), n + 2, 0)
        return resp[idx]

    def exposure_gain(self, exposure_s: float) -> float:
        """DN per unit relative response at the current ISO / aperture, including any shutter bump."""
        s = self._settings
        t = exposure_s * (1.0 + self.bump(exposure_s))
        return self._scale * t * (s.iso / 100.0) * (self.sensor.reference_aperture / s.aperture) ** 2

    def bump(self, exposure_s: float) -> float:
        """Relative deviation of the delivered exposure at ``exposure_s`` (0 when bumps are off)."""
        if not self.bumps_enabled:
            return 0.0
        for t, dev in self.bumps.items():
            if abs(math.log(exposure_s / t)) < 0.01:
                return float(dev)
        return 0.0

    def _expected_dn(self, exposure_s: float, snap: Any) -> np.ndarray:
        if self._scene.kind == "lens_cap":
            return np.zeros((1, 3))
        if self._scene.kind == "field":         # a uniform field: its mean signal is its signal
            return self.field_response(self._scene)[None, :] * self.exposure_gain(exposure_s) * (1.0 + self.world.flare)
        signal = self.class_responses(snap) * self.exposure_gain(exposure_s)
        if self.world.flare > 0.0:          # veiling glare: a fraction of the frame's mean signal everywhere
            signal = signal + self.world.flare * (self._class_fractions() @ signal)
        return signal

    def _class_fractions(self) -> np.ndarray:
        """(n_classes,) the fraction of the frame each pixel class covers (on a grid of at most ~512 columns;
        vignetting left out), cached per scene: weights of the frame's mean signal for the flare."""
        self._sync_scene()
        if self._cache.fractions is None:
            sc = self._scene
            step = max(1, sc.width // 512)
            labels = sc.labels(np.arange(0, sc.height, step), np.arange(0, sc.width, step))
            counts = np.bincount(labels.ravel(), minlength=sc.n_classes).astype(float)
            self._cache.fractions = counts / counts.sum()
        return self._cache.fractions

    def field_response(self, scene: Scene) -> np.ndarray:
        """(3,) relative response to a uniform field's emission: its spectral radiance integrated (trapezoid, on the
        field's own wavelengths: a narrow band is sampled far finer than the grid) against the sensitivities this
        camera renders with, linearly interpolated from the grid and held at its end values beyond it (as
        ``simulation.grid.resample``), divided by the grid step so a broad field matches the grid's sums."""
        wl, radiance = scene.shown_field.emission()
        wl, radiance = np.asarray(wl, dtype=float), np.asarray(radiance, dtype=float)
        if wl.size < 2:
            return np.zeros(3)
        grid = self.grid.wavelengths
        sens = np.stack([np.interp(wl, grid, self.camera_sensitivities[:, c]) for c in range(3)], axis=1)
        return trapezoid(radiance[:, None] * sens, wl, axis=0) / self.grid.step

    def _calibrate(self) -> float:
        """Radiometric scale: DN per (relative response x s x ISO/100) from the Table 7.1 reference."""
        sn = self.sensor
        levels = np.zeros(self.n_leds)
        levels[[n - 1 for n in REFERENCE_LIGHT]] = 1.0
        open_gate = np.ones((1, len(self.grid)))           # the body's gain is set under the nominal LEDs
        white = levels @ led_responses(self.led_spectra(nominal=True), open_gate, self.camera_sensitivities)[:, 0]
        return (sn.open_gate_dn - sn.black_level) / (sn.reference_exposure_s * sn.reference_iso / 100.0 * white.max())

    def _hot_pixels(self, height: int, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions and dark currents (e-/s) of the hot pixels: fixed for this sensor and frame size."""
        rng = np.random.default_rng(self._sensor_seq)
        n = self.sensor.hot_pixels if self.sensor.hot_pixels is not None else 3 + (height * width) // 2_000_000
        lo, hi = self.sensor.hot_current_e_per_s
        return (rng.integers(0, height, n), rng.integers(0, width, n),
                np.exp(rng.uniform(math.log(lo), math.log(hi), n)))

    def render_mosaic(self, exposure_s: float | None = None, snap: Any = None) -> np.ndarray:
        """The raw Bayer mosaic (H, W) uint16 a capture would store (advances the noise generator)."""
        t = float(self._settings.shutter_s if exposure_s is None else self._snap_shutter(exposure_s))
        return self._render(t, self._light() if snap is None else snap)[0]

    def _render(self, exposure_s: float, snap: Any) -> tuple[np.ndarray, dict]:
        sc, sn = self._scene, self.sensor
        self._sync_scene()
        signal = self._expected_dn(exposure_s, snap).astype(np.float32)        # (n_classes, 3) DN at centre
        k = sn.electrons_per_dn_iso100 * 100.0 / self._settings.iso             # e- per DN
        dark_e = sn.dark_current_e_per_s * exposure_s
        out = np.empty((sc.height, sc.width), dtype=np.uint16)
        for (py, px), ch in zip(((0, 0), (0, 1), (1, 0), (1, 1)), CFA_RGGB, strict=True):
            if (py, px) not in self._cache.planes:
                rows, cols = np.arange(py, sc.height, 2), np.arange(px, sc.width, 2)
                self._cache.planes[(py, px)] = sc.labels(rows, cols)
                self._cache.profiles[(py, px)] = sc.vignetting_profiles(rows, cols)
            labels = self._cache.planes[(py, px)]
            vy, vx = self._cache.profiles[(py, px)]
            e = signal[:, ch][labels]                                           # per-pixel lookup, DN
            e *= vy[:, None]
            e *= vx[None, :]
            e *= k                                                              # -> expected electrons
            e += dark_e
            self._shot_noise(e)
            e /= k                                                              # -> DN above black
            sn.knee(e)
            e += self._rng.standard_normal(e.shape, dtype=np.float32) * np.float32(sn.read_noise_dn)
            e += sn.black_level
            np.rint(e, out=e)
            np.clip(e, 0, sn.white_level, out=e)
            out[py::2, px::2] = e
        hy, hx, rate = self._hot_pixels(sc.height, sc.width)
        hot = out[hy, hx].astype(np.float64) + self._rng.poisson(rate * exposure_s) / k
        out[hy, hx] = np.clip(np.rint(hot), 0, sn.white_level).astype(np.uint16)
        levels, drift = self._levels(snap)
        info = {"scene": sc.kind, "scene_name": sc.name, "nd_filter": sc.nd_filter,
                "light_levels": [round(float(v), 6) for v in levels],
                "peak_shift_nm": [round(float(v), 4) for v in drift],
                "bulb": exposure_s > BULB_ABOVE_S, "delivered_exposure_s": exposure_s * (1 + self.bump(exposure_s)),
                "bumps": self.bumps_enabled}
        return out, info

    def _shot_noise(self, e: np.ndarray) -> None:
        """In place: expected electrons -> a photon-noise sample.

        numpy's Poisson sampler costs ~70 ns a pixel (~1.6 s for 24 MP), so above ``poisson_below_e`` electrons,
        where Poisson and its Gaussian limit N(lam, lam) cannot be told apart, the Gaussian is drawn instead
        (~12 ns); dark frames and deep shadows (the ND half) get the exact Poisson draw.
        """
        small = e < self.sensor.poisson_below_e
        lam_small = np.maximum(e[small], 0) if small.any() else None
        z = self._rng.standard_normal(e.shape, dtype=np.float32)
        sd = np.maximum(e, 0)
        np.sqrt(sd, out=sd)
        z *= sd
        e += z
        if lam_small is not None:
            e[small] = self._rng.poisson(lam_small)

    # --- DNG colour tags ----------------------------------------------------------------------------------
    def _color_matrix(self) -> np.ndarray:
        """XYZ -> camera 3x3 (DNG ColorMatrix1), least squares on the sensitivities vs the CIE 1931 CMFs."""
        cmfs = default_setup(self.mode, self.grid).cmfs
        m, *_ = np.linalg.lstsq(cmfs, self.camera_sensitivities, rcond=None)   # cam ~ cmfs @ m
        cm = m.T
        d65 = default_setup(self.mode, self.grid).illuminant @ cmfs
        return cm / (cm @ (d65 / d65[1])).max()

    def _neutral(self, snap: Any) -> np.ndarray:
        """DNG AsShotNeutral: the camera's response to a white under this light, largest component 1."""
        if self._scene.kind in ("lens_cap", "field"):
            return np.ones(3)
        levels, drift = self._levels(snap)
        white = self.sphere_light.output(levels) @ led_responses(
            self.led_spectra(np.array(drift)), np.ones((1, len(self.grid))), self.camera_sensitivities)[:, 0]
        return white / white.max() if white.max() > 0 else np.ones(3)
