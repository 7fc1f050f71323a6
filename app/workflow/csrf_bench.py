"""Where ``dualrgb measure csrf`` and the GUI's *Measure the camera* run on a real bench: the devices (a camera with
a Cornerstone on a serial port, or a monochromator set by hand), the session and the radiance reference (a file, or
a function that measures it after the sweep). The measurement itself is app.workflow.csrf.measure_csrf; the CLI
and the GUI differ only in how they ask the person (``prompt``) and show progress (``on_event``). The virtual lab's
bench is a front end's (app.lab.csrf_bench), which calls :func:`measure_on_bench` with its own devices.
"""
from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dualrgb.app.sequences.base import ProgressEvent
from dualrgb.app.sequences.csrf import CsrfSettings
from dualrgb.app.workflow.csrf import CsrfMeasurement, measure_csrf
from dualrgb.common.progress import CancelToken
from dualrgb.simulation.radiance_reference import RadianceReference

if TYPE_CHECKING:
    from dualrgb.app.protocols import Monochromator
    from dualrgb.drivers.camera.base import Camera

log = logging.getLogger(__name__)

CORNERSTONE, MANUAL = "cornerstone", "manual"
Radiance = RadianceReference | Callable[[list[float]], RadianceReference]


@dataclass
class CsrfBench:
    """The monochromator side: ``kind`` cornerstone (on ``port``) or manual (set by hand: every wavelength is a
    prompt)."""

    kind: str = CORNERSTONE
    port: str = ""
    timeout_s: float = 2.0

    def __post_init__(self) -> None:
        if self.kind not in (CORNERSTONE, MANUAL):
            raise ValueError(f"monochromator {self.kind!r}: expected {CORNERSTONE} or {MANUAL}")
        if self.kind == CORNERSTONE and not self.port:
            raise ValueError("name the Cornerstone's serial port")


@dataclass
class CsrfOutcome:
    """A finished measurement (None when cancelled); what a bench adds about it (``rms_percent``: against known
    curves, % of each channel's peak; ``radiance_file``: the radiance measured after the sweep)."""

    measurement: CsrfMeasurement | None
    rms_percent: dict[str, float] | None = None
    radiance_file: Path | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@contextlib.contextmanager
def bench_devices(bench: CsrfBench, camera: Camera | None = None) -> Iterator[tuple[Camera, Monochromator]]:
    """(camera, monochromator); the shutter closed and the port closed on the way out. ``camera`` is opened by the
    caller."""
    if camera is None:
        raise ValueError("a real monochromator needs the camera: connect it first")
    from dualrgb.drivers.monochromator import Cornerstone, ManualMonochromator

    if bench.kind == MANUAL:
        yield camera, ManualMonochromator()
        return
    with Cornerstone(bench.port, timeout=bench.timeout_s) as mono:
        yield camera, mono


def measure_on_bench(camera: Camera, mono: Monochromator, settings: CsrfSettings, out: Path, folder: Path | None, *,
                     radiance: Radiance | None, prompt: Callable[[str], None] | None,
                     on_event: Callable[[ProgressEvent], None] | None, cancel: CancelToken | None = None,
                     definition: dict[str, Any] | None = None) -> CsrfOutcome:
    """Open (or resume) the measurement's session in ``folder`` (default ``<out>-session``), sweep, process and
    write the camera CSV ``out``. ``radiance``: the monochromator's radiance reference, or a function that measures
    it after the sweep (at the sweep's wavelengths); ``definition``: what else defines the session (a bench's
    identity)."""
    from dualrgb.app.workflow.folders import open_session

    if radiance is None:
        raise ValueError("a real monochromator needs its radiance: a spectroradiometer file, or a photodiode's "
                         "responsivity with its photocurrents")
    kind = MANUAL if getattr(mono, "manual", False) else CORNERSTONE
    where = folder or out.with_name(f"{out.stem}-session")
    with open_session(where, {**settings.definition(), "monochromator": kind, **(definition or {})}, camera,
                      {"measurement": "csrf"}, hint="use the same options and camera, or another --session") as session:
        m = measure_csrf(camera, mono, session, settings, radiance=radiance, out=out, prompt=prompt,
                         on_event=on_event, cancel=cancel)
    return CsrfOutcome(m)
