"""kill -9 of a program driving the virtual lab while the light is on, watched from outside (issue 36).

The virtual lab runs in a process of its own (`dualrgb lab serve`), so when the program that lit its sphere is
killed, nothing but the sphere's own watchdog and on-time limit can switch the light off - as with a physical
sphere's firmware. Two cases:

* ``cli``: `dualrgb calibrate --port --camera --stand` against a lab this script started, killed with SIGKILL
  during a lit exposure (its cap: settle + exposure + the camera's latency allowance, sent with ``ON <ms>``);
* ``window``: the window (offscreen Qt) with the lab as its child, the manual light switched on (its cap: 10 s),
  the window killed with SIGKILL; the lab, left alone, goes on until its sphere is dark and exits.

The light is watched through the lab's light record (``--light-record``: every lit period's start and end on the
emulator's clock, written as they happen), never through the sphere's port (a request would restart its
watchdog). Per case: how long after the kill the sphere was dark, how long the lit period lasted, what ended it,
and (window) whether the lab exited by itself afterwards. ``python -m bench.lab_kill [OUT.json]``.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HANG_GUARD_S = 300.0
FRAME = (240, 160)
WINDOW_SCRIPT = """
import os, sys
os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
from PySide6.QtCore import QTimer
from dualrgb.app.gui.app import application
from dualrgb.app.gui.main_window import MainWindow
from dualrgb.simulation.lightsource import LightSource

app = application()
w = MainWindow(frame_size=(120, 80), show_dialogs=False)
w.show()

def lit():
    print("lit", w.lab.virtual_lab.process.process.pid, flush=True)

def connected():
    w.lab.apply_light(LightSource((4, 6), (0.5, 0.5)), switch_on=True, on_done=lit)

w.lab.start_virtual_lab(on_done=connected)
app.exec()
"""


def _wait(what, timeout_s: float = HANG_GUARD_S, step_s: float = 0.01) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = what()
        if value:
            return value
        time.sleep(step_s)
    raise TimeoutError(f"not within {timeout_s:g} s (a hang guard)")


def _after_kill(record: Path, lit: dict, t_kill: float) -> dict:
    """The lit period ``lit`` (its 'on' event) once it has ended, measured against the kill."""
    from dualrgb.drivers.virtual.lab_server import lit_periods

    ended = _wait(lambda: [p for p in lit_periods(record) if p["t_on"] == lit["t_on"]])[0]
    return {"kill_to_dark_s": round(ended["t_off"] - t_kill, 3), "lit_s": round(ended["t_off"] - ended["t_on"], 3),
            "lit_before_kill_s": round(t_kill - ended["t_on"], 3), "ended_by": ended["ended_by"]}


def kill_cli(folder: Path) -> dict:
    """`dualrgb calibrate` killed during a lit exposure (module docstring)."""
    from dualrgb.app.lab.process import LabOptions, LabProcess
    from dualrgb.app.lab.targets import lab_grids
    from dualrgb.drivers.virtual.lab_server import lit_now

    record = folder / "cli-light.jsonl"
    grids = []
    for role, grid in lab_grids("reflective", FRAME).items():
        path = folder / f"{role}.json"
        path.write_text(json.dumps({"corners": grid.corners.tolist(), "rows": grid.rows, "cols": grid.cols}))
        grids += [f"--{role}-grid", str(path)]
    with LabProcess(LabOptions(frame_size=FRAME, light_record=record)) as lab:
        a = lab.addresses
        cli = subprocess.Popen([sys.executable, "-m", "dualrgb", "calibrate", "--session", str(folder / "s"),
                                "--port", a["sphere"], "--camera", a["camera"], "--stand", a["stand"], "--hdr", "off",
                                "--dark-frames", "1", "--flat-frames", "2", "--no-de-fit", "--settle", "0.5",
                                "--target-width-mm", "280", *grids], stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
        try:
            lit = _wait(lambda: record.exists() and lit_now(record), step_s=0.005)
            cli.send_signal(signal.SIGKILL)
            t_kill = time.monotonic()
        finally:
            cli.kill()
            cli.wait()
        out = _after_kill(record, lit, t_kill)
    return {**out, "cap_s": "settle 0.5 s + the exposure + the camera's 1 s latency allowance (ON <ms>)",
            "watchdog_s": 30.0}


def kill_window(folder: Path) -> dict:
    """The window killed with its manual light on (module docstring)."""
    from dualrgb.drivers.virtual.lab_server import lit_now

    record = folder / "window-light.jsonl"
    env = {**os.environ, "DUALRGB_LAB_LIGHT_RECORD": str(record), "QT_QPA_PLATFORM": "offscreen",
           "DUALRGB_DATA_DIR": str(folder / "data"), "PYTHONUNBUFFERED": "1"}
    window = subprocess.Popen([sys.executable, "-c", WINDOW_SCRIPT], stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, env=env, text=True, cwd=folder)
    try:
        line = window.stdout.readline().split() if window.stdout is not None else []
        if line[:1] != ["lit"]:
            raise RuntimeError(f"the window did not light the sphere (it said {line!r})")
        lab_pid = int(line[1])
        lit = _wait(lambda: record.exists() and lit_now(record), step_s=0.005)
        window.send_signal(signal.SIGKILL)
        t_kill = time.monotonic()
    finally:
        window.kill()
        window.wait()
    out = _after_kill(record, lit, t_kill)
    exited = _wait(lambda: not _alive(lab_pid), timeout_s=60.0)
    return {**out, "cap_s": 10.0, "watchdog_s": 30.0, "lab_exited_after_dark": bool(exited),
            "lab_exit_after_kill_s": round(time.monotonic() - t_kill, 2)}


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie waiting to be reaped by init has exited)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    status = Path(f"/proc/{pid}/status")
    try:
        return "\nState:\tZ" not in status.read_text()
    except OSError:
        return status.parent.exists()


def bench_lab_kill() -> dict:
    """Both cases, each in a fresh temporary folder."""
    out = {}
    for name, case in (("cli", kill_cli), ("window", kill_window)):
        with tempfile.TemporaryDirectory(prefix=f"dualrgb-kill-{name}-") as tmp:
            out[name] = case(Path(tmp))
            print(name, out[name], flush=True)
    return out


if __name__ == "__main__":
    result = {"format": "dualrgb-lab-kill/1", **bench_lab_kill()}
    text = json.dumps(result, indent=2) + "\n"
    if len(sys.argv) > 1:
        Path(sys.argv[1]).write_text(text)
    print(text)
