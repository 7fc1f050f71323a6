"""What a capture adds to the simulation: the settings of the expected-captured objective (one home).

* :class:`CameraNoise`: the sensor (D610-like at ISO 50, as the virtual camera in drivers/virtual/camera.py) and
  the capture protocol of the sequences (app/sequences/calibration.py: each light's exposure puts the open
  gate's brightest channel at 80 % of the 11 000 DN linear limit; a master dark of ``dark_frames`` frames;
  a master white of ``flat_frames`` open-gate frames; eq 7.1 flat field), and the patch size in pixels;
* :class:`CaptureModel`: that camera plus the target reference's uncertainty, the LEDs' peak drift within a
  session and the sphere's level grid (:class:`simulation.sphere.SphereProperties`).

The defaults describe the built-in virtual lab at the demo's 600 x 400 frames (patch sizes measured on its
grid: 56 superpixels per training patch in reflective mode, 36 in transmissive mode, 462 per CC24 test patch)
with exact references (the virtual lab's nominal world renders the same spectra the reference XYZ come from; other
worlds, drivers/virtual/world.py, may not). For a real
chart measured with a spectrophotometer set ``reference_gain_sd`` (the stability study: a 1 % gain error costs
~0.15 dE00); for full-size frames set the patch sizes.
"""
from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field, replace

from dualrgb.simulation.choices import CALIBRATION_DARK_FRAMES, CALIBRATION_FLAT_FRAMES
from dualrgb.simulation.sphere import SphereProperties

log = logging.getLogger(__name__)

# superpixels per patch on the demo's 600 x 400 virtual-lab frames (the PatchGrid the demo samples)
DEMO_PATCH_PIXELS = {"reflective": (56, 462), "transmissive": (36, 462)}


@dataclass(frozen=True)
class CameraNoise:
    """Sensor constants (D610-like at ISO 50, as the virtual camera) and the capture protocol."""

    black_level: float = 600.0
    linear_limit: float = 11000.0          # raw DN
    max_code: int = 2**14 - 1              # 14-bit
    target_fraction: float = 0.8           # open gate's brightest channel at 80 % of the linear limit
    read_noise: float = 2.5                # DN rms per pixel
    electrons_per_dn: float = 8.0          # conversion gain at ISO 50 (4 e-/DN at ISO 100)
    dark_current: float = 0.3              # e-/s per pixel
    dark_frames: int = 10                  # frames averaged into the master dark (thesis 7)
    flat_frames: int = 1                   # open-gate frames averaged into the white (thesis 7: one)
    pixels_per_patch: int = 64             # pixels of one colour averaged per patch (small virtual-lab frames)
    min_flat_dn: float = 5.0               # a channel whose open gate is darker than this is not used
    reference_leds: tuple[int, ...] = (1, 6, 8)
    reference_dn: float = 10500.0          # raw DN of the open gate under the reference light ...
    reference_exposure_s: float = 1 / 60   # ... at this exposure (Table 7.1)

    @property
    def headroom(self) -> float:
        """DN above black that the open gate's brightest channel gets."""
        return self.target_fraction * self.linear_limit - self.black_level

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class CaptureModel:
    """Everything the expected-captured objective adds to the noise-free simulation.

    ``camera.pixels_per_patch`` / ``test_pixels_per_patch``: superpixels averaged per training / test patch
    (the G channel averages two pixels per superpixel, R and B one; ``trim_efficiency`` is the Gaussian
    efficiency of the processing's 10 %-trimmed patch mean). ``reference_gain_sd``: relative sd of a patch's
    reference XYZ as a whole (a gain error, as a spectrophotometer's); ``reference_sd``: relative sd of each
    tristimulus value on its own. ``drift_sd_nm``: sd of each LED's peak between the captures of a session
    (thesis 4.3.2: no shift is detectable at 1 nm in the first 10 s on, which is how the sequences use them).
    """

    camera: CameraNoise = field(default_factory=lambda: CameraNoise(pixels_per_patch=56,
                                                                      flat_frames=CALIBRATION_FLAT_FRAMES))
    test_pixels_per_patch: int | None = 462
    green_pixels: int = 2
    trim_efficiency: float = 0.94
    reference_gain_sd: float = 0.0
    reference_sd: float = 0.0
    drift_sd_nm: float = 0.0
    sphere: SphereProperties = field(default_factory=SphereProperties)

    @classmethod
    def virtual_lab(cls, mode: str, **changes) -> CaptureModel:
        """The demo's capture on the virtual lab (600 x 400 frames, 10 darks, 3 flats) for ``mode``."""
        train_px, test_px = DEMO_PATCH_PIXELS.get(mode, DEMO_PATCH_PIXELS["reflective"])
        base = cls(camera=CameraNoise(pixels_per_patch=train_px, flat_frames=CALIBRATION_FLAT_FRAMES,
                                      dark_frames=CALIBRATION_DARK_FRAMES),
                   test_pixels_per_patch=test_px)
        return replace(base, **changes)

    def pixels(self, which: str) -> int:
        if which == "test" and self.test_pixels_per_patch is not None:
            return self.test_pixels_per_patch
        return self.camera.pixels_per_patch

    def label(self) -> str:
        return (f"{self.camera.pixels_per_patch}/{self.pixels('test')} px per train/test patch, read noise "
                f"{self.camera.read_noise:g} DN, reference sd {100 * self.reference_gain_sd:g} % gain + "
                f"{100 * self.reference_sd:g} %, drift {self.drift_sd_nm:g} nm, min level "
                f"{self.sphere.min_stable_level:g}")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["sphere"] = self.sphere.to_dict()
        return d
