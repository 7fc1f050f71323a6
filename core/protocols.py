"""What the workflow needs of the devices and of the session it drives, as structural types (``typing.Protocol``).

The workflow (app.sequences, app.workflow) takes its devices and its session as arguments. These protocols say
what it calls on each, so that mypy checks every call and any object with those methods will do: the drivers
(drivers.led_sphere.LedSphere, drivers.monochromator.Cornerstone / ManualMonochromator), the virtual lab's
instruments, the session folder (core.session.CaptureSession) and the tests' stand-ins. None of them inherits
from these classes.

The camera is typed by ``drivers.camera.base.Camera``: the abstract interface every camera implements already
(gphoto2, the virtual camera), with shared behaviour (``capture``, the latency allowance) a protocol would not
carry.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

if TYPE_CHECKING:
    from dualrgb.core.session.manifest import DoseRecord, SessionEntry
    from dualrgb.drivers.camera.base import RawCapture
    from dualrgb.drivers.led_sphere.errors import LightReport
    from dualrgb.drivers.led_sphere.supervisor import LitPeriod
    from dualrgb.drivers.monochromator.errors import ShutterReport
    from dualrgb.simulation.lightsource import LightSource

Reading = TypeVar("Reading")


class Sphere(Protocol):
    """The LED integrating sphere: levels, the light on for at most a cap, off with a read-back report."""

    channels: int                                   # LEDs, numbered 1..channels

    def apply(self, light: LightSource) -> list[float]:
        """Set the LED levels of ``light`` (nothing switched on); returns the levels the sphere took."""
        ...

    def set_levels(self, levels: Iterable[float]) -> list[float]: ...

    def on(self, max_on_s: float | None = None) -> LitPeriod:
        """Switch the light on; the sphere switches it off by itself after ``max_on_s``."""
        ...

    def off(self) -> None: ...

    def ensure_off(self) -> LightReport:
        """Switch everything off, never raising; what is known about the light afterwards (read back)."""
        ...

    def exposure_done(self, period: LitPeriod) -> bool:
        """Whether the light stayed on through ``period`` up to now (not cut at its cap)."""
        ...

    def tripped(self) -> bool:
        """Whether the sphere switched its light off by itself (its ``ON <ms>`` limit or its watchdog: ``trip=1``)
        since it was last switched on."""
        ...

    def temperature_c(self) -> float: ...

    def identify(self) -> dict[str, str]:
        """``model``, ``firmware`` and ``serial``."""
        ...

    def keepalive(self) -> None: ...


class Monochromator(Protocol):
    """A monochromator with a shutter, driven over its port or set by a person (its prompts say what to do)."""

    manual: bool                                    # set by hand: its shutter too (never reported closed)

    def prepare(self) -> None: ...

    def describe(self) -> dict[str, str]: ...

    def prompt_to_set(self, wavelength_nm: float) -> str | None:
        """What a person must do to set ``wavelength_nm`` (None: the instrument does it)."""
        ...

    def prompt_to_close(self) -> str | None: ...

    def goto(self, wavelength_nm: float) -> float:
        """Move to ``wavelength_nm``; returns the wavelength reached."""
        ...

    def open_shutter(self) -> None: ...

    def close_shutter(self) -> None: ...

    def ensure_closed(self) -> ShutterReport:
        """Close the shutter, never raising; what is known about it afterwards."""
        ...


class Radiometer(Protocol[Reading]):
    """A spectroradiometer (or photodiode) at the sphere's port: one reading per call, saved in groups."""

    def measure(self, sample_id: str = "") -> Reading: ...

    def save(self, readings: Sequence[Reading], folder: str | Path, stem: str,
             meta: dict[str, str] | None = None) -> list[Path]: ...


class Session(Protocol):
    """A capture session as the workflow writes and reads it: frames and light doses recorded durably, the
    manifest's entries, the session's settings (core.session.CaptureSession)."""

    path: Path
    settings: dict[str, Any]

    def entries(self, role: str | None = None, *, include_superseded: bool = False) -> list[SessionEntry]: ...

    def has_step(self, step_id: str) -> bool: ...

    def entry(self, step_id: str) -> SessionEntry: ...

    def file_path(self, entry: SessionEntry) -> Path: ...

    def record(self, raw: RawCapture, role: str, *, step_id: str | None = None, light: Any = None,
               sphere_temperature_c: float | None = None, settings: dict | None = None,
               captured_at: str | None = None, **meta: Any) -> SessionEntry:
        """Write one downloaded frame durably; its manifest entry."""
        ...

    def record_dose(self, light: Any, on_s: float, *, step_id: str | None = None, **meta: Any) -> DoseRecord: ...

    def doses(self) -> list[DoseRecord]: ...

    def update_settings(self, **values: Any) -> None: ...

    def extend_definition(self, **items: Any) -> None: ...

    def require_intact(self, entries: list[SessionEntry] | None = None) -> None:
        """Raise core.session.DamagedFramesError naming any missing or damaged frame."""
        ...
