"""OnTimeSupervisor: the host's real-time limit on how long the sphere's light stays on (artwork safety).

Light on an original is damage, so every lit period has a limit (at most 10 s by default: thesis 4.3.2 found no
LED drift in the first 10 s, and the object gets no more light than the exposure needs). The host enforces it in
real time on its own thread, whatever the thread that switched the light on is doing (a camera call that hangs,
a slow download, a GUI waiting for a reply): :meth:`OnTimeSupervisor.arm` is called *before* the light is
switched on (the sphere may obey a request whose reply is lost) and at the deadline the supervisor calls
``switch_off`` (the driver's switch-off, which waits for the port's lock for a bounded time), retrying a few
times if that is not confirmed. The firmware enforces the same limit by itself (``ON <ms>``,
docs/led-sphere-protocol.md), so a host that dies still leaves the object in the dark.

A lit period is never extended: arming again while the light has not been confirmed off continues the same
period (same start), exactly as the firmware counts ``ON <ms>`` from the moment the light came on. Status
polls never arm anything, so polling cannot keep the light on.

The supervisor runs on the real monotonic clock (a limit is a physical time) and imports nothing from Qt or app.
"""
from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

log = logging.getLogger(__name__)

RETRY_S = 0.5           # after a switch-off that was not confirmed, try again this much later ...
RETRIES = 6             # ... this many times (the firmware's own limit is the backstop)


@dataclass
class LitPeriod:
    """One lit period on the host's monotonic clock.

    ``t_on``: just before the switch-on request was sent; ``max_on_s``: its limit; ``switched_at``: when the
    switch-on exchange ended (answered or not: only a switch-off asked after that can end this period). The owner
    marks ``exposure_done_at`` when the camera reports the shutter closed; the supervisor marks ``capped_at`` when
    it switched the light off at the limit; ``off_at`` is set when a switch-off was confirmed by the sphere.
    ``device_limit``: the sphere acknowledged ``ON <ms>`` and switches off by itself at the same limit."""

    t_on: float
    max_on_s: float
    device_limit: bool = False
    switched_at: float | None = None
    exposure_done_at: float | None = None
    capped_at: float | None = None
    off_at: float | None = None

    @property
    def deadline(self) -> float:
        return self.t_on + self.max_on_s

    @property
    def confirmed_off(self) -> bool:
        return self.off_at is not None

    @property
    def cut_short(self) -> bool:
        """The light may have gone off before the exposure was reported done: the supervisor switched it off at
        the limit before, or the exposure ended after the deadline (where the sphere's own limit cuts it)."""
        done = self.exposure_done_at
        if self.capped_at is not None and (done is None or self.capped_at < done):
            return True
        return done is not None and done > self.deadline

    def lit_s(self, now: float | None = None) -> float:
        """Seconds the object may have been lit: up to the confirmed switch-off; while that is unconfirmed, up to
        now, but never past the limit when the sphere enforces it itself."""
        now = time.monotonic() if now is None else now
        if self.off_at is not None:
            end = self.off_at
        elif self.device_limit:
            end = min(now, self.deadline)
        else:
            end = now
        return max(0.0, end - self.t_on)


class OnTimeSupervisor:
    """Switches the light off at each lit period's deadline on its own thread (see the module docstring).

    ``switch_off()`` must return normally only when the sphere confirmed the light off and raise otherwise; it
    is called on the supervisor's thread, so it must bound its own waits (the driver's lock and timeouts do)."""

    def __init__(self, switch_off: Callable[[], None], name: str = "light supervisor",
                 retry_s: float = RETRY_S, retries: int = RETRIES):
        self._switch_off = switch_off
        self._name = name
        self._retry_s = retry_s
        self._retries = retries
        self._cond = threading.Condition()
        self._period: LitPeriod | None = None
        self._changed_at = float("-inf")       # when a period was last armed or ended
        self._attempts = 0
        self._next_try: float | None = None
        self._thread: threading.Thread | None = None
        self._stopped = False

    # ------------------------------------------------------------------------------------------ owner side
    def arm(self, max_on_s: float, already_on_s: float = 0.0) -> LitPeriod:
        """A lit period starting now (``already_on_s`` earlier when adopting a light found on). While the
        current period is not confirmed off it continues: same start, the new limit counted from it."""
        now = time.monotonic()
        with self._cond:
            current = self._period
            t_on = current.t_on if current is not None else now - max(0.0, already_on_s)
            period = LitPeriod(t_on, float(max_on_s))
            if current is not None:
                period.capped_at = current.capped_at
            self._period = period
            self._changed_at = now
            self._attempts, self._next_try = 0, None
            self._start_locked()
            self._cond.notify_all()
        if current is not None:
            log.info("%s: light not confirmed off since %.2f s ago: the lit period continues (never extended)",
                     self._name, now - t_on)
        return period

    def current(self) -> LitPeriod | None:
        """The period not yet confirmed off, if any."""
        with self._cond:
            return self._period

    def exposure_done(self, period: LitPeriod) -> bool:
        """Mark the camera's exposure as finished; False when the light had already been cut at its limit."""
        with self._cond:
            period.exposure_done_at = time.monotonic()
            return not period.cut_short

    def confirm_off(self, asked_at: float) -> None:
        """The sphere said the light is off, to a request sent at ``asked_at`` (host monotonic clock): the current
        period ends here if its switch-on had ended by then (a status poll racing a switch-on proves nothing)."""
        with self._cond:
            period = self._period
            if period is not None and period.switched_at is not None and period.switched_at <= asked_at:
                period.off_at = time.monotonic()
                self._period = None
                self._changed_at = period.off_at
                self._cond.notify_all()

    def adopt(self, on_for_s: float, max_on_s: float, asked_at: float) -> LitPeriod | None:
        """The sphere said it is lit (for ``on_for_s``), to a request sent at ``asked_at``, and no period is armed:
        someone else switched it on; the limit applies to it too (unless a period began or ended meanwhile)."""
        with self._cond:
            if self._period is not None or self._changed_at >= asked_at:
                return None
        period = self.arm(max_on_s, already_on_s=on_for_s)
        period.switched_at = asked_at
        return period

    def stop(self) -> None:
        """Stop the thread (the port is closing); a period still armed is left to the firmware's limit."""
        with self._cond:
            self._stopped = True
            self._cond.notify_all()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=5)
        self._thread = None

    # ------------------------------------------------------------------------------------------ thread
    def _start_locked(self) -> None:
        self._stopped = False
        if self._thread is None or not self._thread.is_alive():
            self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
            self._thread.start()

    def _due_locked(self) -> LitPeriod | None:
        """Wait until a switch-off is due; returns its period, or None when stopped."""
        while not self._stopped:
            period = self._period
            if period is None or self._attempts > self._retries:
                self._cond.wait()
                continue
            due = self._next_try if self._next_try is not None else period.deadline
            wait = due - time.monotonic()
            if wait > 0:
                self._cond.wait(wait)
                continue
            if period.capped_at is None:
                period.capped_at = time.monotonic()
            self._attempts += 1
            return period
        return None

    def _run(self) -> None:
        while True:
            with self._cond:
                period = self._due_locked()
            if period is None:
                return
            late = time.monotonic() - period.deadline
            log.warning("%s: the light reached its %.2f s limit: switching it off (%.3f s after the deadline)",
                        self._name, period.max_on_s, late)
            try:
                self._switch_off()
            except Exception as exc:  # noqa: BLE001 - any failure: retried, then left to the firmware's own limit (logged)
                with self._cond:
                    self._next_try = time.monotonic() + self._retry_s
                    gave_up = self._attempts > self._retries
                log.error("%s: switching off at the limit was not confirmed (%s)%s", self._name, exc,
                          "; giving up, the sphere's own limit and watchdog remain" if gave_up else "; retrying")
                continue
            with self._cond:
                if self._period is period:
                    period.off_at = self._changed_at = time.monotonic()
                    self._period = None
