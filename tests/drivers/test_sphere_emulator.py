"""The sphere emulator: firmware replies and error codes, physics (drift of thesis 4.3.2, LED 10 fading,
temperature, dose), the watchdog, and the LedSphere driver end-to-end over a real pty including every fault."""
from __future__ import annotations

import time
from dataclasses import FrozenInstanceError

import numpy as np
import pytest
from sphere_fakes import FakeClock
from transports import TRANSPORTS, assert_port

from dualrgb.drivers.led_sphere import LedSphere, SphereError
from dualrgb.drivers.led_sphere import protocol as P
from dualrgb.drivers.virtual.led_physics import DRIFT_ONSET_S, MAX_SHIFT_NM, fade_factor, peak_shift_nm
from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator, SphereSnapshot
from dualrgb.simulation.lightsource import LightSource

TIMEOUT = 0.2          # fault cases: the time they take
OK_TIMEOUT = 2.0       # happy paths: only matters if something is wrong (keeps a loaded machine from flaking)


# ---------------------------------------------------------------------------------------------- drift model
def test_no_drift_in_the_first_10_seconds():
    assert np.all(peak_shift_nm(np.linspace(0, DRIFT_ONSET_S, 11)[:, None]) == 0)


def test_drift_after_an_hour_matches_thesis_4_3_2():
    shift = peak_shift_nm(np.full(10, 3600.0))
    assert 6.5 <= shift[3] <= 7.0                    # LED 4: the largest, ~7 nm
    assert shift[6] == 0.0                           # LED 7: no shift
    others = np.delete(shift, [3, 6])
    assert np.all((others >= 1.0) & (others <= 5.0))  # a few nm
    assert shift[3] == shift.max()
    assert np.all(peak_shift_nm(np.full(10, 3600.0)) <= MAX_SHIFT_NM)


def test_drift_grows_monotonically_and_saturates():
    t = np.array([0, 10, 11, 60, 600, 1800, 3600, 7200.0])
    led4 = peak_shift_nm(t, MAX_SHIFT_NM[3])
    assert np.all(np.diff(led4) >= 0) and led4[1] == 0 and 0 < led4[2] < 0.01
    assert led4[-1] == pytest.approx(7.0, abs=0.01)


def test_led10_fades_after_long_on_time():
    assert fade_factor(0) == fade_factor(2400) == 1.0
    assert fade_factor(3600) < 0.2


# ---------------------------------------------------------------------------------------------- firmware
def _emu(**kw) -> tuple[SphereEmulator, FakeClock]:
    clock = FakeClock()
    return SphereEmulator(clock=clock, **kw), clock


def _ok(emu: SphereEmulator, line: bytes) -> bytes:
    reply = emu.handle(line)
    assert reply.startswith(b"OK "), reply
    return reply


@pytest.mark.parametrize("line,code", [
    (b"FOO", P.ErrorCode.UNKNOWN_COMMAND), (b"", P.ErrorCode.UNKNOWN_COMMAND),
    (b"\xff\xfe", P.ErrorCode.UNKNOWN_COMMAND),
    (b"LEVEL 4", P.ErrorCode.ARGUMENT_COUNT), (b"LEVEL 4 1 2", P.ErrorCode.ARGUMENT_COUNT),
    (b"PING 1", P.ErrorCode.ARGUMENT_COUNT), (b"LEVELS 1 2 3", P.ErrorCode.ARGUMENT_COUNT),
    (b"LEVELS", P.ErrorCode.ARGUMENT_COUNT), (b"LEVELS " + b"1 " * 17, P.ErrorCode.ARGUMENT_COUNT),
    (b"LEVEL x 1", P.ErrorCode.NOT_A_NUMBER), (b"LEVEL 4 -1", P.ErrorCode.NOT_A_NUMBER),
    (b"LEVEL 4 0.5", P.ErrorCode.NOT_A_NUMBER), (b"WDOG 1e3", P.ErrorCode.NOT_A_NUMBER),
    (b"LEVEL 11 1", P.ErrorCode.OUT_OF_RANGE), (b"LEVEL 0 1", P.ErrorCode.OUT_OF_RANGE),
    (b"LEVEL 4 65536", P.ErrorCode.OUT_OF_RANGE), (b"LIGHT 2", P.ErrorCode.OUT_OF_RANGE),
    (b"WDOG 99", P.ErrorCode.OUT_OF_RANGE), (b"WDOG 3600001", P.ErrorCode.OUT_OF_RANGE),
    (b"LEDTIME? 11", P.ErrorCode.OUT_OF_RANGE),
])
def test_error_codes(line, code):
    emu, _ = _emu()
    reply = emu.handle(line)
    assert reply.startswith(b"ERR %d " % code) and reply.endswith(b"\n"), reply
    with pytest.raises(P.DeviceReply):
        P.COMMANDS["ping"].decode(reply)


def test_lenient_request_forms():
    emu, _ = _emu()
    assert _ok(emu, b"level  4   100") == b"OK LEVEL 4 100\n"
    assert _ok(emu, b"idn?") == b"OK IDN DRGB-SPHERE10-EMU 1.1.0 EMU-0001\n"


def test_every_command_round_trips_through_the_emulator():
    emu, _ = _emu()
    for cmd in P.TABLE:
        request, _ = cmd.example_bytes()
        reply = emu.handle(request.rstrip(b"\n"))
        cmd.decode(reply, cmd.example[0])        # well-formed, right keyword, echoes match


def test_over_temperature_refuses_light():
    emu, _ = _emu()
    emu.ambient_c = emu._temp = 50.0
    assert emu.handle(b"LIGHT 1").startswith(b"ERR 7 ")
    assert not emu.snapshot().light_on


def test_over_temperature_switches_a_lit_sphere_off():
    emu, clock = _emu(watchdog_s=3600)
    _ok(emu, b"LEVELS " + b"65535 " * 9 + b"65535")
    _ok(emu, b"LIGHT 1")
    emu.ambient_c = 40.0                             # 40 + 10 x 1.2 = 52 C steady state > 45 C
    clock.advance(1200)
    snap = emu.snapshot()
    assert not snap.light_on and snap.temperature_c > 45


# ---------------------------------------------------------------------------------------------- physics
def test_snapshot_interface():
    emu, _ = _emu()
    snap = emu.snapshot()
    assert isinstance(snap, SphereSnapshot)
    for arr in (snap.levels, snap.on_time_s, snap.peak_shift_nm):
        assert isinstance(arr, np.ndarray) and arr.shape == (10,)
    assert isinstance(snap.temperature_c, float) and snap.light_on is False
    with pytest.raises(FrozenInstanceError):
        snap.light_on = True                         # frozen


def test_levels_emit_only_with_master_on():
    emu, clock = _emu(watchdog_s=3600)
    _ok(emu, b"LEVEL 4 32768")
    assert np.all(emu.snapshot().levels == 0)
    _ok(emu, b"LIGHT 1")
    snap = emu.snapshot()
    assert snap.light_on and snap.levels[3] == pytest.approx(0.5, abs=1e-4) and snap.levels.sum() == snap.levels[3]
    _ok(emu, b"LIGHT 0")
    assert np.all(emu.snapshot().levels == 0)
    assert emu.commanded_levels()[3] == pytest.approx(0.5, abs=1e-4)


def test_on_time_drift_and_led10_fade_with_a_fake_clock():
    emu, clock = _emu(watchdog_s=3600)
    _ok(emu, b"LEVELS 0 0 0 65535 0 0 65535 0 0 65535")
    _ok(emu, b"LIGHT 1")
    clock.advance(9.0)
    snap = emu.snapshot()
    assert snap.on_time_s[3] == pytest.approx(9.0) and np.all(snap.peak_shift_nm == 0)
    assert emu.handle(b"LEDTIME? 4") == b"OK LEDTIME 4 9.000\n"
    assert emu.handle(b"ONTIME?") == b"OK ONTIME 9.000\n"
    for _ in range(36):                              # an hour, with keepalives
        clock.advance(99.75)
        _ok(emu, b"PING")
    snap = emu.snapshot()
    assert snap.on_time_s[3] == pytest.approx(3600.0)
    assert snap.peak_shift_nm[3] == pytest.approx(6.87, abs=0.05)
    assert snap.peak_shift_nm[6] == 0.0
    assert snap.levels[9] < 0.2                      # LED 10 nearly died (thesis 4.3.2)
    assert snap.temperature_c > 26.0
    # off and on again: on-time and drift start over, LED 10's loss stays
    _ok(emu, b"LIGHT 0")
    clock.advance(600)
    _ok(emu, b"LIGHT 1")
    clock.advance(1)
    snap = emu.snapshot()
    assert snap.on_time_s[3] == pytest.approx(1.0) and snap.peak_shift_nm[3] == 0.0
    assert snap.levels[9] < 0.2 and emu.output_health()[9] < 0.2


def test_temperature_rises_with_power_and_cools():
    emu, clock = _emu(watchdog_s=3600)
    t0 = emu.snapshot().temperature_c
    _ok(emu, b"LEVELS " + b"65535 " * 9 + b"65535")
    _ok(emu, b"LIGHT 1")
    clock.advance(300)
    hot = emu.snapshot().temperature_c
    assert hot > t0 + 5
    assert float(emu.handle(b"TEMP?").split()[2]) == pytest.approx(hot, abs=0.01)
    _ok(emu, b"LIGHT 0")
    clock.advance(1200)
    assert emu.snapshot().temperature_c < t0 + 0.5


def test_light_dose_is_level_times_seconds():
    emu, clock = _emu(watchdog_s=3600)
    _ok(emu, b"LEVELS 65535 32768 0 0 0 0 0 0 0 0")
    _ok(emu, b"LIGHT 1")
    clock.advance(10)
    dose = emu.light_dose()
    assert dose[0] == pytest.approx(10.0) and dose[1] == pytest.approx(5.0, abs=1e-3) and dose[2:].sum() == 0


# ---------------------------------------------------------------------------------------------- watchdog
def test_watchdog_switches_off_at_the_exact_moment():
    emu, clock = _emu(watchdog_s=30)
    _ok(emu, b"LEVEL 1 65535")
    _ok(emu, b"LIGHT 1")
    clock.advance(29.0)
    assert emu.snapshot().light_on
    clock.advance(20.0)
    snap = emu.snapshot()
    assert not snap.light_on and np.all(snap.levels == 0) and np.all(snap.on_time_s == 0)
    assert emu.light_dose()[0] == pytest.approx(30.0)   # lit for exactly the watchdog time
    assert emu.watchdog_tripped
    assert b"trip=1" in emu.handle(b"STATUS?")
    assert emu.handle(b"LEVELS?") == b"OK LEVELS 0 0 0 0 0 0 0 0 0 0\n"
    _ok(emu, b"LIGHT 1")
    assert b"trip=0" in emu.handle(b"STATUS?")


def test_any_request_restarts_the_watchdog_and_wdog_sets_it():
    emu, clock = _emu(watchdog_s=30)
    _ok(emu, b"LEVEL 1 65535")
    _ok(emu, b"LIGHT 1")
    for _ in range(5):
        clock.advance(25)
        emu.handle(b"NOT A COMMAND")                 # even an erroneous line counts
    assert emu.snapshot().light_on
    _ok(emu, b"WDOG 1000")
    assert emu.handle(b"WDOG?") == b"OK WDOG 1000\n"
    clock.advance(1.5)
    assert not emu.snapshot().light_on


def test_watchdog_with_a_short_real_time():
    emu = SphereEmulator(watchdog_s=1.0)
    try:
        port = emu.start()
        sphere = LedSphere(port, timeout=OK_TIMEOUT).open()
        sphere.set_level(2, 1.0)
        sphere.on()
        assert emu.snapshot().levels[1] == 1.0
        sphere.close(leave_on=True)                  # host gone silent (no shutdown)
        deadline = time.monotonic() + 10
        while emu.snapshot().light_on and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not emu.snapshot().light_on and emu.watchdog_tripped
    finally:
        emu.stop()


# ------------------------------------------------------------------- over a serial transport (pty, socket://)
@pytest.fixture(params=TRANSPORTS)
def lab(request):
    clock = FakeClock()
    emu = SphereEmulator(watchdog_s=30, clock=clock, transport=request.param)
    port = emu.start()
    assert_port(port, request.param)
    yield emu, clock, port
    emu.stop()


def test_end_to_end_over_the_serial_transport(lab):
    emu, clock, port = lab
    assert emu.port == port
    with LedSphere(port, timeout=OK_TIMEOUT) as sphere:
        assert sphere.identify()["model"] == "DRGB-SPHERE10-EMU"
        assert sphere.channel_count() == 10
        sphere.apply(LightSource((1, 6, 8), (1.0, 0.5, 0.25)))
        sphere.set_level(10, 0.75)
        assert sphere.level(10) == pytest.approx(0.75, abs=1e-4)
        sphere.on()
        clock.advance(5.0)
        snap = emu.snapshot()
        expected = np.zeros(10)
        expected[[0, 5, 7, 9]] = [1.0, 0.5, 0.25, 0.75]
        assert snap.levels == pytest.approx(expected, abs=1e-4)
        assert sphere.device_on_time_s() == pytest.approx(5.0)
        assert sphere.led_on_time_s(1) == pytest.approx(5.0)
        assert sphere.set_watchdog(10) == 10.0 and sphere.watchdog_s() == 10.0
        sphere.keepalive()
        status = sphere.status()
        assert status["light_on"] and status["faulty_leds"] == [] and not status["watchdog_tripped"]
        assert status["levels"] == pytest.approx(list(expected), abs=1e-4)
        assert 20 < sphere.temperature_c() < 40
        sphere.off()
        assert not sphere.light_on()
        sphere.on()
    snap = emu.snapshot()
    assert not snap.light_on and np.all(snap.levels == 0) and np.all(emu.commanded_levels() == 0)


def test_context_manager_leaves_leds_off_on_exception(lab):
    emu, clock, port = lab
    with pytest.raises(ZeroDivisionError):
        with LedSphere(port, timeout=OK_TIMEOUT) as sphere:
            sphere.apply(LightSource((2, 3)))
            sphere.on()
            assert emu.snapshot().levels.sum() == 2.0
            raise ZeroDivisionError   # an error inside the with block
    assert emu.snapshot().levels.sum() == 0 and not emu.snapshot().light_on


FAULT_CASES = [
    ("garbled", {}, "garbled", False),
    ("slow", {"delay_s": 0.5}, "timeout", False),          # delay > TIMEOUT: both attempts time out
    ("no_reply", {}, "timeout", False),                     # reply lost; the firmware still obeys
    ("no_reply", {"execute": False}, "timeout", True),      # firmware hung: only the watchdog helps
    ("disconnect", {}, "disconnected", True),               # pty closed: only the watchdog helps
    ("led_fail", {"led": 2, "mode": "dark"}, "fault", False),
    ("led_fail", {"led": 2, "mode": "error"}, "device", False),
]


@pytest.mark.parametrize("fault,params,kind,needs_watchdog", FAULT_CASES,
                         ids=[f"{c[0]}-{c[1].get('mode', c[1].get('execute', ''))}" for c in FAULT_CASES])
def test_each_fault_gives_sphere_error_and_leds_end_off(lab, fault, params, kind, needs_watchdog):
    emu, clock, port = lab
    started = None
    with pytest.raises(SphereError) as info:
        with LedSphere(port, timeout=OK_TIMEOUT) as sphere:
            sphere.set_level(1, 1.0)
            sphere.on()
            assert emu.snapshot().levels[0] == 1.0
            sphere.timeout = TIMEOUT
            emu.inject(fault, **params)
            started = time.monotonic()
            sphere.apply(LightSource((1, 2)))
            sphere.identify()
    elapsed = time.monotonic() - started
    err = info.value
    assert err.kind == kind, err
    assert "\n" not in str(err)
    # nothing hangs: the failing exchange takes two attempts of TIMEOUT, then the exit's two off-requests (about
    # 6 x TIMEOUT; a hang guard far above it, since a loaded machine stretches it; the attempts themselves are
    # checked byte for byte in test_led_sphere_driver.py)
    assert elapsed < 60.0
    if needs_watchdog:
        clock.advance(emu.watchdog_s + 1.0)
    snap = emu.snapshot()
    assert not snap.light_on and np.all(snap.levels == 0), (fault, snap)


def test_fault_cleared_works_again(lab):
    emu, clock, port = lab
    emu.inject("garbled")
    with pytest.raises(SphereError):
        with LedSphere(port, timeout=TIMEOUT) as sphere:
            sphere.identify()
    # the switch-off written on close is still answered in garbage: let the emulator take it before the fault
    # is cleared, or that late garbage lands in the next connection's reply (a race under load, not a driver bug)
    settle_until = time.monotonic() + 5.0
    while not (emu.requests and emu.requests[-1].startswith(b"LIGHT 0")) and time.monotonic() < settle_until:
        time.sleep(0.01)
    emu.inject(None)
    with LedSphere(port, timeout=OK_TIMEOUT) as sphere:
        assert sphere.identify()["serial"] == "EMU-0001"


def test_overlong_request_over_the_transport(lab):
    emu, clock, port = lab
    import serial
    with serial.serial_for_url(port, baudrate=P.BAUDRATE, timeout=1.0) as raw:
        raw.write(b"X" * 200 + b"\nPING\n")
        assert raw.readline() == b"ERR 5 line longer than 96 bytes\n"
        assert raw.readline() == b"OK PING\n"
        raw.write(b"PING\r\n")
        assert raw.readline() == b"OK PING\n"


def test_inject_rejects_unknown_faults():
    emu, _ = _emu()
    with pytest.raises(ValueError):
        emu.inject("meteor")
    with pytest.raises(ValueError):
        emu.inject("led_fail", led=11)
    with pytest.raises(ValueError):
        emu.inject("slow", delay_s=0)


def test_a_faulty_led_outside_the_preset_does_not_block(lab):
    emu, clock, port = lab
    emu.inject("led_fail", led=10, mode="dark")
    with LedSphere(port, timeout=OK_TIMEOUT) as sphere:
        sphere.apply(LightSource((1, 6, 8)))
        sphere.on()
        assert sphere.faulty_leds() == []
        assert emu.snapshot().levels[[0, 5, 7]] == pytest.approx([1, 1, 1])
        with pytest.raises(SphereError, match="LED 10 reports a fault"):
            sphere.set_levels([0] * 9 + [1])
        assert not emu.snapshot().light_on


# ---------------------------------------------------------------------------------------------- on-time limit
def test_on_limit_switches_off_at_the_exact_moment_whatever_arrives_meanwhile():
    emu, clock = _emu(watchdog_s=3600)
    _ok(emu, b"LEVEL 1 65535")
    t_on = clock()
    assert emu.handle(b"ON 2500") == b"OK ON 2500\n"
    for _ in range(4):                               # polls, pings and a repeated ON never extend the period
        clock.advance(0.5)
        for line in (b"STATUS?", b"PING", b"ON 2500", b"LIGHT 1"):
            _ok(emu, line)
    assert emu.snapshot().light_on
    clock.advance(1.0)
    snap = emu.snapshot()
    assert not snap.light_on and emu.watchdog_tripped and b"trip=1" in emu.handle(b"STATUS?")
    assert emu.light_dose()[0] == pytest.approx(2.5)
    (lit,) = emu.light_record()
    assert (lit.t_on, lit.t_off, lit.ended_by) == (t_on, pytest.approx(t_on + 2.5), "on-time limit")
    assert emu.commanded_levels()[0] == 1.0          # LIGHT 0 semantics: levels kept


def test_light_0_ends_the_limit_and_a_new_on_starts_a_new_one():
    emu, clock = _emu(watchdog_s=3600)
    _ok(emu, b"LEVEL 2 65535")
    _ok(emu, b"ON 1000")
    clock.advance(0.5)
    _ok(emu, b"LIGHT 0")
    clock.advance(0.1)
    _ok(emu, b"ON 1000")
    clock.advance(0.9)
    assert emu.snapshot().light_on                  # 0.9 s into the second period
    clock.advance(0.2)
    assert not emu.snapshot().light_on
    assert [(i.duration_s, i.ended_by) for i in emu.light_record()] == [
        (pytest.approx(0.5), "LIGHT 0"), (pytest.approx(1.0), "on-time limit")]


def test_light_record_splits_on_level_changes_and_names_the_cause():
    emu, clock = _emu(watchdog_s=30)
    _ok(emu, b"LEVEL 1 65535")
    _ok(emu, b"LIGHT 1")
    clock.advance(1)
    _ok(emu, b"LEVEL 2 32768")
    clock.advance(1)
    _ok(emu, b"ALLOFF")
    _ok(emu, b"LEVEL 3 65535")
    clock.advance(31)                                # the watchdog ends the third period
    record = emu.light_record()
    assert [i.ended_by for i in record] == ["levels changed", "ALLOFF", "watchdog"]
    assert record[0].t_off == record[1].t_on and record[1].levels[1] == pytest.approx(0.5, abs=1e-4)
    assert record[2].duration_s == pytest.approx(30.0)


def test_old_firmware_does_not_know_on():
    emu, _ = _emu(firmware="1.0.0")
    assert emu.handle(b"ON 1000") == b"ERR 1 unknown command ON\n"
    assert not emu.snapshot().light_on
    assert emu.handle(b"IDN?") == b"OK IDN DRGB-SPHERE10-EMU 1.0.0 EMU-0001\n"
    with pytest.raises(ValueError):
        SphereEmulator(firmware="new")


def test_wire_faults_for_some_keywords_only(lab):
    emu, clock, port = lab
    emu.inject("no_reply", keywords=["ON"])          # obeyed, not answered
    emu.inject("ignore", keywords=["light"])         # LIGHT ... neither obeyed nor answered
    sphere = LedSphere(port, timeout=0.2).open()
    try:
        sphere.set_level(1, 1.0)                     # LEVEL is answered
        with pytest.raises(SphereError, match="no reply to 'ON 10000'") as info:
            sphere.on()
    finally:
        sphere.close(leave_on=True)
    assert info.value.light == "off" and "every LED was set to 0 (ALLOFF answered), so nothing is lit, but the " \
        "light switch did not answer: LED sphere" in str(info.value) and "no reply to 'LIGHT 0'" in str(info.value)
    snap = emu.snapshot()
    assert snap.light_on and not snap.levels.any()   # master still on, but ALLOFF (answered) darkened it
    assert [i.ended_by for i in emu.light_record()] == ["ALLOFF"]
    with pytest.raises(ValueError, match="unknown keywords"):
        emu.inject("garbled", keywords=["NOPE"])
