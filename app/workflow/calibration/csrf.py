"""Measuring the camera's spectral sensitivity (thesis 4.2): the one place the CLI (and a GUI) call.

    result = measure_csrf(camera, monochromator, session, CsrfSettings(380, 780, 10), radiance=reference,
                          out=Path("d610_csrf.csv"), prompt=ask_person, on_event=show)

runs the sweep (app.sequences.csrf.CsrfSweep, a plan of the run engine, which alone acts on the camera and the
monochromator: prompts go to ``prompt``, which returns when the person has done it; every other event to
``on_event``), then the processing (app.processing.csrf) against the radiance reference,
and writes the camera CSV. ``radiance`` may be a callable, called after the sweep (the virtual lab's
spectroradiometer measures then). A cancel (``cancel`` token, checked between steps) ends with the shutter
closed and returns None; nothing is written.
"""
from __future__ import annotations

import datetime
import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from dualrgb.app.processing.csrf import CsrfResult, compute_csrf, session_signals, write_camera_csv
from dualrgb.app.sequences.base import ProgressEvent
from dualrgb.app.sequences.csrf import CsrfSettings, CsrfSweep
from dualrgb.common.progress import Cancelled, CancelToken
from dualrgb.core.device_actions import StandDevices
from dualrgb.core.engine import RunControl, RunEngine
from dualrgb.core.light_safety import SafetySettings
from dualrgb.core.vocabulary import EventKind
from dualrgb.simulation.radiance_reference import RadianceReference

if TYPE_CHECKING:
    from dualrgb.core.protocols import Monochromator, Session
    from dualrgb.drivers.camera.base import Camera

log = logging.getLogger(__name__)

Radiance = RadianceReference | Callable[[list[float]], RadianceReference]


@dataclass
class CsrfMeasurement:
    """What a finished measurement gives: the result, where it was written, the sweep's exposures."""

    result: CsrfResult
    path: Path
    session: Path
    exposures: dict[float, float]
    instrument: dict[str, str]


def sweep_engine(camera: Camera, monochromator: Monochromator, session: Session, settings: CsrfSettings, *,
                 prompt: Callable[[str], None] | None = None, on_event: Callable[[ProgressEvent], None] | None = None,
                 cancel: CancelToken | None = None) -> RunEngine:
    """The run engine of a sweep (under ``cancel``): the camera, the monochromator, the session; prompts go to
    ``prompt`` (ValueError without one), every other event to ``on_event``."""
    def ask(message: str) -> None:
        if prompt is None:
            raise ValueError(f"{message}: this measurement needs a person at the monochromator")
        prompt(message)

    def forward(event: ProgressEvent) -> None:
        if on_event is not None and event.kind is not EventKind.PROMPT:
            on_event(event)
    safety = SafetySettings(expose_timeout_s=settings.expose_timeout_s, fetch_timeout_s=settings.fetch_timeout_s)
    return RunEngine("CSRF sweep", StandDevices(camera=camera, session=session, monochromator=monochromator),
                     safety=safety, control=RunControl(cancel), prompt=ask, on_event=forward)


def run_sweep(engine: RunEngine, sweep: CsrfSweep) -> bool:
    """Run the sweep through ``engine``; False when it was cancelled. An error in a callback still closes the
    shutter (the engine's clean-up)."""
    try:
        engine.run_plan(sweep)
    except Cancelled:
        if engine.on_event is not None:                   # said as every cancelled plan says it
            engine.on_event(ProgressEvent(0, 0, f"{sweep.name} cancelled; the shutter closed",
                                          kind=EventKind.CANCELLED))
        return False
    return True


def provenance(sweep: CsrfSweep, session: Session, camera: Camera) -> dict[str, str]:
    """The camera CSV's header lines: instrument, camera, date, session."""
    summary = camera.config_summary() if hasattr(camera, "config_summary") else {}
    return {**{f"monochromator_{k}" if k != "instrument" else "monochromator": str(v)
               for k, v in sweep.instrument.items()},
            "camera": str(summary.get("camera", getattr(camera, "name", "camera"))),
            "camera_settings": f"ISO {summary.get('iso', '?')}, f/{summary.get('aperture', '?')}",
            "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
            "session": f"{session.path.name} (created {session.settings.get('created_at', '?')})"}


def measure_csrf(camera: Camera, monochromator: Monochromator, session: Session, settings: CsrfSettings, *,
                 radiance: Radiance, out: str | Path, prompt: Callable[[str], None] | None = None,
                 on_event: Callable[[ProgressEvent], None] | None = None,
                 cancel: CancelToken | None = None) -> CsrfMeasurement | None:
    """Sweep, process, write the camera CSV to ``out`` (module docstring); None when cancelled."""
    engine = sweep_engine(camera, monochromator, session, settings, prompt=prompt, on_event=on_event, cancel=cancel)
    sweep = CsrfSweep(engine.facts, settings)
    if not run_sweep(engine, sweep):
        return None
    reference = radiance(settings.wavelengths()) if callable(radiance) else radiance
    result = compute_csrf(session_signals(session, settings.region), reference)
    path = write_camera_csv(result, out, provenance(sweep, session, camera))
    return CsrfMeasurement(result, path, session.path, dict(sweep.exposures), dict(sweep.instrument))
