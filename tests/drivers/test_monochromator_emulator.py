"""The monochromator emulator: its firmware (echo, answers, status byte and error codes), its light (the band's
shape and width, nothing through a closed shutter, checked against hand computations), and the Cornerstone driver
end to end over a real pty, every injected fault included."""
from __future__ import annotations

import time

import numpy as np
import pytest
from colour.colorimetry import planck_law
from transports import TRANSPORTS, assert_port

from dualrgb.drivers.monochromator import protocol as P
from dualrgb.drivers.monochromator.driver import Cornerstone
from dualrgb.drivers.monochromator.errors import MonochromatorError
from dualrgb.drivers.virtual.monochromator_emulator import MonochromatorEmulator
from dualrgb.drivers.virtual.monochromator_light import MonochromatorOptics

TIMEOUT = 0.25


# ---------------------------------------------------------------------------------------------- firmware
@pytest.mark.parametrize("line,back", [
    (b"INFO?", b"INFO?\r\nCS130 VER 1.01 EMULATOR\r\n"),
    (b"GOWAVE 550", b"GOWAVE 550\r\n"),
    (b"gowave 612.345", b"gowave 612.345\r\n"),
    (b"WAVE?", b"WAVE?\r\n500.000\r\n"),
    (b"SHUTTER?", b"SHUTTER?\r\nC\r\n"),
    (b"GRAT?", b"GRAT?\r\n1,1200,500NM\r\n"),
    (b"FILTER?", b"FILTER?\r\n1\r\n"),
    (b"UNITS?", b"UNITS?\r\nNM\r\n"),
    (b"STEP?", b"STEP?\r\n50000\r\n"),
    (b"STB?", b"STB?\r\n00\r\n"),
    (b"ERROR?", b"ERROR?\r\n\r\n"),
])
def test_echo_and_answers(line, back):
    assert MonochromatorEmulator().handle(line) == back


@pytest.mark.parametrize("line,code", [
    (b"FLY 3", P.ErrorCode.NOT_UNDERSTOOD), (b"GOWAVE", P.ErrorCode.BAD_PARAMETER),
    (b"GOWAVE abc", P.ErrorCode.BAD_PARAMETER), (b"GOWAVE 5 6", P.ErrorCode.BAD_PARAMETER),
    (b"GOWAVE 100", P.ErrorCode.DESTINATION_NOT_ALLOWED), (b"GOWAVE 1500", P.ErrorCode.DESTINATION_NOT_ALLOWED),
    (b"SHUTTER X", P.ErrorCode.BAD_PARAMETER), (b"GRAT 3", P.ErrorCode.BAD_PARAMETER),
    (b"GRAT 1", P.ErrorCode.ALREADY_THERE), (b"FILTER 1", P.ErrorCode.ALREADY_THERE),
    (b"FILTER 9", P.ErrorCode.BAD_PARAMETER), (b"WAVE? 3", P.ErrorCode.BAD_PARAMETER),
])
def test_refused_statements_set_status_and_error_code(line, code):
    emu = MonochromatorEmulator()
    assert emu.handle(line) == line + b"\r\n"              # echoed, nothing else
    assert emu.handle(b"STB?") == b"STB?\r\n20\r\n"
    assert emu.handle(b"ERROR?") == f"ERROR?\r\n{int(code)}\r\n".encode()
    assert emu.handle(b"STB?") == b"STB?\r\n00\r\n"        # reading cleared it
    assert emu.handle(b"ERROR?") == b"ERROR?\r\n\r\n"


def test_state_changes():
    emu = MonochromatorEmulator()
    emu.handle(b"GOWAVE 612.347")
    assert emu.handle(b"WAVE?") == b"WAVE?\r\n612.350\r\n"       # the drive stops on a motor step (0.01 nm)
    assert emu.handle(b"STEP?") == b"STEP?\r\n61235\r\n"
    emu.handle(b"GRAT 2")
    assert emu.handle(b"GRAT?") == b"GRAT?\r\n2,600,1.0UM\r\n" and emu.wavelength_nm == pytest.approx(612.35, abs=0.02)
    emu.handle(b"FILTER 3")
    assert emu.filter_position == 3
    emu.handle(b"UNITS UM")
    assert emu.handle(b"WAVE?") == b"WAVE?\r\n0.612\r\n"
    emu.handle(b"GOWAVE 0.55")
    assert emu.wavelength_nm == pytest.approx(550.0)
    emu.handle(b"SHUTTER O")
    assert emu.shutter_open and emu.handle(b"SHUTTER?") == b"SHUTTER?\r\nO\r\n"


# ---------------------------------------------------------------------------------------------- the light
def test_band_is_a_triangle_of_the_stated_width_on_the_lamp_times_throughput():
    optics = MonochromatorOptics()
    assert optics.fwhm_nm(1) == pytest.approx(1.0 * 6.4)
    wl = np.arange(530.0, 571.0, 0.5)
    band = optics.spectrum(550.0, wl)
    lamp = planck_law(wl * 1e-9, 3000.0) / planck_law(560e-9, 3000.0) * 0.1      # independently: Planck, 3000 K
    eta = 0.8 * np.sinc(1 - 500.0 / wl) ** 2                                    # the scalar blaze model
    slit = np.clip(1 - np.abs(wl - 550.0) / 6.4, 0, None)
    assert band == pytest.approx(lamp * 0.3 * eta * slit, rel=1e-9)
    above_half = wl[band >= band.max() / 2]
    assert above_half[-1] - above_half[0] == pytest.approx(6.4, abs=1.0)          # FWHM within the sampling
    assert np.all(band[np.abs(wl - 550) >= 6.4] == 0)


def test_nothing_comes_out_with_the_shutter_closed_and_the_record_says_when_it_was_open():
    emu = MonochromatorEmulator(clock=iter(range(100)).__next__)
    emu.handle(b"GOWAVE 600")
    assert not np.any(emu.output()[1])
    emu.handle(b"SHUTTER O")
    wl, radiance = emu.output()
    assert radiance.max() > 0 and wl[np.argmax(radiance)] == pytest.approx(600.0)
    emu.handle(b"GOWAVE 610")
    emu.handle(b"SHUTTER C")
    emu.set_by_hand(620, shutter_open=True)
    record = emu.shutter_record()
    assert [(r.wavelength_nm, r.closed_by) for r in record] == [(600, "GOWAVE"), (610, "SHUTTER C"), (620, "")]
    assert record[-1].t_close is None and record[0].t_close is not None and record[0].t_close > record[0].t_open


def test_filter_transmittance_and_blocked_position():
    emu = MonochromatorEmulator()
    emu.handle(b"GOWAVE 450")
    emu.handle(b"SHUTTER O")
    open_ = emu.output()[1].max()
    emu.handle(b"FILTER 3")                    # 590 nm long-pass: almost nothing at 450 nm
    assert emu.output()[1].max() < 1e-4 * open_
    emu.handle(b"FILTER 6")                    # blocked
    assert emu.output()[1].max() == 0


# ---------------------------------------------------------------------------------------------- over the pty
@pytest.fixture(params=TRANSPORTS)
def served(request):
    emu = MonochromatorEmulator(transport=request.param)
    port = emu.start()
    assert_port(port, request.param)
    yield emu, port
    emu.inject(None)
    emu.stop()


def test_end_to_end_over_the_serial_transport(served):
    emu, port = served
    with Cornerstone(port, timeout=1.0) as mono:
        assert mono.identify() == "CS130 VER 1.01 EMULATOR"
        mono.prepare()
        assert mono.goto(550) == 550.0 and emu.wavelength_nm == 550.0
        assert mono.units() == "NM" and mono.step_position() == 55000
        mono.open_shutter()
        assert emu.shutter_open and mono.shutter_is_open()
        assert mono.set_filter(2) == 2 and mono.set_filter(2) == 2       # error 7, already there: no error
        assert mono.set_grating(2) == P.GratingInfo(2, 600, "1.0UM")
        with pytest.raises(MonochromatorError, match="destination not allowed") as info:
            mono.goto(300)                                                # grating 2 starts at 400 nm
        assert info.value.code == 3 and mono.wavelength() == pytest.approx(550.0)
    assert not emu.shutter_open                                           # closed on leaving the block


def test_the_drive_takes_time_to_slew_and_the_driver_waits_for_it(served):
    emu, port = served
    emu.motion_s_per_nm = 0.004                                           # 200 nm: 0.8 s > the reply timeout
    with Cornerstone(port, timeout=0.3, motion_timeout=5.0) as mono:
        started = time.monotonic()
        assert mono.goto(700) == 700.0
        assert time.monotonic() - started >= 0.7


FAULTS = [("garbled", {}, "garbled"), ("slow", {"delay_s": 2.0}, "timeout"), ("no_reply", {}, "timeout"),
          ("ignore", {}, "timeout"), ("error", {"code": 8, "keywords": ("GOWAVE",)}, "device"),
          ("disconnect", {}, "disconnected")]


@pytest.mark.fault("light safety")
@pytest.mark.parametrize("fault,params,kind", FAULTS, ids=[f[0] for f in FAULTS])
def test_each_fault_is_one_line_and_the_shutter_ends_closed_or_said_unknown(served, fault, params, kind):
    emu, port = served
    mono = Cornerstone(port, timeout=TIMEOUT).open()
    mono.prepare()
    mono.open_shutter()
    emu.inject(fault, **params)
    with pytest.raises(MonochromatorError) as info:
        mono.goto(600)
    err = info.value
    assert err.kind == kind and "\n" not in str(err)
    report = mono.ensure_closed()
    if report.closed:
        assert not emu.shutter_open
    else:                                   # the instrument could not confirm it: the report says what to do
        assert "front panel" in report.message
        emu.inject(None)
        if fault != "disconnect":
            assert mono.ensure_closed().closed and not emu.shutter_open
    mono.close(leave_open=True)


def test_inject_rejects_unknown_faults_and_keywords():
    emu = MonochromatorEmulator()
    with pytest.raises(ValueError, match="unknown fault"):
        emu.inject("fire")
    with pytest.raises(ValueError, match="unknown keywords"):
        emu.inject("garbled", keywords=("LAUNCH",))
