"""The virtual lab's spectral-sensitivity bench for `dualrgb measure csrf --virtual-lab` and the window's *Measure
the camera*: the monochromator bench (drivers/virtual/monochromator_bench.py: the Cornerstone emulator, the virtual
camera looking at its output) driven by the production measurement (app.workflow.csrf_bench.measure_on_bench),
the radiance measured by the virtual spectroradiometer after the sweep, and the result checked against the curves
the virtual camera renders with.
"""
from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from dualrgb.app.sequences.base import ProgressEvent
from dualrgb.app.sequences.csrf import CsrfSettings
from dualrgb.app.workflow.csrf_bench import CsrfOutcome, measure_on_bench
from dualrgb.common.progress import CancelToken
from dualrgb.simulation.radiance_reference import RadianceReference

if TYPE_CHECKING:
    from dualrgb.drivers.virtual.monochromator_bench import MonochromatorBench

log = logging.getLogger(__name__)

VIRTUAL = "virtual"


@dataclass
class VirtualBench:
    """The virtual bench: the world it renders, its frames, noise seed and the Cornerstone's reply timeout."""

    world: str = "nominal"
    frame_size: tuple[int, int] = (240, 160)
    seed: int = 0
    timeout_s: float = 2.0


@contextlib.contextmanager
def virtual_bench(bench: VirtualBench) -> Iterator[MonochromatorBench]:
    """The started bench (its camera and monochromator), stopped on the way out (the shutter closed)."""
    from dualrgb.drivers.virtual.monochromator_bench import MonochromatorBench

    with MonochromatorBench(frame_size=bench.frame_size, seed=bench.seed, world=bench.world,
                            timeout_s=bench.timeout_s) as started:
        yield started


def measure_on_virtual_bench(bench: MonochromatorBench, settings: CsrfSettings, out: Path, folder: Path | None, *,
                             reference: RadianceReference | None,
                             read_radiance: Callable[[Path], RadianceReference],
                             prompt: Callable[[str], None] | None, on_event: Callable[[ProgressEvent], None] | None,
                             cancel: CancelToken | None = None) -> CsrfOutcome:
    """The measurement on ``bench``; without ``reference`` its spectroradiometer measures the monochromator's output
    after the sweep (``radiance-virtual.csv`` in the session, read back with ``read_radiance`` as a real
    instrument's file). The outcome carries the RMS error against the rendering camera's curves."""
    from dualrgb.app.processing.csrf import rms_error_percent

    camera = bench.camera
    assert camera is not None and bench.monochromator is not None          # made by start()
    where = folder or out.with_name(f"{out.stem}-session")
    written: list[Path] = []

    def measured(wavelengths: list[float]) -> RadianceReference:
        path = bench.spectroradiometer().write_csv(where / "radiance-virtual.csv", wavelengths)
        written.append(path)
        log.info("virtual spectroradiometer: %s", path)
        return read_radiance(path)
    outcome = measure_on_bench(camera, bench.monochromator, settings, out, folder,
                               radiance=reference if reference is not None else measured, prompt=prompt,
                               on_event=on_event, cancel=cancel,
                               definition={"monochromator": VIRTUAL, "world": bench.world.identity})
    if outcome.measurement is not None:
        outcome.rms_percent = rms_error_percent(outcome.measurement.result, *bench.truth())
    outcome.radiance_file = written[0] if written else None
    return outcome
