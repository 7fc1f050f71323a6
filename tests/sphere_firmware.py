"""The reference firmware (firmware/) on a simulated ATmega2560, for tests: builds it, runs the simavr harness
(firmware/sim/harness.c) while a test needs it, and reads the harness's log of the PWM pins' levels against
simulated time.

``FirmwareSphere`` is a context manager: ``start()`` returns the pty path a serial client opens (the driver, pyserial)
and ``stop()`` ends the harness (it never outlives the test: it also dies with its parent and when its stdin
closes). Times are on the chip's clock (clock cycles / 16 MHz), read from the harness's log: ``pins()`` parses it,
``clock()`` asks the harness the time after flushing it, so everything up to that time is in the log.
"""
from __future__ import annotations

import glob
import os
import queue
import shutil
import subprocess
import threading
from dataclasses import dataclass, field
from pathlib import Path

from filelock import FileLock

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "firmware"
BUILD = ROOT / "build" / "firmware"
ELF = BUILD / "sphere.elf"
HARNESS = BUILD / "sphere-sim"
PACKAGES = "gcc-avr avr-libc simavr libsimavr-dev libsimavrparts1"
F_CPU = 16_000_000
PWM_PERIOD_CYCLES = 65535               # firmware/src/board.h: PWM_TOP + 1 clocks, 4.096 ms
N_LEDS = 10
START_TIMEOUT_S = 60.0                  # hang guards only (a loaded machine), never a measurement
REPLY_TIMEOUT_S = 30.0


def missing_toolchain() -> str | None:
    """Why the firmware cannot be built and simulated here (one line naming the packages), or None."""
    have = (shutil.which("avr-gcc") and shutil.which("make") and shutil.which("cc")
            and Path("/usr/include/simavr/sim_avr.h").is_file() and glob.glob("/usr/lib/*/libsimavr.so*"))
    if have:
        return None
    return f"the AVR toolchain and simavr are not installed (Debian packages {PACKAGES})"


def _lock() -> FileLock:
    """Held while the image is built and while a harness loads it: test processes (xdist workers, make
    firmware-check beside make reliability) never load an image another one is writing."""
    BUILD.mkdir(parents=True, exist_ok=True)
    return FileLock(str(BUILD.parent / "firmware.lock"))


def _make() -> None:
    subprocess.run(["make", "--no-print-directory", "-s", "-C", str(FIRMWARE)], check=True, capture_output=True,
                   text=True, timeout=600)


def build() -> None:
    """``make -C firmware`` (incremental; one build at a time across test processes); CalledProcessError on
    failure, with the compiler's output."""
    with _lock():
        _make()


@dataclass
class Span:
    """Light at the pins: from the first rising edge ``t_on`` to the last falling edge ``t_off`` (seconds on the
    chip's clock; None: still lit), pulses less than a PWM period apart joined."""

    t_on: float
    t_off: float | None

    def duration(self, now: float) -> float:
        return (now if self.t_off is None else self.t_off) - self.t_on


@dataclass
class PinLog:
    """The harness's log, parsed: per LED its edges ``(cycle, level)``, and the other events."""

    edges: dict[int, list[tuple[int, int]]] = field(default_factory=lambda: {i: [] for i in range(1, N_LEDS + 1)})
    events: list[tuple[str, int, str]] = field(default_factory=list)

    @classmethod
    def read(cls, path: Path) -> PinLog:
        log = cls()
        for line in path.read_text(encoding="ascii").splitlines():
            if not line or line.startswith("#"):
                continue
            parts = line.split(" ", 2)
            if parts[0] == "P":
                _, cycle, rest = parts
                led, level = rest.split()
                log.edges[int(led)].append((int(cycle), int(level)))
            else:
                log.events.append((parts[0], int(parts[1]), parts[2] if len(parts) > 2 else ""))
        return log

    def high_intervals(self, led: int, until: int) -> list[tuple[int, int]]:
        """The LED pin's high intervals (cycles), the last one ending at ``until`` if still high."""
        out, start = [], None
        for cycle, level in self.edges[led]:
            if level and start is None:
                start = cycle
            elif not level and start is not None:
                out.append((start, cycle))
                start = None
        if start is not None:
            out.append((start, max(until, start)))
        return out

    def spans(self, until: int, since: int = 0) -> list[Span]:
        """Lit spans (any LED high) from ``since`` on, pulses less than 1.5 PWM periods apart joined; a span
        still lit at ``until`` has ``t_off`` None."""
        intervals = sorted(iv for led in self.edges for iv in self.high_intervals(led, until) if iv[1] > since)
        joined: list[list[int]] = []
        for start, end in intervals:
            if joined and start - joined[-1][1] <= PWM_PERIOD_CYCLES * 3 // 2:
                joined[-1][1] = max(joined[-1][1], end)
            else:
                joined.append([start, end])
        spans = [Span(s / F_CPU, e / F_CPU) for s, e in joined]
        lit_now = any(edges and edges[-1][1] for edges in self.edges.values())
        if spans and (lit_now or until - joined[-1][1] <= PWM_PERIOD_CYCLES * 3 // 2):
            spans[-1].t_off = None          # lit, or between two pulses: not dark yet
        return spans

    def duty(self, led: int, start: int, end: int) -> float:
        """The fraction of [start, end) the LED's pin was high."""
        high = sum(max(0, min(e, end) - max(s, start)) for s, e in self.high_intervals(led, end))
        return high / (end - start)

    def last(self, kind: str, before: int | None = None) -> int | None:
        """The cycle of the last event of ``kind`` (R, H, C, E), before ``before`` if given."""
        cycles = [c for k, c, _ in self.events if k == kind and (before is None or c <= before)]
        return max(cycles) if cycles else None


class FirmwareSphere:
    """The harness running the firmware: see the module docstring."""

    def __init__(self, workdir: Path):
        self.log_path = Path(workdir) / "sphere-pins.log"
        self._proc: subprocess.Popen[str] | None = None
        self._lines: queue.Queue[str | None] = queue.Queue()
        self._lock = threading.Lock()
        self.port = ""
        self.returncode: int | None = None      # the harness's exit status once stopped

    def start(self) -> str:
        with _lock():                           # the harness has read the image once it names its port
            _make()
            self._proc = subprocess.Popen([str(HARNESS), str(ELF), str(self.log_path)], stdin=subprocess.PIPE,
                                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1,
                                          cwd=ROOT)
            threading.Thread(target=self._read, name="sphere-sim stdout", daemon=True).start()
            first = self._next_line(START_TIMEOUT_S).split()
        if len(first) < 2 or first[0] != "port":
            raise RuntimeError(f"sphere-sim did not start: {first} {self._stderr()}")
        self.port = first[1]
        return self.port

    def _read(self) -> None:
        assert self._proc is not None and self._proc.stdout is not None
        for line in self._proc.stdout:
            self._lines.put(line.rstrip("\n"))
        self._lines.put(None)

    def _next_line(self, timeout: float) -> str:
        try:
            line = self._lines.get(timeout=timeout)
        except queue.Empty:
            raise RuntimeError(f"sphere-sim gave no answer within {timeout:g} s") from None
        if line is None:
            raise RuntimeError(f"sphere-sim ended: {self._stderr()}")
        return line

    def _stderr(self) -> str:
        if self._proc is None or self._proc.poll() is None or self._proc.stderr is None:
            return ""
        return self._proc.stderr.read().strip()

    def command(self, text: str) -> str:
        """One harness command (firmware/sim/harness.c); its answer line. RuntimeError for an ``error`` answer."""
        with self._lock:
            if self._proc is None or self._proc.stdin is None:
                raise RuntimeError("sphere-sim is not running")
            self._proc.stdin.write(text + "\n")
            self._proc.stdin.flush()
            answer = self._next_line(REPLY_TIMEOUT_S)
        if answer.startswith("error"):
            raise RuntimeError(f"sphere-sim {text!r}: {answer}")
        return answer

    def cycles(self) -> int:
        """The chip's time in clock cycles; the log holds everything up to it."""
        return int(self.command("time").split()[1])

    def clock(self) -> float:
        return self.cycles() / F_CPU

    def pins(self) -> PinLog:
        return PinLog.read(self.log_path)

    def stop(self) -> None:
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            if proc.stdin is not None:
                proc.stdin.close()             # the harness ends at the end of its stdin
            proc.wait(timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            proc.kill()
            proc.wait(timeout=10)
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()
        self.returncode = proc.returncode

    def __enter__(self) -> FirmwareSphere:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def harness_processes() -> list[int]:
    """The pids of sphere-sim processes this user runs (tests check none is left behind)."""
    pids = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                exe = os.readlink(f"/proc/{entry}/exe")
            except OSError:
                continue
            if exe == str(HARNESS):
                pids.append(int(entry))
    return pids
