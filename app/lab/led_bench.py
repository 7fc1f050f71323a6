"""The LED measurement on the virtual lab (`dualrgb measure leds --virtual-lab`, the window's *Measure the LEDs*,
the stand study): the sequence (app.sequences.led_measurement) run on an in-process lab with the virtual
spectroradiometer on a skippable clock (an hour of warm-up takes moments), its files read back like a real
instrument's and analysed by the production path (app.workflow.led_stand).
"""
from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from dualrgb.app.workflow.led_stand import StandMeasurement, analyse, write_stand

if TYPE_CHECKING:
    from dualrgb.app.sequences.led_measurement import LedMeasurementPlan
    from dualrgb.common.progress import ProgressCallback
    from dualrgb.drivers.virtual.spectroradiometer import RadiometerSettings
    from dualrgb.drivers.virtual.world import World

log = logging.getLogger(__name__)


def measure_virtual(out_dir: str | Path, world: str | Path | World | None = None,
                    plan: LedMeasurementPlan | None = None, radiometer: RadiometerSettings | None = None,
                    seed: int = 0, progress: ProgressCallback | None = None) -> tuple[StandMeasurement, list[Path]]:
    """Run the LED measurement (app.sequences.led_measurement) on the virtual lab in ``world`` with the virtual
    spectroradiometer (``radiometer``: its RadiometerSettings), on a skippable clock (an hour of warm-up takes
    moments), read the instrument's files back like a real instrument's, analyse, and write the stand folder
    ``out_dir`` (instrument files under ``readings/``)."""
    from dualrgb.app.sequences.led_measurement import LedMeasurement
    from dualrgb.app.workflow.engine import RunEngine, StandDevices
    from dualrgb.app.workflow.led_readings import read_readings
    from dualrgb.common.progress import report
    from dualrgb.drivers.virtual.clock import SkippableClock
    from dualrgb.drivers.virtual.lab import VirtualLab
    from dualrgb.drivers.virtual.spectroradiometer import VirtualSpectroradiometer

    out = Path(out_dir)
    clock = SkippableClock()
    with VirtualLab(frame_size=(64, 64), seed=seed, world=world, clock=clock) as lab:
        assert lab.sphere is not None and lab.camera is not None
        instrument = VirtualSpectroradiometer(lab.emulator.snapshot, lab.camera.sphere_light, radiometer, seed,
                                              clock)
        seq = LedMeasurement(out / "readings", clock, plan)
        devices = StandDevices(sphere=lab.sphere, radiometer=instrument, sleep=clock.skip)   # the emulator's clock
        RunEngine(seq.name, devices, progress=progress).run_plan(seq, 0.0, 0.9)   # the one run engine: LEDs off after
        world_doc = lab.world.to_dict()
    readings = read_readings([f for f in seq.files if f.suffix == ".ti3"])
    result = analyse(readings)
    report(progress, 0.95, "analysed; writing the stand folder")
    files = write_stand(result, out, {"instrument": instrument.describe(), "world": world_doc,
                                      "light_mode": seq.settings.light_mode()})
    return result, [*seq.files, *files]
