"""The virtual lab's spectral-sensitivity bench (thesis 4.2, Fig 4.3): the monochromator emulator on a real pty, the
Cornerstone driver talking to it through that pty (the code path of the real instrument), and the virtual camera
looking at the monochromator's output diffused by an integrating sphere - a uniform field
(drivers.virtual.scene.FieldLight) whose light is the emulator's band at the moment of each exposure, rendered
through the sensitivities the camera renders everything with (``VirtualCamera.camera_sensitivities``: the
``world``'s camera, drivers.virtual.world; another camera is a world file naming its ``camera_csv``).

    with MonochromatorBench(frame_size=(240, 160)) as bench:
        bench.monochromator.goto(550); bench.monochromator.open_shutter(); raw = bench.camera.capture(0.25)
        bench.spectroradiometer().write_csv("radiance.csv", [380, 390, ...])
        wavelengths, truth = bench.truth()
"""
from __future__ import annotations

import logging
from typing import Any

import numpy as np

from dualrgb.drivers.monochromator.driver import Cornerstone
from dualrgb.drivers.monochromator.manual import ManualMonochromator
from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
from dualrgb.drivers.virtual.monochromator_emulator import MonochromatorEmulator
from dualrgb.drivers.virtual.monochromator_light import MonochromatorOptics
from dualrgb.drivers.virtual.radiometers import VirtualPhotodiode, VirtualSpectroradiometer
from dualrgb.drivers.virtual.scene import FieldLight, Scene
from dualrgb.drivers.virtual.world import World, load_world

log = logging.getLogger(__name__)

# the camera's relative radiance units per W sr-1 m-2 nm-1 of the diffused output: with the default optics the
# brightest band (red, ~600 nm) gives ~13 000 DN/s at ISO 50, f/8, so the sweep's exposures run from ~1/2 s at
# the peaks to the 30 s cap where the camera barely responds
CAMERA_UNITS_PER_RADIANCE = 1.0


class MonochromatorBench:
    """See the module docstring. ``manual=True``: the monochromator is a ManualMonochromator (a person turns the
    emulated instrument's knob: :meth:`MonochromatorEmulator.set_by_hand`), else the Cornerstone driver."""

    def __init__(self, frame_size: tuple[int, int] = (240, 160), seed: int = 0, world: World | str | None = None,
                 optics: MonochromatorOptics | None = None, timeout_s: float = 1.0, manual: bool = False,
                 vignetting: float = 0.04):
        self.width, self.height = (int(frame_size[0]) // 2 * 2, int(frame_size[1]) // 2 * 2)
        self.seed = seed
        self.world = load_world(world)
        self.emulator = MonochromatorEmulator(optics)
        self._timeout = timeout_s
        self._manual = manual
        self._vignetting = vignetting
        self.monochromator: Any = None
        self.camera: VirtualCamera | None = None

    def _emission(self) -> tuple[np.ndarray, np.ndarray]:
        wl, radiance = self.emulator.output()
        return wl, radiance * CAMERA_UNITS_PER_RADIANCE

    def start(self) -> MonochromatorBench:
        port = self.emulator.start()
        if self._manual:
            self.monochromator = ManualMonochromator("virtual Cornerstone 130, set by hand")
        else:
            self.monochromator = Cornerstone(port, timeout=self._timeout).open()
        dark_sphere = StaticLight(np.zeros(10), light_on=False)          # the sphere plays no part here
        field = FieldLight(self._emission, "monochromator output (integrating sphere)")
        self.camera = VirtualCamera(lambda: dark_sphere, Scene.uniform_field(field, self.width, self.height,
                                                                             vignetting=self._vignetting),
                                    world=self.world, seed=self.seed, clock=self.emulator.clock)
        self.camera.open()
        log.info("virtual monochromator bench on %s (%s)", port, "manual" if self._manual else "Cornerstone")
        return self

    def stop(self) -> None:
        try:
            if self.monochromator is not None and not self._manual:
                self.monochromator.close()          # closes the shutter
        finally:
            self.monochromator = None
            if self.camera is not None:
                self.camera.close()
            self.emulator.stop()

    def __enter__(self) -> MonochromatorBench:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def port(self) -> str:
        return self.emulator.port

    def truth(self) -> tuple[np.ndarray, np.ndarray]:
        """(wavelengths nm, (n, 3) sensitivities): what the camera renders with, on its grid."""
        if self.camera is None:
            raise RuntimeError("the bench is not started: call start() (or use it in a with-block) first")
        return self.camera.grid.wavelengths.copy(), np.array(self.camera.camera_sensitivities, dtype=float)

    def spectroradiometer(self, seed: int | None = None) -> VirtualSpectroradiometer:
        """The virtual spectroradiometer at the camera's place, for the emulator's current grating and filter."""
        return VirtualSpectroradiometer(self.emulator.optics, self.emulator.grating_number,
                                        self.emulator.filter_position, seed=self.seed if seed is None else seed)

    def photodiode(self, seed: int | None = None) -> VirtualPhotodiode:
        return VirtualPhotodiode(self.emulator.optics, self.emulator.grating_number, self.emulator.filter_position,
                                 seed=self.seed if seed is None else seed)
