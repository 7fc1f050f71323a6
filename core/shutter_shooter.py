"""ShutterShooter: the run engine's hands for one frame under the monochromator (the
:class:`core.messages.ShutterShot` message; only the engine makes one).

The shutter is open only for the exposure and closed as soon as the camera reports it over, before the download;
the frame is written to the session first thing (resume: a step already there is not shot again); every error
says truthfully what state the shutter was left in.
"""
from __future__ import annotations

import logging
from typing import Any

from dualrgb.core.protocols import Monochromator, Session
from dualrgb.core.session.manifest import SessionEntry
from dualrgb.drivers.camera.base import Camera, CameraError, Exposure, RawCapture, call_with_deadline
from dualrgb.drivers.monochromator.errors import MonochromatorError, ShutterReport

log = logging.getLogger(__name__)


def restate(error: BaseException, report: ShutterReport) -> BaseException:
    """``error`` with what is known about the shutter appended to its one-line message (same type where possible)."""
    text = f"{error}; {report.message}"
    if isinstance(error, MonochromatorError):
        return MonochromatorError(text, kind=error.kind, code=error.code,
                                  shutter="closed" if report.closed else "unknown")
    if isinstance(error, CameraError):
        return CameraError(text, error.code)
    error.add_note(report.message)
    return error


class ShutterShooter:
    """One frame done safely under the monochromator (module docstring)."""

    def __init__(self, camera: Camera, monochromator: Monochromator, session: Session, *,
                 expose_timeout_s: float = 30.0, fetch_timeout_s: float = 120.0):
        self.camera = camera
        self.monochromator = monochromator
        self.session = session
        self.expose_timeout_s, self.fetch_timeout_s = expose_timeout_s, fetch_timeout_s

    def shoot(self, role: str, step: str, exposure_s: float, *, lit: bool, **meta: Any) -> SessionEntry:
        if self.session.has_step(step):
            log.info("step %s already in the session: not shot again", step)
            return self.session.entry(step)
        report: ShutterReport | None = None
        if lit:
            exposure, report = self._lit_exposure(exposure_s)
        else:
            exposure = self._expose(exposure_s)
        raw = self._fetch(exposure, report)
        settings = {k: v for k, v in self.camera.settings().__dict__.items() if v is not None}
        entry = self.session.record(raw, role, step_id=step, settings=settings, shutter_open=lit, **meta)
        if report is not None and not report.closed:
            raise MonochromatorError(f"{step}: the frame was saved (#{entry.seq}); {report.message}",
                                     kind=report.error.kind if report.error else "device", shutter="unknown")
        return entry

    def _lit_exposure(self, exposure_s: float) -> tuple[Exposure, ShutterReport]:
        """Shutter open, expose, shutter closed; a failure is raised after the shutter was closed, saying so."""
        self.monochromator.open_shutter()             # a failed open has closed it and says so
        exposure: Exposure | None = None
        failure: BaseException | None = None
        try:
            exposure = self._expose(exposure_s)
        except BaseException as exc:  # noqa: BLE001 - any failure, Ctrl-C too: the shutter closes first, then it is raised
            failure = exc
        report = self.close()
        if failure is not None:
            raise restate(failure, report) from failure
        assert exposure is not None
        return exposure, report

    def close(self) -> ShutterReport:
        try:
            self.monochromator.close_shutter()
        except MonochromatorError as exc:
            log.warning("closing the shutter after the exposure: %s", exc)
            return self.monochromator.ensure_closed()
        return ShutterReport(True, "the monochromator's shutter was closed")

    def _expose(self, exposure_s: float) -> Exposure:
        return call_with_deadline(lambda: self.camera.expose(exposure_s),
                                  float(exposure_s) + self.expose_timeout_s, "capture: the exposure")

    def _fetch(self, exposure: Exposure, report: ShutterReport | None) -> RawCapture:
        try:
            return call_with_deadline(lambda: self.camera.fetch(exposure), self.fetch_timeout_s,
                                      "capture: the download")
        except CameraError as exc:
            raise (restate(exc, report) if report is not None else exc) from exc
