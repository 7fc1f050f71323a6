"""The host's on-time supervisor (drivers/led_sphere/supervisor.py) on its own: it switches off at the deadline on
its own thread, retries an unconfirmed switch-off, never extends a lit period, and ignores a status reply that
raced a switch-on; and LedSphere's port lock makes a second thread wait a bounded time."""
from __future__ import annotations

import threading
import time

import pytest
from sphere_fakes import ScriptedSerial

from dualrgb.drivers.led_sphere import LedSphere, SphereError
from dualrgb.drivers.led_sphere.supervisor import OnTimeSupervisor


class Switch:
    def __init__(self, fail: int = 0):
        self.calls: list[float] = []
        self.fail = fail

    def __call__(self) -> None:
        self.calls.append(time.monotonic())
        if len(self.calls) <= self.fail:
            raise SphereError("no reply to 'LIGHT 0'", kind="timeout")


def test_switches_off_at_the_deadline_whatever_the_owner_does():
    switch = Switch()
    sup = OnTimeSupervisor(switch, retry_s=0.05)
    period = sup.arm(0.2)
    period.switched_at = time.monotonic()
    time.sleep(0.5)                                  # the owner is "hung": it does nothing
    assert len(switch.calls) == 1 and 0.2 <= switch.calls[0] - period.t_on < 0.3
    assert period.capped_at is not None and period.confirmed_off and sup.current() is None
    assert not sup.exposure_done(period) and period.cut_short
    sup.stop()


def test_an_unconfirmed_switch_off_is_retried():
    switch = Switch(fail=2)
    sup = OnTimeSupervisor(switch, retry_s=0.05)
    period = sup.arm(0.1)
    time.sleep(0.5)
    assert len(switch.calls) == 3 and period.confirmed_off
    sup.stop()


def test_arming_again_before_the_light_is_off_never_extends_the_period():
    sup = OnTimeSupervisor(Switch())
    first = sup.arm(5.0)
    time.sleep(0.05)
    second = sup.arm(5.0)
    assert second.t_on == first.t_on and second.deadline == first.deadline
    sup.confirm_off(time.monotonic() + 1)            # switch-on of `second` not ended: proves nothing
    assert sup.current() is second
    second.switched_at = time.monotonic()
    sup.confirm_off(time.monotonic())
    assert sup.current() is None and sup.arm(5.0).t_on > first.t_on
    sup.stop()


def test_a_status_reply_that_raced_a_switch_on_neither_ends_nor_adopts_it():
    sup = OnTimeSupervisor(Switch())
    asked = time.monotonic()                         # STATUS? sent ...
    period = sup.arm(5.0)                            # ... while another thread switches on
    period.switched_at = time.monotonic()
    sup.confirm_off(asked)                           # its 'light=0' is older than the switch-on
    assert sup.current() is period
    period.off_at = None
    sup.confirm_off(time.monotonic())
    assert sup.adopt(1.0, 10.0, asked) is None       # a period ended after that STATUS? was sent
    before = time.monotonic()
    adopted = sup.adopt(1.0, 10.0, time.monotonic())
    after = time.monotonic()
    assert adopted is not None and adopted.deadline == pytest.approx(adopted.t_on + 10.0)
    assert before - 1.0 <= adopted.t_on <= after - 1.0          # on for 1.0 s when adopted
    sup.stop()


def test_lit_seconds_for_the_dose():
    sup = OnTimeSupervisor(Switch())
    period = sup.arm(0.5)
    period.device_limit = True
    assert period.lit_s(period.t_on + 9.0) == 0.5    # the sphere's own limit bounds an unconfirmed period
    period.device_limit = False
    assert period.lit_s(period.t_on + 9.0) == pytest.approx(9.0)    # without it, until now
    period.off_at = period.t_on + 0.25
    assert period.lit_s(period.t_on + 9.0) == 0.25
    sup.stop()


def test_a_second_thread_waits_for_the_port_a_bounded_time():
    class SlowSerial(ScriptedSerial):
        def write(self, data):
            release.wait(30)                         # one exchange hangs inside the lock (until released)
            return super().write(data)
    release = threading.Event()
    port = SlowSerial([(b"PING\n", b"OK PING\n"), (b"TEMP?\n", b"OK TEMP 25.00\n")])
    sphere = LedSphere(port, timeout=0.05)
    holder = threading.Thread(target=sphere.keepalive)
    holder.start()
    time.sleep(0.05)
    with pytest.raises(SphereError, match="the port stayed busy with another request") as info:
        sphere.temperature_c()
    assert info.value.kind == "timeout" and holder.is_alive()   # it gave up while the other request still hangs
    release.set()
    holder.join(5)
    assert sphere.temperature_c() == 25.0
    sphere.close(leave_on=True)


def test_an_exposure_that_ends_after_the_deadline_counts_as_cut_short():
    sup = OnTimeSupervisor(Switch())
    period = sup.arm(5.0)
    period.exposure_done_at = period.deadline + 0.01     # the sphere's own limit may have cut it
    assert period.cut_short
    period.exposure_done_at = period.deadline - 0.01
    assert not period.cut_short
    sup.stop()
