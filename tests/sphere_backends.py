"""One protocol suite, two spheres (issue 38): the Python emulator (drivers/virtual/sphere_emulator.py) and the
reference firmware (firmware/) run instruction by instruction on a simulated ATmega2560 (tests/sphere_firmware.py).

A pytest plugin (tests/conftest.py loads it):

* the fixture ``sphere_backend`` is parametrised over ``emulator`` and ``firmware``: a started sphere with the same
  interface on both (:class:`SphereBackend`): its port, its clock, what it emits, lit spans, and the faults the
  hardware can have (LED faults, temperature, a pulled cable, cable faults, a reset). Light is judged on the
  emulator's record and, for the firmware, at the PWM pins (the harness's log, simulated time).
  ``fault_backends(category)`` gives the same parameters with the reliability table's categories: the emulator's
  case in ``category``, the firmware's in "firmware";
* the ``firmware`` mark is on every firmware case; they skip, naming the Debian packages, where the AVR toolchain
  and simavr are not installed;
* ``--firmware-check PATH`` (``make firmware-check``) writes the firmware cases' results and the light-off times
  measured at the pins (``record_firmware_figure``) as JSON: mcu, cases, passed, failed, host_loss_off_s,
  on_limit_off_s, cap_s.
"""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import serial
import sphere_firmware as fw

from dualrgb.drivers.led_sphere import protocol as P
from dualrgb.drivers.virtual.sphere_emulator import SphereEmulator

FIRMWARE_MISSING = fw.missing_toolchain()
FIGURE_KEYS = ("host_loss_off_s", "on_limit_off_s", "cap_s")
MCU = "atmega2560"
POLL_S = 0.005
WAIT_GUARD_S = 120.0        # a hang guard on every wait for the device's own clock, never a measurement


class SphereBackend:
    """What the shared tests need from a sphere, whichever it is (the subclasses say how)."""

    name = ""
    model = ""
    serial = ""
    firmware_version = P.FIRMWARE_VERSION
    #: how long after a level change the emitted light is settled enough to measure (one PWM period and more)
    settle_s = 0.0

    def __init__(self, workdir: Path):
        self.workdir = workdir
        self.port = ""

    # ---- the device ----
    def start(self) -> str:
        raise NotImplementedError

    def stop(self) -> None:
        raise NotImplementedError

    def clock(self) -> float:
        """The sphere's own clock (s): the emulator's, or the simulated chip's."""
        raise NotImplementedError

    def spans(self, since: float) -> list[fw.Span]:
        """Lit spans that began at or after ``since`` (its clock), contiguous light joined."""
        raise NotImplementedError

    def emitted(self) -> np.ndarray:
        """(10,) what each LED emits now, 0..1."""
        raise NotImplementedError

    def last_request(self) -> float:
        """When the sphere last took a request line (its clock)."""
        raise NotImplementedError

    # ---- the faults the hardware can have ----
    def set_temperature(self, celsius: float) -> None:
        raise NotImplementedError

    def fail_led(self, led: int, mode: str) -> None:
        """``mode``: dark (open circuit: driven, emits nothing) or error (its driver reports a fault)."""
        raise NotImplementedError

    def wire(self, fault: str, delay_s: float = 1.0, keywords: tuple[str, ...] = ()) -> None:
        """A cable fault: no_reply (reply lost), hang (request lost), garbled, slow (reply ``delay_s`` late)."""
        raise NotImplementedError

    def clear_faults(self) -> None:
        raise NotImplementedError

    def unplug(self) -> None:
        raise NotImplementedError

    # ---- shared helpers ----
    def exchange(self, line: bytes, timeout: float = 5.0) -> bytes:
        """One raw request line (no terminator) through the port; the reply line."""
        with serial.serial_for_url(self.port, baudrate=P.BAUDRATE, timeout=timeout) as port:
            port.write(line + b"\n")
            return bytes(port.readline())

    def wait(self, seconds: float) -> None:
        """Let ``seconds`` pass on the sphere's clock."""
        end = self.clock() + seconds
        self.wait_until(lambda: self.clock() >= end, f"{seconds} s on the sphere's clock")

    def wait_until(self, condition: Any, what: str) -> None:
        guard = time.monotonic() + WAIT_GUARD_S
        while not condition():
            if time.monotonic() > guard:
                raise AssertionError(f"{self.name}: still waiting for {what} after {WAIT_GUARD_S:g} s")
            time.sleep(POLL_S)

    def wait_dark(self, since: float) -> list[fw.Span]:
        """Wait until the light that came on since ``since`` is off; its spans (the last one ended).

        It returns ``settle_s`` after the switch-off, on the sphere's clock, so that what :meth:`emitted` reads next
        (the firmware: the pins' duty over the last two PWM periods) lies wholly after it; a poll that found the
        switch-off within those periods read the end of the lit span as light still emitted."""
        self.wait_until(lambda: not self.spans(since) or self.spans(since)[-1].t_off is not None, "the light off")
        spans = self.spans(since)
        if spans and spans[-1].t_off is not None:
            settled = spans[-1].t_off + self.settle_s
            self.wait_until(lambda: self.clock() >= settled, "the pins settled after the switch-off")
        return spans

    def wait_lit(self, since: float) -> list[fw.Span]:
        self.wait_until(lambda: bool(self.spans(since)), "the light on")
        return self.spans(since)


class EmulatorBackend(SphereBackend):
    name = "emulator"
    model = SphereEmulator.model
    serial = SphereEmulator.serial

    def __init__(self, workdir: Path):
        super().__init__(workdir)
        self.emulator = SphereEmulator(watchdog_s=30)

    def start(self) -> str:
        self.port = self.emulator.start()
        return self.port

    def stop(self) -> None:
        self.emulator.stop()

    def clock(self) -> float:
        return self.emulator.clock()

    def spans(self, since: float) -> list[fw.Span]:
        spans: list[fw.Span] = []
        for i in self.emulator.light_record():
            if i.t_on < since:
                continue
            if spans and spans[-1].t_off is not None and abs(spans[-1].t_off - i.t_on) < 1e-9:
                spans[-1].t_off = i.t_off
            else:
                spans.append(fw.Span(i.t_on, i.t_off))
        return spans

    def emitted(self) -> np.ndarray:
        return self.emulator.snapshot().levels

    def last_request(self) -> float:
        return self.emulator._last_rx

    def set_temperature(self, celsius: float) -> None:
        with self.emulator._lock:                   # the sensor's reading: no physics between tests' steps
            self.emulator._advance(self.emulator.clock())
            self.emulator.ambient_c = self.emulator._temp = celsius

    def fail_led(self, led: int, mode: str) -> None:
        self.emulator.inject("led_fail", led=led, mode=mode)

    def wire(self, fault: str, delay_s: float = 1.0, keywords: tuple[str, ...] = ()) -> None:
        name = {"hang": "ignore"}.get(fault, fault)
        params: dict[str, Any] = {"keywords": list(keywords)} if keywords else {}
        if fault == "slow":
            params["delay_s"] = delay_s
        self.emulator.inject(name, **params)

    def clear_faults(self) -> None:
        self.emulator.inject(None)

    def unplug(self) -> None:
        self.emulator.inject("disconnect")


class FirmwareBackend(SphereBackend):
    name = "firmware"
    model = "DRGB-SPHERE10"
    serial = "SN0001"
    settle_s = 0.012                                # two PWM periods (8.2 ms) and the current sense

    def __init__(self, workdir: Path):
        super().__init__(workdir)
        self.sim = fw.FirmwareSphere(workdir)
        self.failed: set[int] = set()

    def start(self) -> str:
        self.port = self.sim.start()
        return self.port

    def stop(self) -> None:
        self.sim.stop()

    def clock(self) -> float:
        return self.sim.clock()

    def spans(self, since: float) -> list[fw.Span]:
        until = self.sim.cycles()
        return self.sim.pins().spans(until, int(since * fw.F_CPU))

    def emitted(self) -> np.ndarray:
        """The pins' duty over the last two PWM periods, 0 for an LED that is open (it emits nothing)."""
        end = self.sim.cycles()
        pins = self.sim.pins()
        start = end - 2 * fw.PWM_PERIOD_CYCLES
        return np.array([0.0 if led in self.failed else pins.duty(led, start, end) for led in range(1, 11)])

    def last_request(self) -> float:
        cycle = self.sim.pins().last("R", self.sim.cycles())
        assert cycle is not None, "the chip never took a request"
        return cycle / fw.F_CPU

    def host_gone(self, after: float) -> float | None:
        """When the host closed the port (or vanished) first after ``after``, on the chip's clock."""
        until = self.sim.cycles()
        cycles = [c for k, c, _ in self.sim.pins().events if k == "H" and after * fw.F_CPU <= c <= until]
        return min(cycles) / fw.F_CPU if cycles else None

    def set_temperature(self, celsius: float) -> None:
        self.sim.command(f"temp {celsius:.2f}")
        self.wait(0.05)                             # a reading is the mean of 16 conversions, 1 a ms: 2 of them

    def fail_led(self, led: int, mode: str) -> None:
        self.sim.command(f"led {led} {mode}")
        self.failed.add(led)

    def wire(self, fault: str, delay_s: float = 1.0, keywords: tuple[str, ...] = ()) -> None:
        ms = int(round(delay_s * 1000))
        self.sim.command(f"wire {fault} {ms} {' '.join(k.upper() for k in keywords)}".rstrip())

    def clear_faults(self) -> None:
        self.sim.command("wire clear")
        for led in range(1, 11):
            self.sim.command(f"led {led} ok")
        self.failed.clear()
        self.sim.command("temp 25")

    def unplug(self) -> None:
        self.sim.command("unplug")

    def reset(self, cause: str) -> None:
        self.sim.command(f"reset {cause}")


BACKENDS: dict[str, type[SphereBackend]] = {"emulator": EmulatorBackend, "firmware": FirmwareBackend}


def _firmware_marks(*extra: pytest.MarkDecorator) -> list[pytest.MarkDecorator]:
    marks = [pytest.mark.firmware, *extra]
    if FIRMWARE_MISSING:
        marks.append(pytest.mark.skip(reason=FIRMWARE_MISSING))
    return marks


def backend_params() -> list[Any]:
    return [pytest.param("emulator", id="emulator"), pytest.param("firmware", id="firmware", marks=_firmware_marks())]


def fault_backends(category: str) -> list[Any]:
    """The backends for a fault case: the emulator's counted under ``category``, the firmware's under
    "firmware" (docs/explanation/reliability.md)."""
    return [pytest.param("emulator", id="emulator", marks=[pytest.mark.fault(category)]),
            pytest.param("firmware", id="firmware", marks=_firmware_marks(pytest.mark.fault("firmware")))]


def firmware_only(category: str = "firmware") -> list[Any]:
    return [pytest.param("firmware", id="firmware", marks=_firmware_marks(pytest.mark.fault(category)))]


@pytest.fixture(params=backend_params())
def sphere_backend(request: pytest.FixtureRequest, tmp_path: Path):
    backend = BACKENDS[request.param](tmp_path)
    backend.start()
    try:
        yield backend
    finally:
        backend.stop()
    if isinstance(backend, FirmwareBackend):
        assert backend.sim.returncode is not None, "the harness is still running after the test"


@pytest.fixture
def record_firmware_figure(request: pytest.FixtureRequest):
    """``record(key, value)``: a figure for build/firmware-check.json (firmware cases only)."""
    figures = request.config._firmware_figures           # type: ignore[attr-defined]

    def record(key: str, value: float) -> None:
        if key not in FIGURE_KEYS:
            raise KeyError(f"{key}: not one of {FIGURE_KEYS}")
        figures[key] = round(float(value), 6)
    return record


# ------------------------------------------------------------------------------------------------ the plugin
def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--firmware-check", metavar="PATH", default=None,
                     help="write the reference firmware's results and light-off times at the pins as JSON")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "firmware: runs the reference firmware on a simulated ATmega2560 (simavr); "
                                       "make firmware-check runs these")
    config._firmware_figures = {}                         # type: ignore[attr-defined]
    config._firmware_results = {"passed": 0, "failed": 0}  # type: ignore[attr-defined]


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    outcome = yield
    report = outcome.get_result()
    if item.get_closest_marker("firmware") is None or report.skipped:
        return
    results = item.config._firmware_results              # type: ignore[attr-defined]
    if report.when == "call" or (report.failed and report.when in ("setup", "teardown")):
        if report.when == "teardown" and report.failed:
            results["passed"] -= 1                        # it passed its call, then failed to clean up
        results["passed" if report.passed else "failed"] += 1


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    target = session.config.getoption("--firmware-check")
    if not target:
        return
    results = session.config._firmware_results           # type: ignore[attr-defined]
    figures = session.config._firmware_figures           # type: ignore[attr-defined]
    report = {"mcu": MCU, "cases": results["passed"] + results["failed"], "passed": results["passed"],
              "failed": results["failed"], **{key: figures.get(key) for key in FIGURE_KEYS}}
    path = Path(target)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write_line(f"firmware check written to {path}: {report}")
