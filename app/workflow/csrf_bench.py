"""Where ``dualrgb measure csrf`` and the GUI's *Measure the camera* run: the devices (the virtual lab's
monochromator bench, or a real camera with a Cornerstone on a serial port or a monochromator set by hand), the
session, the radiance reference (a file, or the virtual spectroradiometer after the sweep) and, on the virtual
lab, the check against the curves the virtual camera renders with. The measurement itself is
app.workflow.csrf.measure_csrf; the CLI and the GUI differ only in how they ask the person (``prompt``) and show
progress (``on_event``).
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
from dualrgb.app.workflow.csrf import CsrfMeasurement, measure_csrf
from dualrgb.common.progress import CancelToken
from dualrgb.simulation.radiance_reference import RadianceReference

if TYPE_CHECKING:
    from dualrgb.app.protocols import Monochromator
    from dualrgb.drivers.camera.base import Camera
    from dualrgb.drivers.virtual.monochromator_bench import MonochromatorBench

log = logging.getLogger(__name__)

VIRTUAL, CORNERSTONE, MANUAL = "virtual", "cornerstone", "manual"


@dataclass
class CsrfBench:
    """The monochromator side: ``kind`` virtual (the virtual lab's bench, rendering in ``world``), cornerstone (on
    ``port``) or manual (set by hand: every wavelength is a prompt)."""

    kind: str = VIRTUAL
    port: str = ""
    world: str = "nominal"
    frame_size: tuple[int, int] = (240, 160)
    seed: int = 0
    timeout_s: float = 2.0

    def __post_init__(self) -> None:
        if self.kind not in (VIRTUAL, CORNERSTONE, MANUAL):
            raise ValueError(f"monochromator {self.kind!r}: expected {VIRTUAL}, {CORNERSTONE} or {MANUAL}")
        if self.kind == CORNERSTONE and not self.port:
            raise ValueError("name the Cornerstone's serial port")


@dataclass
class CsrfOutcome:
    """A finished measurement (None when cancelled) and, on the virtual lab, its RMS error against the curves the
    virtual camera renders with (% of each channel's peak)."""

    measurement: CsrfMeasurement | None
    rms_percent: dict[str, float] | None
    radiance_file: Path | None = None


@contextlib.contextmanager
def bench_devices(bench: CsrfBench, camera: Camera | None = None
                  ) -> Iterator[tuple[Camera, Monochromator, MonochromatorBench | None]]:
    """(camera, monochromator, virtual bench or None); the shutter closed and the ports closed on the way out.
    A real bench uses ``camera`` (opened by the caller); the virtual bench has its own."""
    if bench.kind == VIRTUAL:
        from dualrgb.drivers.virtual.monochromator_bench import MonochromatorBench

        with MonochromatorBench(frame_size=bench.frame_size, seed=bench.seed, world=bench.world,
                                timeout_s=bench.timeout_s) as virtual:
            assert virtual.camera is not None                      # made by start()
            yield virtual.camera, virtual.monochromator, virtual
        return
    if camera is None:
        raise ValueError("a real monochromator needs the camera: connect it first")
    from dualrgb.drivers.monochromator import Cornerstone, ManualMonochromator

    if bench.kind == MANUAL:
        yield camera, ManualMonochromator(), None
        return
    with Cornerstone(bench.port, timeout=bench.timeout_s) as mono:
        yield camera, mono, None


def measure_on_bench(camera: Camera, mono: Monochromator, virtual: MonochromatorBench | None,
                     settings: CsrfSettings, out: Path, folder: Path | None, *,
                     reference: RadianceReference | None, read_radiance: Callable[[Path], RadianceReference],
                     prompt: Callable[[str], None] | None, on_event: Callable[[ProgressEvent], None] | None,
                     cancel: CancelToken | None = None) -> CsrfOutcome:
    """Open (or resume) the measurement's session in ``folder`` (default ``<out>-session``), sweep, process and
    write the camera CSV ``out``. Without ``reference`` the virtual bench's spectroradiometer measures the
    monochromator's output after the sweep (``read_radiance`` reads its file with the caller's method)."""
    from dualrgb.app.workflow.folders import open_session

    if reference is None and virtual is None:
        raise ValueError("a real monochromator needs its radiance: a spectroradiometer file, or a photodiode's "
                         "responsivity with its photocurrents")
    kind = VIRTUAL if virtual is not None else MANUAL if getattr(mono, "manual", False) else CORNERSTONE
    definition = {**settings.definition(), "monochromator": kind,
                  **({"world": virtual.world.identity} if virtual is not None else {})}
    where = folder or out.with_name(f"{out.stem}-session")
    written: list[Path] = []

    def measured(wavelengths: list[float]) -> RadianceReference:
        assert virtual is not None
        path = virtual.spectroradiometer().write_csv(where / "radiance-virtual.csv", wavelengths)
        written.append(path)
        log.info("virtual spectroradiometer: %s", path)
        return read_radiance(path)
    with open_session(where, definition, camera, {"measurement": "csrf"},
                      hint="use the same options and camera, or another --session") as session:
        m = measure_csrf(camera, mono, session, settings, radiance=reference if reference is not None else measured,
                         out=out, prompt=prompt, on_event=on_event, cancel=cancel)
    rms = None
    if m is not None and virtual is not None:
        from dualrgb.app.processing.csrf import rms_error_percent

        rms = rms_error_percent(m.result, *virtual.truth())
    return CsrfOutcome(m, rms, written[0] if written else None)
