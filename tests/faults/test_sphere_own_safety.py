"""The sphere's own safety (issue 38), on both spheres: the emulator and the reference firmware on a simulated
ATmega2560 (tests/sphere_backends.py). Faults through the driver end in one SphereError and a dark sphere; the
ON <ms> limit and the watchdog switch off by themselves at their moment, whatever arrives meanwhile, also when the
host is killed; over-temperature and LED faults as the protocol says; on the firmware, every reset (brown-out,
watchdog, reset pin, power) leaves the pins dark at once.

Light is judged on the sphere's own clock: the emulator's light record, the firmware's PWM pins (the harness's
log, simulated time). The firmware's two light-off times go to build/firmware-check.json (make firmware-check)."""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from sphere_backends import fault_backends, firmware_only

from dualrgb.drivers.led_sphere import LedSphere, SphereError
from dualrgb.simulation.lightsource import LightSource

ROOT = Path(__file__).resolve().parents[2]
OK_TIMEOUT = 2.0        # happy paths: only matters when something is wrong
TIMEOUT = 0.2           # fault cases: the time they take
WATCHDOG_S = 1.0
CAP_S = 1.0             # the ON limit and the watchdog of the two measured cases: the light is off within it
TICK_S = 0.001          # the firmware counts its limits in 1 ms ticks, from the tick at or before their start
EPS = 1e-9              # the emulator's float clock
PINS = pytest.mark.parametrize("sphere_backend", fault_backends("light safety"), indirect=True)

FAULT_CASES = [
    ("garbled", {}, "garbled", False),
    ("slow", {"delay_s": 0.5}, "timeout", False),          # later than TIMEOUT: both attempts time out
    ("no_reply", {}, "timeout", False),                     # the reply is lost; the sphere obeys
    ("hang", {}, "timeout", True),                          # the request is lost: only the watchdog helps
    ("unplug", {}, "disconnected", True),                   # the cable pulled: only the watchdog helps
    ("dark", {"led": 2}, "fault", False),                   # LED 2 open: driven, no current
    ("error", {"led": 2}, "device", False),                 # LED 2's driver reports a fault: ERR 6
]


def _inject(backend, fault: str, params: dict) -> None:
    if fault in ("dark", "error"):
        backend.fail_led(params["led"], fault)
    elif fault == "unplug":
        backend.unplug()
    else:
        backend.wire(fault, **params)


def _status(backend) -> dict[str, str]:
    reply = backend.exchange(b"STATUS?").decode().split()
    assert reply[:2] == ["OK", "STATUS"], reply
    return dict(field.split("=") for field in reply[2:])


@PINS
@pytest.mark.parametrize("fault,params,kind,needs_watchdog", FAULT_CASES, ids=[c[0] for c in FAULT_CASES])
def test_each_fault_gives_one_sphere_error_and_the_sphere_ends_dark(sphere_backend, fault, params, kind,
                                                                     needs_watchdog):
    backend = sphere_backend
    t0 = backend.clock()
    with pytest.raises(SphereError) as info:
        with LedSphere(backend.port, timeout=OK_TIMEOUT) as sphere:
            sphere.set_watchdog(WATCHDOG_S)
            sphere.set_level(1, 1.0)
            sphere.on()
            sphere.timeout = TIMEOUT
            _inject(backend, fault, params)
            sphere.apply(LightSource((1, 2)))
            sphere.identify()
    err = info.value
    assert err.kind == kind, err
    assert "\n" not in str(err)
    spans = backend.wait_dark(t0)
    assert spans and spans[-1].t_off is not None
    if needs_watchdog:                              # the sphere's own watchdog, counted from its last request
        assert spans[-1].t_off - backend.last_request() <= WATCHDOG_S + EPS
    assert not backend.emitted().any()


@PINS
def test_a_cleared_fault_works_again(sphere_backend):
    backend = sphere_backend
    backend.wire("garbled")
    with pytest.raises(SphereError):
        with LedSphere(backend.port, timeout=TIMEOUT) as sphere:
            sphere.identify()
    backend.wait(0.1)                               # the switch-off's late garbage is not the next reply
    backend.clear_faults()
    with LedSphere(backend.port, timeout=OK_TIMEOUT) as sphere:
        assert sphere.identify()["serial"] == backend.serial


@PINS
def test_a_faulty_led_outside_the_preset_does_not_block(sphere_backend):
    backend = sphere_backend
    backend.fail_led(10, "dark")
    with LedSphere(backend.port, timeout=OK_TIMEOUT) as sphere:
        sphere.apply(LightSource((1, 6, 8)))
        sphere.on()
        assert sphere.faulty_leds() == []
        backend.wait(backend.settle_s)
        assert backend.emitted()[[0, 5, 7]] == pytest.approx([1, 1, 1])
        with pytest.raises(SphereError, match="LED 10 reports a fault"):
            sphere.set_levels([0] * 9 + [1])
        assert _status(backend)["light"] == "0"


@PINS
def test_led_faults_as_the_protocol_says(sphere_backend):
    backend = sphere_backend
    backend.fail_led(4, "dark")
    backend.fail_led(6, "error")
    assert backend.exchange(b"FAULT?") == b"OK FAULT 0\n"                 # nothing driven: no fault to see
    assert backend.exchange(b"LEVEL 4 65535") == b"OK LEVEL 4 65535\n"
    assert backend.exchange(b"FAULT?") == b"OK FAULT 0\n"                 # the light is off: not driven
    assert backend.exchange(b"LIGHT 1") == b"OK LIGHT 1\n"
    assert backend.exchange(b"FAULT?") == b"OK FAULT 8\n"                 # reported right after switching on
    assert _status(backend)["fault"] == "8"
    assert backend.exchange(b"LEDTIME? 4") == b"OK LEDTIME 4 0.000\n"     # it emits nothing
    assert backend.exchange(b"LEVEL 6 1") == b"ERR 6 LED 6 driver fault\n"
    assert backend.exchange(b"LEVELS 1 0 0 0 0 1 0 0 0 0") == b"ERR 6 LED 6 driver fault\n"
    assert backend.exchange(b"LEVELS?") == b"OK LEVELS 0 0 0 65535 0 0 0 0 0 0\n"   # all or none
    assert backend.exchange(b"LEVEL 6 0") == b"OK LEVEL 6 0\n"


@PINS
def test_the_on_limit_holds_whatever_arrives_meanwhile(sphere_backend):
    backend = sphere_backend
    assert backend.exchange(b"LEVEL 1 65535") == b"OK LEVEL 1 65535\n"
    t0 = backend.clock()
    assert backend.exchange(b"ON 1000") == b"OK ON 1000\n"
    rounds = 0
    while backend.clock() < t0 + 0.6:               # polls, pings, a repeated ON and LIGHT 1 never extend it
        for line in (b"STATUS?", b"PING", b"ON 1000", b"LIGHT 1"):
            assert backend.exchange(line).startswith(b"OK "), line
        rounds += 1
        backend.wait(0.1)
    (span,) = backend.wait_dark(t0)
    assert rounds >= 2 and 1.0 - 2 * TICK_S <= span.duration(0) <= 1.0 + EPS
    assert _status(backend)["trip"] == "1"
    assert backend.exchange(b"LEVEL? 1") == b"OK LEVEL 1 65535\n"         # levels kept (LIGHT 0 semantics)


@PINS
def test_light_0_ends_the_limit_and_a_new_on_starts_a_new_one(sphere_backend):
    backend = sphere_backend
    backend.exchange(b"LEVEL 2 65535")
    t0 = backend.clock()
    backend.exchange(b"ON 1000")
    backend.wait(0.3)
    assert backend.exchange(b"LIGHT 0") == b"OK LIGHT 0\n"
    backend.wait(0.1)
    assert backend.exchange(b"ON 400") == b"OK ON 400\n"
    first, second = backend.wait_dark(t0)
    assert first.duration(0) < 1.0 and 0.4 - 2 * TICK_S <= second.duration(0) <= 0.4 + EPS
    assert _status(backend)["trip"] == "1"


@PINS
def test_the_watchdog_switches_off_and_zeroes_the_levels(sphere_backend):
    backend = sphere_backend
    for line in (b"WDOG 300", b"LEVEL 1 65535", b"LIGHT 1"):
        assert backend.exchange(line).startswith(b"OK "), line
    t0 = backend.clock() - 0.1
    (span,) = backend.wait_dark(t0)
    assert 0.3 - 2 * TICK_S <= span.t_off - backend.last_request() <= 0.3 + EPS
    assert backend.exchange(b"LEVELS?") == b"OK LEVELS 0 0 0 0 0 0 0 0 0 0\n"
    assert _status(backend)["trip"] == "1"
    assert backend.exchange(b"LIGHT 1") == b"OK LIGHT 1\n"
    assert _status(backend)["trip"] == "0"


@PINS
def test_any_request_line_restarts_the_watchdog(sphere_backend):
    backend = sphere_backend
    for line in (b"WDOG 400", b"LEVEL 1 65535", b"LIGHT 1"):
        backend.exchange(line)
    t0 = backend.clock() - 0.1
    for _ in range(5):
        backend.wait(0.2)
        assert backend.exchange(b"NOT A COMMAND").startswith(b"ERR 1 ")      # an error restarts it too
    assert backend.spans(t0)[-1].t_off is None
    (span,) = backend.wait_dark(t0)
    assert span.t_off - backend.last_request() <= 0.4 + EPS


@PINS
def test_over_temperature_refuses_the_light_and_switches_a_lit_sphere_off(sphere_backend):
    backend = sphere_backend
    backend.exchange(b"LEVEL 3 65535")
    backend.set_temperature(50.0)
    assert backend.exchange(b"LIGHT 1") == b"ERR 7 temperature 50.0 C, light stays off\n"
    assert backend.exchange(b"ON 1000") == b"ERR 7 temperature 50.0 C, light stays off\n"
    assert _status(backend)["light"] == "0"
    backend.set_temperature(25.0)
    t0 = backend.clock()
    assert backend.exchange(b"LIGHT 1") == b"OK LIGHT 1\n"
    backend.wait_lit(t0)
    backend.set_temperature(50.0)
    assert backend.wait_dark(t0)[-1].t_off is not None
    status = _status(backend)
    assert status["light"] == "0" and status["trip"] == "0"         # the emulator's rule: no trip for heat


DEAD_HOST = """
import os, signal, sys, time
from dualrgb.drivers.led_sphere import LedSphere
from dualrgb.simulation.lightsource import LightSource
port, limit, watchdog, pings = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
sphere = LedSphere(port, timeout=2.0).open()
sphere.set_watchdog(watchdog)
sphere.apply(LightSource((1, 6, 8)))
sphere.on(max_on_s=limit)
for _ in range(pings):                  # mid-exposure: a long limit, kept alive...
    time.sleep(0.1)
    sphere.keepalive()
print("lit", flush=True)
os.kill(os.getpid(), signal.SIGKILL)    # ...then the host dies with the light on
"""


def _host_dies(backend, limit_s: float, watchdog_s: float, pings: int) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-c", DEAD_HOST, backend.port, str(limit_s), str(watchdog_s),
                           str(pings)], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == -9 and proc.stdout == "lit\n", proc


@PINS
def test_a_dead_host_leaves_the_light_to_the_on_limit(sphere_backend, record_firmware_figure):
    """kill -9 right after ON: the sphere's own limit ends the exposure (the host's supervisor died with it)."""
    backend = sphere_backend
    t0 = backend.clock()
    _host_dies(backend, CAP_S, 30.0, 0)
    (span,) = backend.wait_dark(t0)
    lit = span.duration(0)
    print(f"[firmware] {backend.name}: the ON limit switched off {lit:.4f} s after the light came on")
    assert CAP_S - 2 * TICK_S <= lit <= CAP_S + EPS
    assert _status(backend)["trip"] == "1"
    if backend.name == "firmware":
        record_firmware_figure("on_limit_off_s", lit)
        record_firmware_figure("cap_s", CAP_S)


@PINS
def test_a_host_vanishing_mid_exposure_leaves_the_light_to_the_watchdog(sphere_backend, record_firmware_figure):
    """A long exposure kept alive by pings, then kill -9: the watchdog ends it WDOG after the last request."""
    backend = sphere_backend
    t0 = backend.clock()
    _host_dies(backend, 60.0, CAP_S, 3)
    (span,) = backend.wait_dark(t0)
    last_request = backend.last_request()
    gone = backend.host_gone(after=last_request) if backend.name == "firmware" else None
    after_request = span.t_off - last_request
    assert CAP_S - 2 * TICK_S <= after_request <= CAP_S + EPS, (span, last_request)
    assert _status(backend)["trip"] == "1"
    if backend.name == "firmware":
        assert gone is not None and last_request < gone < span.t_off, (last_request, gone, span)
        off_s = span.t_off - gone
        print(f"[firmware] the watchdog switched off {off_s:.4f} s after the host vanished "
              f"({after_request:.4f} s after its last request)")
        assert 0 < off_s <= CAP_S
        record_firmware_figure("host_loss_off_s", off_s)
        record_firmware_figure("cap_s", CAP_S)


@PINS
def test_status_polls_never_extend_a_lit_period(sphere_backend):
    """The host's supervisor thread is dead; the GUI's status polls go on (they restart the watchdog): the
    sphere's own limit still ends the lit period."""
    backend = sphere_backend
    stop = threading.Event()
    with LedSphere(backend.port, timeout=OK_TIMEOUT) as sphere:
        sphere.apply(LightSource((1, 6, 8)))
        t0 = backend.clock()
        sphere.on(max_on_s=0.4)
        sphere._supervisor.stop()                   # a host thread that stopped working

        def poll() -> None:
            while not stop.is_set():
                try:
                    sphere.status()
                except SphereError:
                    pass
                stop.wait(0.1)
        poller = threading.Thread(target=poll, daemon=True)
        poller.start()
        try:
            (span,) = backend.wait_dark(t0)
        finally:
            stop.set()
            poller.join(10)
    assert span.duration(0) <= 0.4 + EPS


@pytest.mark.parametrize("sphere_backend", firmware_only(), indirect=True)
@pytest.mark.parametrize("cause,trip", [("brownout", "1"), ("watchdog", "1"), ("external", "1"), ("power", "0")])
def test_a_reset_darkens_the_pins_at_once_and_says_so(sphere_backend, cause, trip):
    """Brown-out (BOD), the chip's watchdog, the reset pin, power: the pins are inputs from the reset on (the
    board's pull-downs: dark); the firmware starts dark, at the power-up state, trip=1 unless it was power-on."""
    backend = sphere_backend
    pins = backend.sim.pins()
    assert all(level == 0 for edges in pins.edges.values() for _, level in edges)   # dark from power-up
    for line in (b"WDOG 60000", b"LEVELS 65535 0 0 0 0 32768 0 65535 0 0", b"ON 60000"):
        assert backend.exchange(line).startswith(b"OK "), line
    t0 = backend.clock()
    backend.wait(backend.settle_s)
    backend.reset(cause)
    backend.clock()                                 # the log is written up to now
    reset_at = max(c for k, c, text in backend.sim.pins().events if k == "E" and text == f"reset {cause}")
    (span,) = backend.wait_dark(t0 - 0.1)
    assert span.t_off is not None and abs(span.t_off * 16e6 - reset_at) <= 1
    backend.wait(0.01)                              # the firmware boots (its first temperature reading: 2 ms)
    status = _status(backend)
    assert (status["light"], status["trip"], status["wdog"]) == ("0", trip, "30000")
    assert backend.exchange(b"LEVELS?") == b"OK LEVELS 0 0 0 0 0 0 0 0 0 0\n"
    time.sleep(0.05)
    assert backend.spans(t0)[-1].t_off is not None                  # and it stays dark


@PINS
def test_the_sphere_command_switches_on_for_its_limit_and_off_on_any_error(sphere_backend, capsys, caplog):
    """`dualrgb sphere` as a technician types it: `on --max-on` ends by the sphere's own limit after the command
    exited; `off` reads the light back; a bad value refused while parsing still leaves the lit sphere dark."""
    from dualrgb.app.cli import main

    backend = sphere_backend
    port = ["sphere", "--port", backend.port, "--timeout", str(OK_TIMEOUT)]
    assert main([*port, "set", "2", "1.0"]) == 0
    t0 = backend.clock()
    assert main([*port, "on", "--max-on", "0.5"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == \
        "light on for at most 0.5 s (the sphere switches it off by itself)"
    (span,) = backend.wait_dark(t0)
    lit = span.duration(0)
    assert lit <= 0.5 + EPS
    if _status(backend)["trip"] != "1":
        # a starved host (this suite beside busy loops) kept the command alive past its 0.5 s wall-clock deadline:
        # the host's own supervisor switched off first, earlier on simavr's slower clock - and said so
        assert any("reached its 0.50 s limit" in r.getMessage() for r in caplog.records), (lit, caplog.text)
    else:
        assert lit >= 0.5 - 2 * TICK_S
    assert main([*port, "on"]) == 0
    assert main([*port, "off"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "all LEDs off, light off (read back)"
    assert main([*port, "on"]) == 0
    t1 = backend.clock()
    with pytest.raises(SystemExit) as info:
        main([*port, "set", "11", "0.5"])
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert info.value.code == 2 and last.endswith("; all LEDs and the light were switched off"), last
    assert backend.wait_dark(t1 - 1.0)[-1].t_off is not None
    assert backend.exchange(b"LEVELS?") == b"OK LEVELS 0 0 0 0 0 0 0 0 0 0\n"
