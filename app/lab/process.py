"""The virtual lab in a process of its own: ``dualrgb lab serve`` started as a child, its instruments' addresses
read from the lines it prints (``<name> <address>``), stopped at the end.

    with LabProcess(LabOptions(mode="reflective", frame_size=(600, 400))) as lab:
        sphere, camera, stand = lab.addresses["sphere"], lab.addresses["camera"], lab.addresses["stand"]
        ...                                     # opened by address, exactly as a physical stand's devices

The child runs in a session of its own (a Ctrl-C in the terminal, or the parent killed, does not reach it) with
``--with-parent``: when its standard input closes - :meth:`LabProcess.stop`, or the parent's death, kill -9
included - it waits until its sphere is dark (the sphere's own watchdog and on-time limit switch it off, as a
physical sphere's firmware does: nobody else will) and exits. Its log goes to a file (:attr:`LabProcess.log_path`),
whose last line is quoted when it fails to start.
"""
from __future__ import annotations

import logging
import os
import queue
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

log = logging.getLogger(__name__)

NEEDED = ("sphere", "camera", "stand")          # what a copy stand run opens (the lab prints more)
START_TIMEOUT_S = 180.0                         # a hang guard: the lab starts in a few seconds
STOP_TIMEOUT_S = 60.0                           # the sphere is dark already when a run ends; its watchdog bounds it


@dataclass
class LabOptions:
    """What the lab is (``dualrgb lab serve``'s options; app.commands.lab)."""

    mode: str = "reflective"
    frame_size: tuple[int, int] = (600, 400)
    seed: int = 0
    world: str | None = None
    bumps: bool = False
    stand_in: str = ""                          # the virtual original an original is shown as ('' the mode's)
    charts: dict[str, tuple[str, str, str]] = field(default_factory=dict)   # role -> (file, layout, leave-out)
    watchdog_s: float | None = None
    light_record: Path | None = None
    verbose: int = 0

    def arguments(self) -> list[str]:
        """The command line of ``dualrgb lab serve`` for these options."""
        args = ["-v"] * min(self.verbose, 2) + ["lab", "serve", "--mode", self.mode, "--frame-size",
                                                  "{}x{}".format(*self.frame_size), "--seed", str(self.seed)]
        args += ["--world", str(self.world)] if self.world else []
        args += ["--bumps"] if self.bumps else []
        args += ["--original", self.stand_in] if self.stand_in else []
        args += ["--watchdog-s", f"{self.watchdog_s:g}"] if self.watchdog_s is not None else []
        args += ["--light-record", str(self.light_record)] if self.light_record else []
        for role, (file, layout, leave_out) in self.charts.items():
            args += [f"--{role}-target", file] + ([f"--{role}-layout", layout] if layout else [])
            args += [f"--{role}-leave-out", leave_out] if leave_out else []
        return args


class LabProcess:
    """``dualrgb lab serve`` as a child process (module docstring)."""

    def __init__(self, options: LabOptions, python: str = sys.executable):
        self.options = options
        self.command = [python, "-m", "dualrgb", *options.arguments(), "--with-parent"]
        self.addresses: dict[str, str] = {}
        self.process: subprocess.Popen[bytes] | None = None
        self.log_path: Path | None = None
        self._log: IO[bytes] | None = None

    def start(self, timeout_s: float = START_TIMEOUT_S) -> dict[str, str]:
        """Start the lab; returns its instruments' addresses (name -> address) once it has printed them."""
        fd, name = tempfile.mkstemp(prefix="dualrgb-lab-", suffix=".log")
        self.log_path, self._log = Path(name), os.fdopen(fd, "wb")
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self.process = subprocess.Popen(self.command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                        stderr=self._log, env=env, start_new_session=True)
        try:
            self.addresses = self._read_addresses(timeout_s)
        except BaseException:
            self.stop()
            raise
        log.info("virtual lab (pid %d): %s", self.process.pid,
                 ", ".join(f"{k} {v}" for k, v in self.addresses.items()))
        return dict(self.addresses)

    def _read_addresses(self, timeout_s: float) -> dict[str, str]:
        process = self.process
        assert process is not None and process.stdout is not None
        lines: queue.Queue[bytes] = queue.Queue()
        stdout = process.stdout

        def pump() -> None:
            for line in iter(stdout.readline, b""):
                lines.put(line)
            lines.put(b"")
        threading.Thread(target=pump, name="lab addresses", daemon=True).start()
        found: dict[str, str] = {}
        deadline = time.monotonic() + timeout_s
        while not set(NEEDED) <= set(found):
            try:
                line = lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise RuntimeError(f"the virtual lab did not start within {timeout_s:g} s"
                                   f"{self._last_words()}") from None
            if not line:
                raise RuntimeError(f"the virtual lab did not start (exit {process.wait()}){self._last_words()}")
            name, _, address = line.decode(errors="replace").strip().partition(" ")
            if name and address:
                found[name] = address
        return found

    def _last_words(self) -> str:
        """': <the last line of the lab's log>' (its one-line error), or ''."""
        if self.log_path is None or not self.log_path.exists():
            return ""
        text = [x for x in self.log_path.read_text(errors="replace").splitlines() if x.strip()]
        return f": {text[-1].strip()}" if text else ""

    @property
    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def stop(self, timeout_s: float = STOP_TIMEOUT_S) -> int | None:
        """Close the lab's standard input: it stops once its sphere is dark; returns its exit status (terminated
        after ``timeout_s``, a hang guard)."""
        process, self.process = self.process, None
        if process is None:
            return None
        if process.stdin is not None:
            try:
                process.stdin.close()
            except OSError as exc:
                log.debug("lab stdin: %s", exc)
        try:
            code = process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            log.error("the virtual lab (pid %d) did not stop within %g s: terminated", process.pid, timeout_s)
            process.terminate()
            code = process.wait(10)
        if self._log is not None:
            self._log.close()
            self._log = None
        if code == 0 and self.log_path is not None:
            self.log_path.unlink(missing_ok=True)
        return code

    def __enter__(self) -> LabProcess:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
