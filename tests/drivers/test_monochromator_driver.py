"""Cornerstone against scripted serial ports: byte-exact exchanges (statement, echo, answer) for every statement,
the status check after each command, retries, garbled echoes and answers, device error codes, argument
validation, and the shutter closed on exit, on a failed open and on every error path."""
from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

import pytest
from sphere_fakes import BrokenSerial, ScriptedSerial

from dualrgb.drivers.monochromator import protocol as P
from dualrgb.drivers.monochromator.driver import Cornerstone
from dualrgb.drivers.monochromator.errors import MonochromatorError

DOC = Path(__file__).resolve().parents[2] / "docs" / "monochromator-protocol.md"
OK = (b"STB?\r\n", b"STB?\r\n00\r\n")                # the status check after every command
CLOSE = [(b"SHUTTER C\r\n", b"SHUTTER C\r\n"), OK, (b"SHUTTER?\r\n", b"SHUTTER?\r\nC\r\n")]


@contextlib.contextmanager
def expected_protocol(pairs, timeout: float = 0.05, **kwargs) -> Iterator[Cornerstone]:
    """A Cornerstone on a ScriptedSerial; every scripted exchange must have happened when the block ends."""
    port = ScriptedSerial(pairs)
    mono = Cornerstone(port, timeout=timeout, motion_timeout=kwargs.pop("motion_timeout", timeout), **kwargs)
    try:
        yield mono
    finally:
        mono.close(leave_open=True)
    assert port.done, f"only {port.index} of {len(port.pairs)} scripted exchanges happened: {port.written}"


# (driver call, [(statement bytes, echo + answer bytes)], expected return value)
EXCHANGES = [
    (lambda m: m.identify(), [(b"INFO?\r\n", b"INFO?\r\nCS130 VER 1.01\r\n")], "CS130 VER 1.01"),
    (lambda m: m.goto(550), [(b"GOWAVE 550.000\r\n", b"GOWAVE 550.000\r\n"), OK,
                             (b"WAVE?\r\n", b"WAVE?\r\n550.000\r\n")], 550.0),
    (lambda m: m.goto(412.3456), [(b"GOWAVE 412.346\r\n", b"GOWAVE 412.346\r\n"), OK,
                                  (b"WAVE?\r\n", b"WAVE?\r\n412.300\r\n")], 412.3),
    (lambda m: m.wavelength(), [(b"WAVE?\r\n", b"WAVE?\r\n-0.125\r\n")], -0.125),
    (lambda m: m.open_shutter(), [(b"SHUTTER O\r\n", b"SHUTTER O\r\n"), OK], None),
    (lambda m: m.close_shutter(), [(b"SHUTTER C\r\n", b"SHUTTER C\r\n"), OK], None),
    (lambda m: m.shutter_is_open(), [(b"SHUTTER?\r\n", b"SHUTTER?\r\nO\r\n")], True),
    (lambda m: m.grating(), [(b"GRAT?\r\n", b"GRAT?\r\n2,600,1.0 UM\r\n")], P.GratingInfo(2, 600, "1.0 UM")),
    (lambda m: m.set_grating(1), [(b"GRAT 1\r\n", b"GRAT 1\r\n"), OK, (b"GRAT?\r\n", b"GRAT?\r\n1,1200,500NM\r\n")],
     P.GratingInfo(1, 1200, "500NM")),
    (lambda m: m.filter(), [(b"FILTER?\r\n", b"FILTER?\r\n0\r\n")], 0),
    (lambda m: m.set_filter(3), [(b"FILTER 3\r\n", b"FILTER 3\r\n"), OK, (b"FILTER?\r\n", b"FILTER?\r\n3\r\n")], 3),
    (lambda m: m.units(), [(b"UNITS?\r\n", b"UNITS?\r\nNM\r\n")], "NM"),
    (lambda m: m.set_units("nm"), [(b"UNITS NM\r\n", b"UNITS NM\r\n"), OK], None),
    (lambda m: m.step_position(), [(b"STEP?\r\n", b"STEP?\r\n123450\r\n")], 123450),
    (lambda m: m.status_byte(), [(b"STB?\r\n", b"STB?\r\n20\r\n")], 0x20),
    (lambda m: m.last_error(), [(b"ERROR?\r\n", b"ERROR?\r\n3\r\n")], 3),
    (lambda m: m.last_error(), [(b"ERROR?\r\n", b"ERROR?\r\n\r\n")], None),
    (lambda m: m.ensure_closed().closed, CLOSE, True),
    # prepare: units, a stale error read (and so cleared), the shutter closed and confirmed
    (lambda m: m.prepare(), [(b"UNITS NM\r\n", b"UNITS NM\r\n"), OK, (b"STB?\r\n", b"STB?\r\n20\r\n"),
                             (b"ERROR?\r\n", b"ERROR?\r\n1\r\n"), *CLOSE], None),
    # a filter or grating already in place (error 7) is no error
    (lambda m: m.set_filter(1), [(b"FILTER 1\r\n", b"FILTER 1\r\n"), (b"STB?\r\n", b"STB?\r\n20\r\n"),
                                 (b"ERROR?\r\n", b"ERROR?\r\n7\r\n"), (b"FILTER?\r\n", b"FILTER?\r\n1\r\n")], 1),
    (lambda m: m.describe(), [(b"INFO?\r\n", b"INFO?\r\nCS260 V2\r\n"), (b"GRAT?\r\n", b"GRAT?\r\n1,1200,VIS\r\n")],
     {"instrument": "Newport / Oriel Cornerstone monochromator", "model": "CS260 V2", "port": "scripted",
      "grating": "1 (1200 l/mm, VIS)"}),
]


@pytest.mark.parametrize("call,pairs,expected", EXCHANGES,
                         ids=[f"{p[1][0][0].decode().strip()}#{i}" for i, p in enumerate(EXCHANGES)])
def test_byte_exact_exchange(call, pairs, expected):
    with expected_protocol(pairs) as mono:
        assert call(mono) == expected


def test_every_protocol_statement_has_a_byte_exact_test():
    sent = {req.split(b" ")[0].strip().decode() for _, pairs, _ in EXCHANGES for req, _ in pairs}
    assert sent == set(P.BY_KEYWORD), f"untested: {set(P.BY_KEYWORD) - sent}"


def test_table_examples_round_trip_and_are_documented():
    doc = DOC.read_text(encoding="utf-8")
    for stmt in P.TABLE:
        request, back = stmt.example_bytes()
        parsed, value = P.parse_statement(request.rstrip(b"\r\n"))     # the device reads the example back
        assert parsed is stmt and value == (None if stmt.arg is None else stmt.arg.check(stmt.example[0]))
        assert back.startswith(request)                                  # the echo comes first
        if stmt.is_query:
            assert stmt.decode(back[len(request):]) == stmt.example[1]
        assert repr(request)[2:-1] in doc, f"{request!r} not in {DOC.name}"
        assert repr(back)[2:-1] in doc, f"{back!r} not in {DOC.name}"
    for code in P.ErrorCode:
        assert f"| {int(code)} |" in doc, f"error code {int(code)} not documented"


# ---------------------------------------------------------------------------------------------- errors
@pytest.mark.parametrize("code", list(P.ErrorCode))
def test_device_error_codes_give_one_line_advice(code):
    pairs = [(b"UNITS NM\r\n", b"UNITS NM\r\n"), (b"STB?\r\n", b"STB?\r\n20\r\n"),
             (b"ERROR?\r\n", f"ERROR?\r\n{int(code)}\r\n".encode())]
    with expected_protocol(pairs) as mono:
        with pytest.raises(MonochromatorError) as info:
            mono.set_units("NM")
    err = info.value
    assert err.kind == "device" and err.code == code and "\n" not in str(err)
    assert f"error {int(code)}" in str(err) and P.ERROR_ADVICE[code] in str(err)


def test_a_refused_wavelength_is_an_error_naming_it():
    pairs = [(b"GOWAVE 2400.000\r\n", b"GOWAVE 2400.000\r\n"), (b"STB?\r\n", b"STB?\r\n20\r\n"),
             (b"ERROR?\r\n", b"ERROR?\r\n3\r\n")]
    with expected_protocol(pairs) as mono:
        with pytest.raises(MonochromatorError, match="GOWAVE 2400.000.*destination not allowed") as info:
            mono.goto(2400)
    assert info.value.code == 3


def test_status_flagged_without_a_code():
    pairs = [(b"SHUTTER C\r\n", b"SHUTTER C\r\n"), (b"STB?\r\n", b"STB?\r\n20\r\n"), (b"ERROR?\r\n", b"ERROR?\r\n\r\n")]
    with expected_protocol(pairs) as mono:
        with pytest.raises(MonochromatorError, match="no code"):
            mono.close_shutter()


def test_a_drive_that_stops_elsewhere_is_an_error():
    pairs = [(b"GOWAVE 550.000\r\n", b"GOWAVE 550.000\r\n"), OK, (b"WAVE?\r\n", b"WAVE?\r\n0.550\r\n")]
    with expected_protocol(pairs) as mono:
        with pytest.raises(MonochromatorError, match="UNITS NM"):
            mono.goto(550)


@pytest.mark.parametrize("call", [lambda m: m.goto(-1), lambda m: m.goto(float("nan")), lambda m: m.goto(3000),
                                  lambda m: m.goto(True), lambda m: m.set_grating(4), lambda m: m.set_filter(0),
                                  lambda m: m.set_filter(1.5), lambda m: m.set_units("inch")])
def test_invalid_arguments_send_nothing(call):
    with expected_protocol([]) as mono:
        with pytest.raises(MonochromatorError) as info:
            call(mono)
    assert info.value.kind == "argument"


# ---------------------------------------------------------------------------------------------- the wire
def test_retries_once_after_a_timeout():
    with expected_protocol([(b"WAVE?\r\n", None), (b"WAVE?\r\n", b"WAVE?\r\n500.000\r\n")]) as mono:
        assert mono.wavelength() == 500.0


def test_two_timeouts_raise_one_line_error():
    with expected_protocol([(b"SHUTTER?\r\n", None), (b"SHUTTER?\r\n", None)]) as mono:
        with pytest.raises(MonochromatorError) as info:
            mono.shutter_is_open()
    err = info.value
    assert err.kind == "timeout" and "sent twice" in str(err) and "\n" not in str(err)


def test_echo_without_answer_is_a_timeout():
    with expected_protocol([(b"WAVE?\r\n", b"WAVE?\r\n")]) as mono:
        with pytest.raises(MonochromatorError, match="no answer") as info:
            mono.wavelength()
    assert info.value.kind == "timeout"


@pytest.mark.parametrize("back", [b"WAVX?\r\n500.000\r\n", b"\xff\xfe\r\n", b"WAVE?\r\nfive hundred\r\n",
                                  b"WAVE?\r\n5\x0000\r\n", b"WAVE?\r\n" + b"9" * 200])
def test_garbled_echo_or_answer(back):
    with expected_protocol([(b"WAVE?\r\n", back)]) as mono:
        with pytest.raises(MonochromatorError) as info:
            mono.wavelength()
    assert info.value.kind == "garbled" and "\n" not in str(info.value)


def test_a_late_echo_of_an_earlier_statement_is_skipped():
    pairs = [(b"WAVE?\r\n", None), (b"WAVE?\r\n", b"WAVE?\r\n500.000\r\n"),
             (b"SHUTTER?\r\n", b"WAVE?\r\nSHUTTER?\r\nC\r\n")]
    with expected_protocol(pairs) as mono:
        assert mono.wavelength() == 500.0 and mono.shutter_is_open() is False


def test_a_bare_lf_echo_and_lowercase_statement_echo_are_accepted():
    with expected_protocol([(b"WAVE?\r\n", b"wave?\n550.000\n")]) as mono:
        assert mono.wavelength() == pytest.approx(550.0)


@pytest.mark.parametrize("fail_on", ["read", "write", "write_timeout"])
def test_broken_port(fail_on):
    mono = Cornerstone(BrokenSerial(fail_on), timeout=0.05)
    with pytest.raises(MonochromatorError) as info:
        mono.wavelength()
    assert info.value.kind == ("timeout" if fail_on == "write_timeout" else "disconnected")


def test_unopenable_port_is_one_line():
    with pytest.raises(MonochromatorError, match="cannot open monochromator port /nonexistent/tty") as info:
        Cornerstone("/nonexistent/tty").open()
    assert info.value.kind == "port"


# ---------------------------------------------------------------------------------------------- the shutter
@pytest.mark.fault("light safety")
def test_a_failed_open_closes_the_shutter_and_says_so():
    pairs = [(b"SHUTTER O\r\n", b"SHUTTER O\r\n"), (b"STB?\r\n", b"STB?\r\n20\r\n"),
             (b"ERROR?\r\n", b"ERROR?\r\n0\r\n"), *CLOSE]
    with expected_protocol(pairs) as mono:
        with pytest.raises(MonochromatorError) as info:
            mono.open_shutter()
    assert info.value.shutter == "closed" and str(info.value).endswith("the monochromator's shutter was closed")


@pytest.mark.fault("light safety")
def test_context_manager_closes_the_shutter_on_an_exception():
    port = ScriptedSerial([(b"SHUTTER O\r\n", b"SHUTTER O\r\n"), OK, *CLOSE])
    with pytest.raises(KeyError) as info:
        with Cornerstone(port, timeout=0.05) as mono:
            mono.open_shutter()
            raise KeyError("camera failed")
    assert port.done and not getattr(info.value, "__notes__", None)


@pytest.mark.fault("light safety")
def test_shutter_still_open_is_reported_truthfully():
    pairs = [(b"SHUTTER C\r\n", b"SHUTTER C\r\n"), OK, (b"SHUTTER?\r\n", b"SHUTTER?\r\nO\r\n")]
    with expected_protocol(pairs) as mono:
        report = mono.ensure_closed()
    assert not report.closed and "still reports open" in report.message and "front panel" in report.message


@pytest.mark.fault("light safety")
def test_a_port_that_never_answered_gets_shutter_c_blind():
    port = ScriptedSerial([(b"WAVE?\r\n", None), (b"WAVE?\r\n", None), (b"SHUTTER C\r\n", None)])
    mono = Cornerstone(port, timeout=0.05)
    with pytest.raises(MonochromatorError):
        mono.wavelength()
    report = mono.ensure_closed()
    assert port.done and not report.closed and "without waiting" in report.message


@pytest.mark.fault("light safety")
def test_close_on_a_closed_port_says_the_state_is_unknown():
    mono = Cornerstone("/nonexistent/tty")
    report = mono.ensure_closed()
    assert not report.closed and "unknown" in report.message
