"""The run engine's message vocabulary: what a plan may ask for, typed, in one place (bluesky's ``Msg``).

A *plan* is a generator. It yields messages and gets each one's answer back, and yields
:class:`ProgressEvent` s to say what it did; the run engine (core.engine) alone applies the messages to
the devices (the LED sphere, the camera, the monochromator, the spectroradiometer, the stand), so no plan holds a
device or calls one:

    def darks(exposures, n):                                   # a plan: nothing happens until the engine runs it
        for t in exposures:
            for i in range(n):
                entry = yield Shot(Role.DARK.value, None, t, step_id(Role.DARK, exposure_s=t, frame=i))
                yield ProgressEvent(i + 1, n, f"dark {i + 1}/{n}", kind=EventKind.FRAME, data={"entry": entry.seq})

    engine.drive(darks([1 / 60], 10))                          # core.engine.RunEngine

=================  ==========================================================================  ====================
message            what the engine does                                                        answer
=================  ==========================================================================  ====================
Checkpoint         waits while the run is paused, raises Cancelled once it is cancelled        None
Prompt             a person must do something: the CLI asks, the window pauses until Continue  None
Place              the stand (a device) places it; without one, a person is asked (Prompt)     None
SetLight           the sphere's LED levels (nothing is switched on)                            levels taken
LightOn            the light on for at most ``cap_s`` (the driver's supervisor and the
                   sphere's own ``ON <ms>``); its lit period counts in the light dose          LitPeriod
LightOff           the light off, read back; the lit period's dose recorded as it ends        LightReport
ReadBack           every LED 0 and the light off, read back (never raises)                     LightReport
Wait               time passes (cancellable; the sphere's watchdog hears from the host)        None
Shot               one frame, safely: the light-on cap computed first, light on only for the
                   exposure, off before the download, the frame written to the session first;
                   a frame the light did not cover all through is set aside and shot again
                   once (core.shooter)                                                 Taken
Entries            the session's entries of a role (what a resumed plan has already)           [SessionEntry]
ReadFrame          a frame read back from the session folder                                   RawFrame
Instrument         the monochromator prepared; what it is                                      dict
Tune               the monochromator moved (a person asked first when it is set by hand)       wavelength reached
ShutterShot        one frame under the monochromator: its shutter open only for the exposure   Taken
CloseShutter       the monochromator's shutter closed (a person asked when set by hand)        None
Measure            one spectroradiometer reading                                               the reading
SaveReadings       the instrument writes a series of readings                                  the files
=================  ==========================================================================  ====================

The module imports nothing of the devices nor of app/workflow above the vocabulary: it can live in a low package
with the engine and the device protocols.
"""
from __future__ import annotations

from collections.abc import Generator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dualrgb.core.vocabulary import EventKind

if TYPE_CHECKING:
    from dualrgb.core.session.manifest import SessionEntry
    from dualrgb.simulation.lightsource import LightSource

KEEPALIVE_S = 10.0          # during a Wait the sphere's watchdog (30 s by default) hears from the host this often


@dataclass
class PlannedFrame:
    """One frame a plan will take, listed before anything moves."""

    role: str                    # 'dark', 'flat', 'target', 'hdr', 'crf', ...
    exposure_s: float
    light: str = ""              # light source label ('' = lights off)
    note: str = ""


@dataclass
class ProgressEvent:
    """One step of a plan (a frame saved or kept, a prompt for the user, done, cancelled) or of a run."""

    step: int                    # steps completed so far
    total: int                   # steps planned
    message: str
    kind: EventKind = EventKind.PROGRESS
    time_left_s: float | None = None
    data: dict[str, Any] = field(default_factory=dict)

    @property
    def fraction(self) -> float:
        return 0.0 if self.total <= 0 else min(1.0, self.step / self.total)


# ---------------------------------------------------------------------------------------------- no device
@dataclass(frozen=True)
class Checkpoint:
    what: str = ""


@dataclass(frozen=True)
class Prompt:
    message: str
    data: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Place:
    """``what`` ('train', 'test', 'open-gate', 'lens-cap', 'original:<id>') on the stand, ``nd``: under the ND
    filter; ``ask``: what a person is asked when no stand device places it."""

    what: str
    nd: bool = False
    ask: str = ""

    def prompt(self) -> str:
        return self.ask or f"Place the {self.what}, then continue"


@dataclass(frozen=True)
class Entries:
    """The session's current entries of ``role`` (what a resumed plan has already)."""

    role: str


@dataclass(frozen=True)
class ReadFrame:
    """The raw frame of a session entry (a Shot's answer's ``entry``); ``keep``: cached for the plan's next reads."""

    entry: SessionEntry
    keep: bool = True


# ---------------------------------------------------------------------------------------------- the sphere
@dataclass(frozen=True)
class SetLight:
    light: LightSource


@dataclass(frozen=True)
class LightOn:
    """The light on (the levels last set) for at most ``cap_s``; ``what`` names its lit period in the dose."""

    cap_s: float
    what: str = "light"


@dataclass(frozen=True)
class LightOff:
    pass


@dataclass(frozen=True)
class ReadBack:
    pass


@dataclass(frozen=True)
class Wait:
    seconds: float


# ---------------------------------------------------------------------------------------------- the camera
@dataclass(frozen=True)
class Shot:
    """One frame: ``light`` None (or dark) for an unlit frame; recorded under ``step_id`` with ``meta``."""

    role: str
    light: LightSource | None
    exposure_s: float
    step_id: str
    meta: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Taken:
    """A Shot's (and a ShutterShot's) answer: the frame's session entry, and whether the session had the step
    already (``kept``: resumed, not shot again)."""

    entry: SessionEntry
    kept: bool = False

    @property
    def seq(self) -> int:
        return self.entry.seq

    @property
    def kind(self) -> EventKind:
        return EventKind.KEPT if self.kept else EventKind.FRAME


# ---------------------------------------------------------------------------------------------- monochromator
@dataclass(frozen=True)
class Instrument:
    pass


@dataclass(frozen=True)
class Tune:
    wavelength_nm: float


@dataclass(frozen=True)
class ShutterShot:
    """One frame under the monochromator, its shutter open (``lit``) or closed."""

    role: str
    step_id: str
    exposure_s: float
    lit: bool
    meta: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class CloseShutter:
    pass


# ---------------------------------------------------------------------------------------------- radiometer
@dataclass(frozen=True)
class Measure:
    sample_id: str = ""


@dataclass(frozen=True)
class SaveReadings:
    readings: Sequence[Any]
    folder: Path
    stem: str


Message = (Checkpoint | Prompt | Place | Entries | ReadFrame | SetLight | LightOn | LightOff | ReadBack | Wait | Shot
           | Instrument | Tune | ShutterShot | CloseShutter | Measure | SaveReadings)
DEVICE_MESSAGES = (SetLight, LightOn, LightOff, ReadBack, Wait, Shot, Instrument, Tune, ShutterShot, CloseShutter,
                   Measure, SaveReadings)
PlanItem = Message | ProgressEvent
PlanSteps = Generator[PlanItem, Any, Any]      # what a plan's ``_steps()`` and a generator plan are
