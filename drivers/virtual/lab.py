"""The built-in virtual lab: the sphere emulator on a real pseudo-terminal, the LedSphere driver talking to
it through that pty (the same code path as real hardware), and the virtual camera rendering what lies on
the copy stand under the emulator's current light.

    with VirtualLab(mode="reflective", frame_size=(600, 400)) as lab:
        lab.place("open-gate")
        lab.sphere.apply(light); lab.sphere.on(); raw = lab.camera.capture(1 / 60); lab.sphere.off()
        lab.place("original:painting"); truth = lab.ground_truth_xyz("painting", lab.height, lab.width)
"""
from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dualrgb.drivers.led_sphere import LedSphere
from dualrgb.drivers.virtual.camera import VirtualCamera
from dualrgb.drivers.virtual.originals import ORIGINAL_PREFIX, ORIGINALS, ground_truth_xyz, original_name
from dualrgb.drivers.virtual.scene import Scene, original_scene
from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator
from dualrgb.drivers.virtual.world import World, load_world
from dualrgb.simulation.datasets import Target, default_setup

log = logging.getLogger(__name__)

PLACES = ("train", "test", "open-gate", "lens-cap")


class VirtualLab:
    """The lab; ``world`` (a packaged name, a JSON file or a :class:`World`; default nominal) is what it renders
    (drivers/virtual/world.py); ``clock`` is the emulator's (and camera's) clock, e.g. a
    :class:`drivers.virtual.clock.SkippableClock` for an hour-long warm-up measured in moments."""

    def __init__(self, mode: str = "reflective", frame_size: tuple[int, int] = (600, 400), seed: int = 0,
                 watchdog_s: float = 30.0, bumps: bool = False, timeout_s: float = 1.0,
                 world: World | str | Path | None = None, clock: Callable[[], float] = time.monotonic,
                 transport: str | None = None):
        self.mode = mode
        self.width, self.height = (int(frame_size[0]) // 2 * 2, int(frame_size[1]) // 2 * 2)
        self.seed = seed
        self.world = load_world(world)
        self.setup = default_setup(mode)            # the packaged reference data the calibration uses
        self.emulator = SphereEmulator(watchdog_s=watchdog_s, clock=clock, transport=transport)
        self._timeout = timeout_s
        self._bumps = bumps
        self.sphere: LedSphere | None = None
        self.camera: VirtualCamera | None = None
        self.placed = ""
        self.charts: dict[str, Target] = {}         # a stand's own charts on the stand (use_chart)

    # ---- lifecycle ----
    def start(self, connect: bool = True) -> VirtualLab:
        """Start the emulator and the camera; ``connect``: also open the LedSphere driver on the emulator's port
        (False: the port is left to clients of its own, as `dualrgb lab serve` serves it)."""
        port = self.emulator.start()
        log.info("virtual sphere emulator on %s", port)
        if connect:
            self.sphere = LedSphere(port, timeout=self._timeout).open()
        self.camera = VirtualCamera(self.emulator.snapshot, mode=self.mode, seed=self.seed,
                                    bumps_enabled=self._bumps, clock=self.emulator.clock, world=self.world)
        self.camera.open()
        self.place("open-gate")
        return self

    def stop(self) -> None:
        if self.sphere is not None:
            try:
                self.sphere.close()         # leaves every LED off
            finally:
                self.sphere = None
        if self.camera is not None:
            self.camera.close()
        self.emulator.stop()

    def _started_camera(self) -> VirtualCamera:
        if self.camera is None:
            raise RuntimeError("the virtual lab is not started: call start() (or use it in a with-block) first")
        return self.camera

    def devices(self) -> tuple[VirtualCamera, LedSphere]:
        """The started lab's camera and sphere."""
        if self.camera is None or self.sphere is None:
            raise RuntimeError("the virtual lab is not started: call start() (or use it in a with-block) first")
        return self.camera, self.sphere

    def __enter__(self) -> VirtualLab:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def port(self) -> str:
        return self.emulator.port

    # ---- the copy stand ----
    def target(self, which: str) -> Target:
        """The training or test chart on the stand: the one :meth:`use_chart` put there, else the packaged
        reference data (what the calibration computes with)."""
        if which in self.charts:
            return self.charts[which]
        return {"train": self.setup.train, "test": self.setup.test}[which]

    def use_chart(self, which: str, target: Target | None) -> None:
        """Put a chart of the stand's own on it as the training ('train') or test ('test') target: ``target`` is
        every cell of its layout with its spectra on this lab's grid (simulation.charts.Chart.render_target); the
        world's reference error applies to it as to the packaged ones. None: the packaged target again."""
        if which not in ("train", "test"):
            raise ValueError(f"chart {which!r}: expected 'train' or 'test'")
        if target is None:
            self.charts.pop(which, None)
            return
        if np.asarray(target.spectra).shape[1] != len(self.setup.grid):
            raise ValueError(f"chart {target.name}: {np.asarray(target.spectra).shape[1]} samples, the lab's grid "
                             f"{self.setup.grid.label()} has {len(self.setup.grid)}")
        self.charts[which] = target

    def true_target(self, which: str) -> Target:
        """The target as it lies on the stand in this world (its reference error applied; World.true_target)."""
        return self.world.true_target(self.target(which))

    def place(self, what: str, nd: bool = False) -> Scene:
        """Put the training or test target, the open gate, the lens cap (ND 2.0 over half a target) or an
        original ('original:painting', 'original:film', 'original:shadow'; drivers/virtual/originals.py)."""
        if what not in PLACES and not what.startswith(ORIGINAL_PREFIX):
            raise ValueError(f"cannot place {what!r}: expected one of {', '.join(PLACES)} or "
                             f"{', '.join(ORIGINAL_PREFIX + n for n in ORIGINALS)}")
        size = {"width": self.width, "height": self.height}
        if what.startswith(ORIGINAL_PREFIX):
            scene = original_scene(what, self.width, self.height, mode=self.mode, grid=self.setup.grid, nd_filter=nd)
        elif what == "open-gate":
            scene = Scene.open_gate(**size)
        elif what == "lens-cap":
            scene = Scene.lens_cap(**size)
        else:
            scene = Scene.with_target(self.true_target(what), **size, nd_filter=nd, name=what,
                                      pose=self.world.chart_pose)
        self._started_camera().scene = scene
        self.placed = what + (" + ND" if nd else "")
        return scene

    def scene_for(self, what: str, nd: bool = False) -> Scene:
        """The scene ``place(what, nd)`` would put on the stand (for patch geometry) without placing it."""
        if what in ("train", "test"):
            return Scene.with_target(self.true_target(what), width=self.width, height=self.height, nd_filter=nd,
                                     pose=self.world.chart_pose)
        if what.startswith(ORIGINAL_PREFIX):
            return original_scene(what, self.width, self.height, grid=self.setup.grid, nd_filter=nd)
        return dataclasses.replace(self._started_camera().scene)

    def ground_truth_xyz(self, name: str, height: int | None = None, width: int | None = None) -> np.ndarray:
        """(height, width, 3) float32 per-pixel XYZ of original ``name`` ('painting' or 'original:painting') at
        sensor resolution (default: this lab's frame): eq 4.2, D65, CIE 1931 2 degree, Y of a perfect white
        (clear film) = 100; rows down, columns right as the raw mosaic. Each 2x2 Bayer cell is one material, so
        ``app.lab.ground_truth.bin_to_superpixels`` gives the superpixel grid the processing delivers."""
        return ground_truth_xyz(original_name(name), self.height if height is None else height,
                                self.width if width is None else width, self.setup.grid,
                                self.setup.illuminant, self.setup.cmfs)
