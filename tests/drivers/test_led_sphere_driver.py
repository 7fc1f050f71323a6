"""LedSphere against scripted serial ports: byte-exact exchanges for every command, retries, late replies, errors,
argument validation, the safe context manager, and a 10 000-frame reply fuzz."""
from __future__ import annotations

import math
import random
import re
from pathlib import Path

import pytest
from sphere_fakes import BrokenSerial, FakeClock, FrameSerial, ScriptedSerial, expected_protocol

from dualrgb.drivers.led_sphere import LedSphere, SphereError
from dualrgb.drivers.led_sphere import protocol as P
from dualrgb.simulation.lightsource import LightSource

DOC = Path(__file__).resolve().parents[2] / "docs" / "led-sphere-protocol.md"

# every switch-off is read back (drivers/led_sphere/switch_off.py): LIGHT? must say the light is off
READ_BACK_OFF = (b"LIGHT?\n", b"OK LIGHT 0\n")

# (driver call, [(request bytes, reply bytes)], expected return value)
EXCHANGES = [
    (lambda s: s.identify(), [(b"IDN?\n", b"OK IDN DRGB-SPHERE10 1.1.0 SN0001\n")],
     {"model": "DRGB-SPHERE10", "firmware": "1.1.0", "serial": "SN0001"}),
    (lambda s: s.channel_count(), [(b"CHANNELS?\n", b"OK CHANNELS 10\n")], 10),
    (lambda s: s.set_level(4, 0.5), [(b"LEVEL 4 32768\n", b"OK LEVEL 4 32768\n")], 32768 / 65535),
    (lambda s: s.set_level(10, 1.0), [(b"LEVEL 10 65535\n", b"OK LEVEL 10 65535\n")], 1.0),
    (lambda s: s.set_level(1, 0), [(b"LEVEL 1 0\n", b"OK LEVEL 1 0\n")], 0.0),
    (lambda s: s.level(4), [(b"LEVEL? 4\n", b"OK LEVEL 4 16384\n")], 16384 / 65535),
    (lambda s: s.set_levels([0, 1, 0, 0, 0, 0.5, 0, 0, 0, 0]),
     [(b"LEVELS 0 65535 0 0 0 32768 0 0 0 0\n", b"OK LEVELS 0 65535 0 0 0 32768 0 0 0 0\n")],
     [0, 1, 0, 0, 0, 32768 / 65535, 0, 0, 0, 0]),
    (lambda s: s.apply(LightSource((1, 6, 8), (1.0, 0.25, 0.75))),
     [(b"LEVELS 65535 0 0 0 0 16384 0 49151 0 0\n", b"OK LEVELS 65535 0 0 0 0 16384 0 49151 0 0\n")],
     [1, 0, 0, 0, 0, 16384 / 65535, 0, 49151 / 65535, 0, 0]),
    (lambda s: s.levels(), [(b"LEVELS?\n", b"OK LEVELS 0 0 0 65535 0 0 0 0 0 1\n")],
     [0, 0, 0, 1, 0, 0, 0, 0, 0, 1 / 65535]),
    (lambda s: s.all_off(), [(b"ALLOFF\n", b"OK ALLOFF\n")], None),
    (lambda s: s.on().max_on_s, [(b"ON 10000\n", b"OK ON 10000\n"), (b"FAULT?\n", b"OK FAULT 0\n")], 10.0),
    (lambda s: s.on(max_on_s=0.2505).device_limit, [(b"ON 251\n", b"OK ON 251\n"), (b"FAULT?\n", b"OK FAULT 0\n")],
     True),
    # firmware 1.0 does not know ON: the watchdog set to the limit is its backstop, then LIGHT 1 (and only that
    # from then on)
    (lambda s: (s.on(max_on_s=2).device_limit, s.on(max_on_s=2).device_limit),
     [(b"ON 2000\n", b"ERR 1 unknown command ON\n"), (b"WDOG 2000\n", b"OK WDOG 2000\n"),
      (b"LIGHT 1\n", b"OK LIGHT 1\n"), (b"FAULT?\n", b"OK FAULT 0\n"),
      (b"WDOG 2000\n", b"OK WDOG 2000\n"), (b"LIGHT 1\n", b"OK LIGHT 1\n"), (b"FAULT?\n", b"OK FAULT 0\n")],
     (False, False)),
    (lambda s: s.off(), [(b"LIGHT 0\n", b"OK LIGHT 0\n"), READ_BACK_OFF], None),
    (lambda s: s.light_on(), [(b"LIGHT?\n", b"OK LIGHT 1\n")], True),
    (lambda s: s.temperature_c(), [(b"TEMP?\n", b"OK TEMP 27.31\n")], 27.31),
    (lambda s: s.device_on_time_s(), [(b"ONTIME?\n", b"OK ONTIME 12.500\n")], 12.5),
    (lambda s: s.led_on_time_s(4), [(b"LEDTIME? 4\n", b"OK LEDTIME 4 8.250\n")], 8.25),
    (lambda s: s.set_watchdog(30), [(b"WDOG 30000\n", b"OK WDOG 30000\n")], 30.0),
    (lambda s: s.set_watchdog(0.25), [(b"WDOG 250\n", b"OK WDOG 250\n")], 0.25),
    (lambda s: s.watchdog_s(), [(b"WDOG?\n", b"OK WDOG 5000\n")], 5.0),
    (lambda s: s.keepalive(), [(b"PING\n", b"OK PING\n")], None),
    (lambda s: s.faulty_leds(), [(b"FAULT?\n", b"OK FAULT 520\n")], [4, 10]),
    (lambda s: s.shutdown(), [(b"ALLOFF\n", b"OK ALLOFF\n"), (b"LIGHT 0\n", b"OK LIGHT 0\n"), READ_BACK_OFF], None),
    # trip=1: the sphere switched its light off by itself (its ON limit or its watchdog) since it was switched on
    (lambda s: s.tripped(), [(b"STATUS?\n", b"OK STATUS light=0 ontime=0.000 temp=25.10 wdog=150 trip=1 fault=0\n")],
     True),
    (lambda s: s.tripped(), [(b"STATUS?\n", b"OK STATUS light=1 ontime=0.500 temp=25.10 wdog=30000 trip=0 fault=0\n")],
     False),
    (lambda s: {k: v for k, v in s.status().items() if k != "port"},
     [(b"STATUS?\n", b"OK STATUS light=1 ontime=2.250 temp=25.10 wdog=30000 trip=0 fault=8\n"),
      (b"LEVELS?\n", b"OK LEVELS 0 0 0 65535 0 0 0 0 0 0\n")],
     {"light_on": True, "levels": [0, 0, 0, 1.0, 0, 0, 0, 0, 0, 0], "temperature_c": 25.1, "on_time_s": None,
      "device_on_time_s": 2.25, "watchdog_s": 30.0, "watchdog_tripped": False, "faulty_leds": [4],
      # lit by someone else 2.25 s ago: the host's 10 s limit applies to it too
      "off_in_s": pytest.approx(7.75, abs=0.1), "off_by": "limit", "max_on_s": 10.0}),
]


@pytest.mark.parametrize("call,pairs,expected", EXCHANGES, ids=[p[1][0][0].decode().strip() + f"#{i}"
                                                                for i, p in enumerate(EXCHANGES)])
def test_byte_exact_exchange(call, pairs, expected):
    with expected_protocol(pairs) as sphere:
        result = call(sphere)
    if isinstance(expected, float):
        assert result == pytest.approx(expected)
    elif isinstance(expected, list) and expected and isinstance(expected[0], (int, float)):
        assert result == pytest.approx(expected)
    else:
        assert result == expected


def test_every_protocol_command_has_a_byte_exact_test():
    sent = {req.split(b" ")[0].strip().decode() for _, pairs, _ in EXCHANGES for req, _ in pairs}
    assert sent == set(P.BY_KEYWORD), f"untested: {set(P.BY_KEYWORD) - sent}"


def test_table_examples_round_trip_and_are_documented():
    doc = DOC.read_text(encoding="utf-8")
    for cmd in P.TABLE:
        request, reply = cmd.example_bytes()
        # the device parses the request back to the example's arguments, the host parses the reply
        parsed_cmd, args = P.parse_request(request.rstrip(b"\n"))
        assert parsed_cmd is cmd and args == {k: P._normalise(v) for k, v in cmd.example[0].items()}
        cmd.decode(reply, cmd.example[0])
        for line in (request, reply):
            assert repr(line)[2:-1] in doc or line.decode().strip() in doc, f"{line!r} not in {DOC.name}"
    for code in P.ErrorCode:
        assert f"ERR {int(code)} " in doc, f"error code {int(code)} not documented"


# ---------------------------------------------------------------------------------------------- timeouts
def test_retries_once_after_a_timeout():
    with expected_protocol([(b"TEMP?\n", None), (b"TEMP?\n", b"OK TEMP 30.00\n")]) as sphere:
        assert sphere.temperature_c() == 30.0


def test_two_timeouts_raise_one_line_sphere_error():
    with expected_protocol([(b"LEVEL 2 65535\n", None), (b"LEVEL 2 65535\n", None)]) as sphere:
        with pytest.raises(SphereError) as info:
            sphere.set_level(2, 1.0)
    err = info.value
    assert isinstance(err, RuntimeError) and err.kind == "timeout"
    assert "\n" not in str(err) and "LEVEL 2 65535" in str(err) and "sent twice" in str(err)


def test_a_fragment_without_terminator_is_a_timeout_then_retry():
    with expected_protocol([(b"PING\n", b"OK PI"), (b"PING\n", b"OK PING\n")]) as sphere:
        sphere.keepalive()


def test_late_reply_to_an_earlier_request_is_skipped():
    # the previous request's reply arrives late, just before this one's; keyword and echo tell them apart
    pairs = [(b"LEVEL? 5\n", b"OK LEVEL 4 100\nOK TEMP 20.00\nOK LEVEL 5 200\n")]
    with expected_protocol(pairs) as sphere:
        assert sphere.level(5) == pytest.approx(200 / 65535)


def test_only_unrelated_replies_is_a_timeout_naming_them():
    pairs = [(b"PING\n", b"OK TEMP 20.00\n"), (b"PING\n", b"OK TEMP 20.00\n")]
    with expected_protocol(pairs) as sphere:
        with pytest.raises(SphereError, match="skipped unrelated replies") as info:
            sphere.keepalive()
    assert info.value.kind == "timeout"


# ---------------------------------------------------------------------------------------------- bad replies
@pytest.mark.parametrize("reply", [b"OK LEVEL 4 70000\n", b"OK LEVEL 4\n", b"KO\n", b"OK LEVEL 4 1 2\n",
                                   b"\xff\xfe\n", b"OK LEVEL\x004 1\n", b"OK BOGUS 1\n", b"ERR x y\n",
                                   b"OK LEVEL 4 -1\n", b"ok level 4 1\n", b"OK LEVEL  4 1\n"])
def test_garbled_reply(reply):
    with expected_protocol([(b"LEVEL? 4\n", reply)]) as sphere:
        with pytest.raises(SphereError) as info:
            sphere.level(4)
    assert info.value.kind == "garbled" and "\n" not in str(info.value)


def test_overlong_reply_is_garbled():
    with expected_protocol([(b"IDN?\n", b"A" * 500)]) as sphere:
        with pytest.raises(SphereError, match="overlong") as info:
            sphere.identify()
    assert info.value.kind == "garbled"


@pytest.mark.parametrize("code", list(P.ErrorCode))
def test_device_error_codes_give_advice(code):
    reply = P.render_error(code, "something")
    with expected_protocol([(b"LEVEL 1 32768\n", reply)]) as sphere:
        with pytest.raises(SphereError) as info:
            sphere.set_level(1, 0.5)
    err = info.value
    assert err.kind == "device" and err.code == code
    assert f"error {int(code)}" in str(err) and P.ERROR_ADVICE[code] in str(err)


def test_a_refused_on_switches_off_and_says_so():
    pairs = [(b"ON 10000\n", P.render_error(P.ErrorCode.OVER_TEMPERATURE, "temperature 46.2 C, light stays off")),
             (b"ALLOFF\n", b"OK ALLOFF\n"), (b"LIGHT 0\n", b"OK LIGHT 0\n"), READ_BACK_OFF]
    with expected_protocol(pairs) as sphere:
        with pytest.raises(SphereError) as info:
            sphere.on()
    err = info.value
    assert err.code == P.ErrorCode.OVER_TEMPERATURE and err.light == "off"
    assert str(err).endswith("all LEDs and the light were switched off")
    assert err.period is not None and err.period.confirmed_off


def test_unknown_device_error_code():
    with expected_protocol([(b"PING\n", b"ERR 99 new firmware\n")]) as sphere:
        with pytest.raises(SphereError, match="unknown error code") as info:
            sphere.keepalive()
    assert info.value.code == 99


def test_fault_after_light_on_switches_off_and_raises():
    pairs = [(b"ON 10000\n", b"OK ON 10000\n"), (b"FAULT?\n", b"OK FAULT 8\n"),
             (b"ALLOFF\n", b"OK ALLOFF\n"), (b"LIGHT 0\n", b"OK LIGHT 0\n"), READ_BACK_OFF]
    with expected_protocol(pairs) as sphere:
        with pytest.raises(SphereError, match="LED 4 reports a fault") as info:
            sphere.on()
    assert info.value.kind == "fault" and info.value.light == "off"
    assert "all LEDs and the light were switched off" in str(info.value)


def test_apply_while_on_checks_faults():
    pairs = [(b"ON 10000\n", b"OK ON 10000\n"), (b"FAULT?\n", b"OK FAULT 0\n"),
             (b"LEVELS 0 65535 0 0 0 0 0 0 0 0\n", b"OK LEVELS 0 65535 0 0 0 0 0 0 0 0\n"),
             (b"FAULT?\n", b"OK FAULT 0\n")]
    with expected_protocol(pairs) as sphere:
        sphere.on()
        sphere.apply(LightSource((2,)))


@pytest.mark.parametrize("fail_on,kind", [("read", "disconnected"), ("write", "disconnected"),
                                          ("write_timeout", "timeout")])
def test_port_errors(fail_on, kind):
    sphere = LedSphere(BrokenSerial(fail_on), timeout=0.05)
    with pytest.raises(SphereError) as info:
        sphere.identify()
    assert info.value.kind == kind and "\n" not in str(info.value)


def test_unopenable_port():
    with pytest.raises(SphereError) as info:
        LedSphere("/dev/no-such-sphere", timeout=0.05).open()
    assert info.value.kind == "port" and "/dev/no-such-sphere" in str(info.value)


def test_loop_url_echo_is_garbled():
    sphere = LedSphere("loop://", timeout=0.05).open()
    try:
        with pytest.raises(SphereError) as info:
            sphere.identify()
        assert info.value.kind == "garbled"
    finally:
        sphere.close(leave_on=True)


def test_not_open():
    with pytest.raises(SphereError, match="not open"):
        LedSphere("loop://", timeout=0.05).identify()


def test_constructor_validates_timeout():
    for bad in (0, -1, math.nan, math.inf, "1"):
        with pytest.raises(SphereError):
            LedSphere("loop://", timeout=bad)


# ---------------------------------------------------------------------------------------------- arguments
@pytest.mark.parametrize("led,level", [(0, 0.5), (11, 0.5), (1.5, 0.5), (True, 0.5), ("3", 0.5), (None, 0.5),
                                       (1, -0.01), (1, 1.0001), (1, math.nan), (1, math.inf), (1, "x"),
                                       (1, None), (1, True)])
def test_invalid_arguments_send_nothing(led, level):
    with expected_protocol([]) as sphere:
        with pytest.raises(SphereError) as info:
            sphere.set_level(led, level)
    assert info.value.kind == "argument"


def test_invalid_arguments_elsewhere_send_nothing():
    with expected_protocol([]) as sphere:
        for call in (lambda: sphere.set_levels([0.5] * 9), lambda: sphere.set_levels([0.5] * 9 + [2]),
                     lambda: sphere.level(0), lambda: sphere.led_on_time_s(11), lambda: sphere.set_watchdog(0),
                     lambda: sphere.set_watchdog(0.05), lambda: sphere.set_watchdog(4000), lambda: sphere.apply((1,)),
                     lambda: sphere.set_watchdog(math.nan), lambda: sphere.exchange("set_level", led=1)):
            with pytest.raises(SphereError) as info:
                call()
            assert info.value.kind == "argument"


# ---------------------------------------------------------------------------------------------- safety
def test_context_manager_switches_off_on_exception():
    port = ScriptedSerial([(b"LEVEL 3 65535\n", b"OK LEVEL 3 65535\n"), (b"ON 10000\n", b"OK ON 10000\n"),
                           (b"FAULT?\n", b"OK FAULT 0\n"),
                           (b"ALLOFF\n", b"OK ALLOFF\n"), (b"LIGHT 0\n", b"OK LIGHT 0\n"), READ_BACK_OFF])
    with pytest.raises(KeyError):
        with LedSphere(port, timeout=0.05) as sphere:
            sphere.set_level(3, 1.0)
            sphere.on()
            raise KeyError("capture failed")
    assert port.done


def test_context_manager_switches_off_on_normal_exit():
    port = ScriptedSerial([(b"ALLOFF\n", b"OK ALLOFF\n"), (b"LIGHT 0\n", b"OK LIGHT 0\n"), READ_BACK_OFF])
    with LedSphere(port, timeout=0.05):
        pass
    assert port.done


def test_close_switches_off_unless_told_not_to():
    port = ScriptedSerial([(b"ALLOFF\n", b"OK ALLOFF\n"), (b"LIGHT 0\n", b"OK LIGHT 0\n"), READ_BACK_OFF])
    sphere = LedSphere(port, timeout=0.05)
    sphere.close()
    assert port.done and not sphere.is_open
    sphere.close()                                   # twice is harmless
    port = ScriptedSerial([])
    LedSphere(port, timeout=0.05).close(leave_on=True)


def test_close_survives_a_dead_link():
    LedSphere(BrokenSerial("write"), timeout=0.05).close()


def test_off_failure_during_exception_is_noted_not_hidden():
    port = ScriptedSerial([(b"ALLOFF\n", b"ERR 6 stuck\n"), (b"LIGHT 0\n", b"OK LIGHT 0\n"), READ_BACK_OFF])
    with pytest.raises(ValueError) as info:
        with LedSphere(port, timeout=0.05):
            raise ValueError("original")
    assert str(info.value) == "original" and "could not be switched off" in info.value.__notes__[0]
    assert port.done        # LIGHT 0 was still tried after ALLOFF failed


def test_off_failure_on_normal_exit_raises_and_says_the_light_is_off():
    port = ScriptedSerial([(b"PING\n", b"OK PING\n"), (b"ALLOFF\n", None), (b"ALLOFF\n", None),
                           (b"LIGHT 0\n", b"OK LIGHT 0\n"), READ_BACK_OFF])
    with pytest.raises(SphereError, match="the light was switched off .LIGHT 0 answered. but the LED levels were "
                                          "not zeroed") as info:
        with LedSphere(port, timeout=0.05) as sphere:
            sphere.keepalive()
    assert info.value.light == "off"


def test_off_unconfirmed_says_unknown_and_what_the_sphere_guarantees():
    port = ScriptedSerial([(b"ON 10000\n", b"OK ON 10000\n"), (b"FAULT?\n", b"OK FAULT 0\n"),
                           (b"ALLOFF\n", None), (b"ALLOFF\n", None), (b"LIGHT 0\n", None), (b"LIGHT 0\n", None)])
    sphere = LedSphere(port, timeout=0.05)
    sphere.on()
    report = sphere.ensure_off()
    assert not report.off and report.error.kind == "timeout"
    assert "the light's state is unknown" in report.message
    assert re.search(r"the sphere switches it off by itself at most 10 s after it came on \(in (9\.\d|10\.0) s\), "
                     r"the limit sent with ON", report.message)
    sphere.close(leave_on=True)


def test_a_port_that_never_answered_is_switched_off_without_waiting():
    port = ScriptedSerial([(b"IDN?\n", None), (b"IDN?\n", None), (b"ALLOFF\n", None), (b"LIGHT 0\n", None)])
    sphere = LedSphere(port, timeout=0.05)
    with pytest.raises(SphereError):
        sphere.identify()
    report = sphere.ensure_off()
    assert port.done and not report.off and report.error is None
    assert "never answered like an LED sphere" in report.message and "sent without waiting" in report.message


def test_host_on_time_uses_the_clock():
    clock = FakeClock()
    pairs = [(b"ON 10000\n", b"OK ON 10000\n"), (b"FAULT?\n", b"OK FAULT 0\n"), (b"LIGHT 0\n", b"OK LIGHT 0\n"),
             READ_BACK_OFF]
    with expected_protocol(pairs, clock=clock) as sphere:
        assert sphere.on_time_s() == 0.0
        sphere.on()
        clock.advance(12.5)
        assert sphere.on_time_s() == 12.5
        assert sphere.seconds_since_last_exchange == 12.5
        sphere.off()
        assert sphere.on_time_s() == 0.0


# ---------------------------------------------------------------------------------------------- fuzz
def _fuzz_frames(rng: random.Random, n: int) -> list[bytes]:
    valid = []
    for cmd in P.TABLE:
        valid.append(cmd.example_bytes()[1])
    valid += [b"OK LEVELS " + b" ".join(b"%d" % rng.randrange(65536) for _ in range(k)) + b"\n" for k in (1, 10, 16)]
    keywords = [c.reply_keyword.encode() for c in P.TABLE] + [b"", b"OK", b"ERR", b"LEVEL?", b"\xff"]
    frames = []
    for _ in range(n):
        r = rng.random()
        if r < 0.25:
            frame = rng.choice(valid)
        elif r < 0.55:
            frame = bytearray(rng.choice(valid))
            for _ in range(rng.randint(1, 4)):
                op = rng.random()
                pos = rng.randrange(len(frame) + 1)
                if op < 0.4 and frame:
                    frame[min(pos, len(frame) - 1)] = rng.randrange(256)
                elif op < 0.7:
                    frame.insert(pos, rng.choice(b" \n\r0123456789.-=OKER\x00\xff"))
                elif frame:
                    del frame[min(pos, len(frame) - 1)]
            frame = bytes(frame)
        elif r < 0.75:
            frame = bytes(rng.randrange(256) for _ in range(rng.randint(0, 220)))
            if rng.random() < 0.5:
                frame += b"\n"
        elif r < 0.87:
            frame = b"ERR %d " % rng.randrange(-5, 1200) + bytes(rng.randrange(32, 127) for _ in range(
                rng.randint(0, 160))) + rng.choice([b"\n", b"\r\n", b""])
        else:
            nums = b" ".join(rng.choice([b"%d" % rng.randrange(10 ** rng.randint(1, 9)), b"-1", b"1.5", b"1e3",
                                         b"nan", b"x=1", b"light=1"]) for _ in range(rng.randint(0, 18)))
            frame = b"OK " + rng.choice(keywords) + b" " + nums + b"\n"
        frames.append(frame)
    return frames


def test_fuzz_random_replies_only_raise_sphere_error():
    rng = random.Random(20240601)
    frames = _fuzz_frames(rng, 10_000)
    port = FrameSerial(frames)
    sphere = LedSphere(port, timeout=0.5)
    calls = [lambda: sphere.identify(), lambda: sphere.channel_count(), lambda: sphere.set_level(4, 0.5),
             lambda: sphere.level(3), lambda: sphere.set_levels([0.1] * 10), lambda: sphere.levels(),
             lambda: sphere.all_off(), lambda: sphere.on(), lambda: sphere.off(), lambda: sphere.light_on(),
             lambda: sphere.temperature_c(), lambda: sphere.device_on_time_s(), lambda: sphere.led_on_time_s(2),
             lambda: sphere.set_watchdog(30), lambda: sphere.watchdog_s(), lambda: sphere.keepalive(),
             lambda: sphere.faulty_leds(), lambda: sphere.status(), lambda: sphere.shutdown()]
    outcomes = {"ok": 0, "error": 0}
    kinds: set[str] = set()
    for _ in range(len(frames) * 2):          # bounded: every call consumes at least one frame
        if port.next >= len(frames):
            break
        before = port.next
        try:
            rng.choice(calls)()
            outcomes["ok"] += 1
        except SphereError as exc:
            outcomes["error"] += 1
            kinds.add(exc.kind)
            assert "\n" not in str(exc)
        assert port.next > before or port.next >= len(frames)
    assert port.next >= len(frames)
    assert outcomes["ok"] > 100 and outcomes["error"] > 1000, outcomes
    assert {"garbled", "device", "timeout"} <= kinds


# ---------------------------------------------------------------------------------------------- read-back (issue 28)
IGNORED_OFF = [(b"ALLOFF\n", b"OK ALLOFF\n"), (b"LIGHT 0\n", b"OK LIGHT 0\n"), (b"LIGHT?\n", b"OK LIGHT 1\n"),
               (b"LEVELS?\n", b"OK LEVELS 65535 0 0 0 0 0 0 0 0 0\n")]


def test_a_switch_off_the_sphere_acknowledges_but_ignores_is_not_called_off():
    port = ScriptedSerial(IGNORED_OFF)
    sphere = LedSphere(port, timeout=0.05)
    report = sphere.ensure_off()
    assert port.done and not report.off and report.error.kind == "unconfirmed"
    assert "the sphere did not confirm it is off: it answered ALLOFF and LIGHT 0 but still reports the light on " \
           "with LED 1 above 0" in report.message
    with pytest.raises(SphereError, match="did not confirm it is off") as info:
        LedSphere(ScriptedSerial(IGNORED_OFF), timeout=0.05).shutdown()
    assert info.value.light == "unknown"
    sphere.close(leave_on=True)


def test_a_light_off_the_sphere_ignores_raises_and_a_dark_switch_on_is_off():
    port = ScriptedSerial([(b"LIGHT 0\n", b"OK LIGHT 0\n"), (b"LIGHT?\n", b"OK LIGHT 1\n"),
                           (b"LEVELS?\n", b"OK LEVELS 0 0 0 0 0 0 0 0 0 9\n")])
    with pytest.raises(SphereError, match="it answered LIGHT 0 but still reports the light on with LED 10") as info:
        LedSphere(port, timeout=0.05).off()
    assert info.value.kind == "unconfirmed"
    # the switch reads on but every level is 0: nothing emits, that is off
    port = ScriptedSerial([(b"LIGHT 0\n", b"OK LIGHT 0\n"), (b"LIGHT?\n", b"OK LIGHT 1\n"),
                           (b"LEVELS?\n", b"OK LEVELS 0 0 0 0 0 0 0 0 0 0\n")])
    LedSphere(port, timeout=0.05).off()
    assert port.done


def test_status_of_a_sphere_someone_else_lit_names_the_watchdog_when_not_adopting():
    pairs = [(b"STATUS?\n", b"OK STATUS light=1 ontime=2.250 temp=25.10 wdog=30000 trip=0 fault=0\n"),
             (b"LEVELS?\n", b"OK LEVELS 0 0 0 65535 0 0 0 0 0 0\n")]
    with expected_protocol(pairs) as sphere:
        status = sphere.status(adopt=False)
        assert sphere.lit_period is None                     # no limit claimed that nothing would hold
    assert status["off_by"] == "watchdog" and status["off_in_s"] == 30.0 and status["max_on_s"] is None
