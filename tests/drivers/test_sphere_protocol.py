"""The sphere protocol suite on both spheres (issue 38): the emulator and the reference firmware on a simulated
ATmega2560 (tests/sphere_backends.py). Every reply is compared byte for byte with the emulator's, the driver's
exchanges of tests/drivers/test_led_sphere_driver.py run against each sphere, and the driver works end to end.

Where the two legitimately differ the test says so (and docs/led-sphere-protocol.md, "Reference firmware"):
the identity (model and serial number), the temperature (the emulator models it from the emitted power, the
firmware measures an LM35) and the on-times (each sphere's own clock)."""
from __future__ import annotations

import re

import numpy as np
import pytest
import serial
from sphere_fakes import FakeClock
from test_led_sphere_driver import EXCHANGES

from dualrgb.drivers.led_sphere import LedSphere
from dualrgb.drivers.led_sphere import protocol as P
from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator
from dualrgb.simulation.lightsource import LightSource

OK_TIMEOUT = 2.0        # only matters when something is wrong (a loaded machine must not fail a test)

# request lines, sent in this order to a fresh sphere; the replies must be the emulator's, byte for byte
CORPUS = [
    *[cmd.example_bytes()[0].rstrip(b"\n") for cmd in P.TABLE],
    # ERR 1: unknown, empty, not ASCII, control characters, near misses
    b"FOO", b"", b"   ", b"\t", b"\xff\xfe", b"\x00", b"PING\x00", b"\x01PING", b"ABCDEFGHIJKLMNOPQRSTUVWXYZ",
    b"IDN", b"IDN??", b"LEVELSX", b"\x7fPING",
    # ERR 2: argument count
    b"LEVEL 4", b"LEVEL 4 1 2", b"PING 1", b"STATUS? x", b"LEVELS 1 2 3", b"LEVELS", b"LEVELS " + b"1 " * 17,
    b"LEVELS " + b"1 " * 16, b"LEVELS " + b"1 " * 11, b"ON", b"WDOG 1 2",
    # ERR 3: not an unsigned integer (checked before any range)
    b"LEVEL x 1", b"LEVEL 4 -1", b"LEVEL 4 0.5", b"WDOG 1e3", b"LEVEL 12345678 1", b"LEVEL 4 99999999",
    b"LEVELS 1 2 x 4 5 6 7 8 9 10", b"LEVELS 70000 x 0 0 0 0 0 0 0 0", b"LEVEL 99 x", b"ON +100",
    # ERR 4: ranges (the table's 1..16 for LED numbers, then the sphere's 1..10)
    b"LEVELS 70000 0 0 0 0 0 0 0 0 0", b"LEVEL 11 1", b"LEVEL 0 1", b"LEVEL 17 1", b"LEVEL 16 1", b"LEVEL 4 65536",
    b"LIGHT 2", b"WDOG 99", b"WDOG 3600001", b"ON 99", b"ON 3600001", b"LEDTIME? 11", b"LEVEL? 0", b"LEVEL? 16",
    b"LEVEL 9999999 1",
    # lenient forms: case, runs of spaces and tabs, leading zeros, other whitespace
    b"idn?", b"Idn?", b"level  4   100", b"  LEVEL\t4 \t 0000200  ", b"LEVEL 4 0000000", b"LEVEL? 4", b"ping\x1c",
    b"PING\r", b"PING\x0b", b"LIGHT\x1f0", b"LEVEL 10 65535", b"LEVELS?", b"ALLOFF", b"LEVELS?",
    # state: watchdog bounds, the light, the levels it keeps
    b"WDOG 100", b"WDOG 3600000", b"WDOG?", b"WDOG 30000", b"LIGHT 0", b"LIGHT?", b"FAULT?",
    b"LEVELS 0 0 0 0 0 0 0 0 0 0", b"LIGHT 1", b"LIGHT?", b"STATUS?", b"ON 3600000", b"LEVEL 3 1", b"LEVEL? 3",
    b"LIGHT 0", b"LEVEL? 3", b"ALLOFF", b"STATUS?", b"ONTIME?", b"LEDTIME? 3",
]


def _masked(reply: bytes) -> str:
    """A reply with what may differ between the spheres masked: identity, temperature, on-times."""
    text = reply.decode("ascii", "backslashreplace")
    text = re.sub(r"^OK IDN \S+ (\S+) \S+", r"OK IDN <model> \1 <serial>", text)
    text = re.sub(r"(OK TEMP |temp=)-?\d+\.\d\d", r"\1<celsius>", text)
    return re.sub(r"(OK ONTIME |ontime=|OK LEDTIME \d+ )\d+\.\d{3}", r"\1<s>", text)


def _open(backend) -> serial.Serial:
    return serial.serial_for_url(backend.port, baudrate=P.BAUDRATE, timeout=OK_TIMEOUT)


def test_every_reply_is_the_emulators_byte_for_byte(sphere_backend):
    reference = SphereEmulator(clock=FakeClock())
    with _open(sphere_backend) as port:
        for line in CORPUS:
            port.write(line + b"\n")
            got = bytes(port.readline())
            expected = reference.handle(line)
            assert _masked(got) == _masked(expected), (line, got, expected)
            if got.startswith(b"OK IDN "):
                assert got == f"OK IDN {sphere_backend.model} {P.FIRMWARE_VERSION} {sphere_backend.serial}\n"\
                    .encode()
            if got.startswith(b"OK TEMP "):          # the emulator models it, the firmware measures it (25 C)
                assert 20.0 <= float(got.split()[2]) <= 30.0


def test_framing_over_the_wire(sphere_backend):
    """Overlong lines get ERR 5 once and are skipped to their end; CR LF and 95-byte lines are requests."""
    longest = b"LEVELS" + b" " * 70 + b"0 0 0 0 0 0 0 0 0 0"
    assert len(longest) == P.MAX_REQUEST_BYTES - 1
    with _open(sphere_backend) as port:
        port.write(b"X" * 200 + b"\nPING\n")
        assert port.readline() == b"ERR 5 line longer than 96 bytes\n"
        assert port.readline() == b"OK PING\n"
        port.write(b"PING\r\n")
        assert port.readline() == b"OK PING\n"
        port.write(longest + b"\n")
        assert port.readline() == b"OK LEVELS 0 0 0 0 0 0 0 0 0 0\n"
        port.write(longest + b" \n")
        assert port.readline() == b"ERR 5 line longer than 96 bytes\n"
        port.write(b"IDN?\n")
        assert port.readline().startswith(b"OK IDN ")


_DRIVER_CASES = [(i, e) for i, e in enumerate(EXCHANGES) if not any(r and r.startswith(b"ERR 1") for _, r in e[1])]


class _Recording:
    """A serial port that remembers what was written (the driver's requests)."""

    def __init__(self, port: serial.Serial):
        self._port = port
        self.written: list[bytes] = []

    def write(self, data: bytes) -> int:
        self.written.append(bytes(data))
        return self._port.write(data)

    def __getattr__(self, name: str):
        return getattr(self._port, name)


@pytest.mark.parametrize("case", _DRIVER_CASES, ids=[f"{e[1][0][0].decode().strip()}#{i}" for i, e in _DRIVER_CASES])
def test_the_drivers_exchanges_run_against_the_sphere(sphere_backend, case):
    """tests/drivers/test_led_sphere_driver.py's byte-exact exchanges (firmware 1.1: not the 1.0 fallback): the
    driver sends the same bytes to the real sphere and takes its replies (their values are the sphere's state)."""
    _, (call, pairs, _) = case
    with _open(sphere_backend) as raw:
        for line in (b"ALLOFF", b"LIGHT 0"):
            raw.write(line + b"\n")
            assert raw.readline().startswith(b"OK "), line
        port = _Recording(raw)
        sphere = LedSphere(port, timeout=OK_TIMEOUT)
        try:
            call(sphere)
            assert port.written == [request for request, _ in pairs]
        finally:
            sphere.close()


def test_end_to_end_with_the_driver(sphere_backend):
    backend = sphere_backend
    with LedSphere(backend.port, timeout=OK_TIMEOUT) as sphere:
        assert sphere.identify() == {"model": backend.model, "firmware": P.FIRMWARE_VERSION, "serial": backend.serial}
        assert sphere.channel_count() == 10
        sphere.apply(LightSource((1, 6, 8), (1.0, 0.5, 0.25)))
        sphere.set_level(10, 0.75)
        assert sphere.level(10) == pytest.approx(0.75, abs=1e-4)
        t0 = backend.clock()
        sphere.on()
        backend.wait(0.3)
        expected = np.zeros(10)
        expected[[0, 5, 7, 9]] = [1.0, 0.5, 0.25, 0.75]
        assert backend.emitted() == pytest.approx(expected, abs=1e-4)      # at the pins: the duty cycle
        assert sphere.device_on_time_s() >= 0.3 and sphere.led_on_time_s(1) >= 0.3
        assert sphere.led_on_time_s(2) == 0.0
        assert sphere.set_watchdog(10) == 10.0 and sphere.watchdog_s() == 10.0
        sphere.keepalive()
        status = sphere.status()
        assert status["light_on"] and status["faulty_leds"] == [] and not status["watchdog_tripped"]
        assert status["levels"] == pytest.approx(list(expected), abs=1e-4)
        assert 20 < sphere.temperature_c() < 40
        sphere.off()
        assert not sphere.light_on()
        sphere.on()
    (span,) = backend.wait_dark(t0)[:1]
    assert span.t_off is not None
    assert not backend.emitted().any()
    assert backend.exchange(b"LEVELS?") == b"OK LEVELS 0 0 0 0 0 0 0 0 0 0\n"


def test_context_manager_leaves_the_sphere_dark_on_exception(sphere_backend):
    backend = sphere_backend
    t0 = backend.clock()
    with pytest.raises(ZeroDivisionError):
        with LedSphere(backend.port, timeout=OK_TIMEOUT) as sphere:
            sphere.apply(LightSource((2, 3)))
            sphere.on()
            backend.wait(backend.settle_s)
            assert backend.emitted().sum() == pytest.approx(2.0)
            raise ZeroDivisionError
    assert backend.wait_dark(t0)[-1].t_off is not None
    assert backend.exchange(b"STATUS?").startswith(b"OK STATUS light=0 ")


def test_levels_are_exact_at_the_pins(sphere_backend):
    """Level p emits p / 65535 of the time (firmware: the PWM duty measured over whole periods)."""
    backend = sphere_backend
    pwms = [1, 164, 1000, 16384, 32768, 49151, 65534, 65535, 0, 7]
    line = b"LEVELS " + b" ".join(b"%d" % p for p in pwms)
    assert backend.exchange(line) == b"OK " + line + b"\n"
    assert backend.exchange(b"LIGHT 1") == b"OK LIGHT 1\n"
    backend.wait(backend.settle_s)
    assert backend.emitted() == pytest.approx(np.array(pwms) / 65535, abs=2e-5)
    assert backend.exchange(b"LIGHT 0") == b"OK LIGHT 0\n"
