"""The light-on rule every lit frame obeys, and what a plan knows of the stand before anything moves.

:class:`SafetySettings`: a frame's light stays on for at most settle + exposure + the camera's latency allowance,
refused before anything is switched on when that exceeds ``max_on_s`` (default 10 s: the thesis found no LED drift
in the first 10 s, 4.3.2). :class:`StandFacts`: the camera's shutter speeds and that rule with the camera's own
latency, read once by the run engine (core.engine), so that plans are built and checked without a device.
:func:`restate`: an error with what is known about the light appended (every error says the light's state).
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from dualrgb.common.errors import ReportedError
from dualrgb.core.light_timing import SETTLE_S
from dualrgb.core.vocabulary import Role
from dualrgb.drivers.camera.base import DEFAULT_LATENCY_S, CameraError
from dualrgb.drivers.led_sphere.errors import SphereError

if TYPE_CHECKING:
    from dualrgb.drivers.camera.base import Camera
    from dualrgb.drivers.led_sphere.errors import LightReport

log = logging.getLogger(__name__)

REJECTED_ROLE = Role.REJECTED.value      # frames kept aside, never used (lit for less than the exposure)
NO_CAMERA = "no camera is connected (connect one: Devices, or --camera)"


class LightSafetyError(ReportedError, RuntimeError):
    """A capture the light-on limit does not allow (refused before anything was switched on), or a step whose
    light was cut before the shutter closed twice (both frames kept aside as 'rejected')."""


@dataclass(frozen=True)
class SafetySettings:
    max_on_s: float = 10.0          # per capture, light on at most (settle + exposure + latency)
    settle_s: float = SETTLE_S      # after switching on, before the shutter opens
    # the camera's allowance beyond the exposure (trigger, shutter lag, reporting the shutter closed); None: what
    # the camera reports (Camera.latency_for, filled in by for_camera), DEFAULT_LATENCY_S without a camera
    latency_s: float | None = None
    expose_timeout_s: float = 30.0  # host-side deadline of an exposure beyond its exposure time
    fetch_timeout_s: float = 120.0  # host-side deadline of a download
    camera_latency: Callable[[float], float] | None = field(default=None, repr=False, compare=False)
    # how late after the settle time the host may trigger the camera once the light is on (a host starved by other
    # work); None: half the camera's latency allowance, so the exposure can still end within the light's limit.
    # A later trigger is not sent: the light goes off at once and the frame is shot again (core.shooter)
    trigger_slack_s: float | None = None

    def for_camera(self, camera: Camera | None) -> SafetySettings:
        """These settings with the camera's own latency allowance (unless one was given, or the camera - a
        stand-in - reports none)."""
        latency_for = getattr(camera, "latency_for", None)
        if self.latency_s is not None or latency_for is None:
            return self
        return replace(self, camera_latency=latency_for)

    def latency_for(self, exposure_s: float) -> float:
        if self.latency_s is not None:
            return self.latency_s
        return float(self.camera_latency(exposure_s)) if self.camera_latency else DEFAULT_LATENCY_S

    @property
    def max_exposure_s(self) -> float:
        """The longest exposure the light-on limit allows (the allowance may grow with the exposure)."""
        budget = self.max_on_s - self.settle_s
        if self.latency_s is not None or self.camera_latency is None:
            return budget - self.latency_for(0.0)
        lo, hi = 0.0, max(budget, 0.0)
        if self.light_limit_s(hi) <= self.max_on_s:
            return hi
        for _ in range(50):             # bisection: the light limit grows with the exposure
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if self.light_limit_s(mid) <= self.max_on_s else (lo, mid)
        return lo

    def light_limit_s(self, exposure_s: float) -> float:
        """How long the light may stay on for one exposure."""
        return self.settle_s + float(exposure_s) + self.latency_for(float(exposure_s))

    def slack_s(self, exposure_s: float) -> float:
        """How late the host may be at either end of a lit exposure (``trigger_slack_s``): the camera's trigger
        after switch-on + settle, and the switch-off after the camera reported the exposure's end."""
        return float(self.trigger_slack_s if self.trigger_slack_s is not None else self.latency_for(exposure_s) / 2)

    def trigger_bound_s(self, exposure_s: float) -> float:
        """The longest the camera's trigger may follow the light's switch-on: settle + the slack."""
        return self.settle_s + self.slack_s(exposure_s)

    def check(self, exposure_s: float) -> None:
        idle = self.settle_s + self.latency_for(0.0)
        if idle >= self.max_on_s:
            raise LightSafetyError(
                f"the camera's latency allowance ({self.latency_for(0.0):g} s) plus settle ({self.settle_s:g} s) "
                f"leaves no exposure within the {self.max_on_s:g} s light limit: this camera cannot be used with "
                "the light as set; measure its latency (docs/first-session-d610.md) or raise the limit")
        on = self.light_limit_s(exposure_s)
        if on > self.max_on_s:
            raise LightSafetyError(
                f"exposure {exposure_s:g} s would keep the light on up to {on:.1f} s (settle {self.settle_s:g} s, "
                f"camera latency {self.latency_for(exposure_s):g} s), over the {self.max_on_s:g} s limit (LEDs "
                "drift after 10 s); use a brighter light, a higher ISO or raise the limit")


@dataclass(frozen=True)
class StandFacts:
    """What a plan knows of the stand before anything moves: the camera's shutter speeds (empty: no camera) and
    the light-on rule with this camera's latency. Made by the run engine (``RunEngine.facts``) or, for plans shown
    before anything is connected, by core.engine.facts_of."""

    shutters: tuple[float, ...] = ()
    safety: SafetySettings = SafetySettings()

    def shutter_speeds(self) -> list[float]:
        if not self.shutters:
            raise ValueError(NO_CAMERA)
        return list(self.shutters)

    @property
    def max_exposure_s(self) -> float:
        return self.safety.max_exposure_s

    def check_light_time(self, exposure_s: float) -> None:
        """Refuse (LightSafetyError, one line) an exposure whose light would stay on past the cap."""
        self.safety.check(exposure_s)


def restate(error: BaseException, light: LightReport) -> BaseException:
    """``error`` with what is known about the light appended to its one-line message (same type where possible:
    SphereError, CameraError, LightSafetyError), so the camera's error and an unconfirmed switch-off are both
    reported."""
    text = f"{error}; {light.message}"
    if isinstance(error, SphereError):
        return SphereError(text, kind=error.kind, code=error.code, light="off" if light.off else "unknown")
    if isinstance(error, CameraError):
        return CameraError(text, error.code)
    if isinstance(error, LightSafetyError):
        return LightSafetyError(text)
    error.add_note(light.message)
    return error
