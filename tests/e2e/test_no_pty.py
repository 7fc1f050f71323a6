"""The virtual lab on an OS without POSIX terminals (issue 26): `dualrgb calibrate` and `dualrgb capture` in
processes where ``tty``, ``termios``, ``pty`` and ``fcntl`` cannot be imported and ``os.openpty`` is missing, as on
Windows. The instruments' emulators then serve pyserial's ``socket://127.0.0.1:PORT`` and the session lock goes
through filelock.

The blocker is a ``sitecustomize`` put first on PYTHONPATH. pyserial is imported before it blocks: its own platform
backend needs termios on POSIX (on Windows it loads serialwin32 instead), and what it took stays with it; the
blocked modules are then taken out of ``sys.modules``, so any other import of them fails.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BLOCKED = ("tty", "termios", "pty", "fcntl")
FRAME = ["--frame-size", "160x108", "--settle", "0"]
# the importers that try a POSIX module and do without it (as on Windows): the drivers' termios.error, the pty check,
# filelock's fcntl probe, the standard library's subprocess
GUARDED = {"dualrgb.drivers.led_sphere.driver", "dualrgb.drivers.monochromator.driver",
           "dualrgb.drivers.virtual.transport", "filelock._native._unix", "subprocess", "__main__"}
SITECUSTOMIZE = f'''
import os
import sys

import serial  # noqa: F401 - pyserial's own platform backend first (module docstring)

BLOCKED = {BLOCKED!r}
ATTEMPTS = []


class NoPosixTerminals:
    """Refuses the POSIX terminal modules, as an OS without them would."""

    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            frame = sys._getframe(1)
            while frame is not None and frame.f_globals.get("__name__", "").startswith(("importlib", "_frozen")):
                frame = frame.f_back
            ATTEMPTS.append(f"{{name}}<-{{frame.f_globals.get('__name__', '?') if frame else '?'}}")
            raise ImportError(f"No module named {{name!r}} (blocked: no POSIX terminals here)")
        return None


for _name in BLOCKED:
    sys.modules.pop(_name, None)
sys.meta_path.insert(0, NoPosixTerminals())
del os.openpty


def _report():
    report = os.environ.get("NO_PTY_REPORT")
    if report:
        with open(report, "a", encoding="utf-8") as fh:
            fh.write(" ".join(ATTEMPTS) + "\\n")


import atexit  # noqa: E402

atexit.register(_report)
'''


@pytest.fixture(scope="module")
def no_pty(tmp_path_factory):
    """Run ``dualrgb ARGS`` (and Python snippets) where the POSIX terminal modules cannot be imported."""
    root = tmp_path_factory.mktemp("no-pty")
    site = root / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(SITECUSTOMIZE, encoding="utf-8")
    report = root / "attempts.txt"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]),
           "NO_PTY_REPORT": str(report), "PYTHONUNBUFFERED": "1"}
    env.pop("DUALRGB_VIRTUAL_TRANSPORT", None)

    def run(*args: str, code: str | None = None) -> subprocess.CompletedProcess:
        argv = [sys.executable, "-c", code] if code is not None else [sys.executable, "-m", "dualrgb", *args]
        return subprocess.run(argv, capture_output=True, text=True, env=env, cwd=ROOT, timeout=1800)
    return root, run, report, env


def test_the_blocker_blocks(no_pty):
    _, run, _, _ = no_pty
    r = run(code="import os\nfor m in ('tty', 'termios', 'pty', 'fcntl'):\n    try:\n        __import__(m)\n"
                 "    except ImportError:\n        print('blocked', m)\nprint('openpty', hasattr(os, 'openpty'))")
    assert r.stdout.split("\n")[:5] == [*(f"blocked {m}" for m in BLOCKED), "openpty False"], r.stderr


def test_every_module_imports_without_posix_terminals(no_pty):
    """No dualrgb module imports a POSIX-only module at import time (the GUI's modules included)."""
    _, run, _, _ = no_pty
    names = sorted(".".join(("dualrgb", *p.relative_to(ROOT).with_suffix("").parts)).removesuffix(".__init__")
                   for pkg in ("app", "common", "drivers", "simulation", "resources")
                   for p in (ROOT / pkg).rglob("*.py") if p.name != "__main__.py")
    code = (f"import importlib\nfor name in {names!r}:\n    importlib.import_module(name)\n"
            f"print({len(names)}, 'modules')")
    r = run(code=code)
    assert r.returncode == 0, r.stderr[-3000:]
    assert int(r.stdout.split()[0]) > 200


def test_calibrate_and_capture_on_the_virtual_lab_without_a_pty(no_pty):
    root, run, report, _ = no_pty
    r = run("-v", "calibrate", "--session", str(root / "calib"), "--virtual-lab", "--hdr", "off", "--dark-frames", "1",
            "--flat-frames", "1", "--no-de-fit", "--json", str(root / "cal.json"), *FRAME)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "opened LED sphere port socket://127.0.0.1:" in r.stderr           # the emulator on loopback TCP
    cal = json.loads((root / "cal.json").read_text())
    r = run("capture", "--session", str(root / "originals"), "--calibration", cal["calibration"], "--id", "NOPTY-1",
            "--virtual-lab", "--json", str(root / "cap.json"), *FRAME)
    assert r.returncode == 0, r.stderr[-3000:]
    delivered = json.loads((root / "cap.json").read_text())
    assert delivered["original"]["identifier"] == "NOPTY-1" and Path(delivered["sidecar"]).is_file()
    assert delivered["new"] > 0 and all(Path(f).is_file() for f in delivered["files"].values())
    tried = set(report.read_text().split())
    print("blocked imports (module <- importer):", sorted(tried))
    assert {t.split("<-")[1] for t in tried} <= GUARDED, tried      # only where an ImportError is expected


def test_the_session_lock_refuses_a_second_writer_without_fcntl(no_pty):
    root, run, _, env = no_pty
    session = root / "locked"
    holder = ("import sys, time\nfrom dualrgb.core.session.capture_session import CaptureSession\n"
              f"s = CaptureSession.create({str(session)!r})\nprint('holding', flush=True)\ntime.sleep(600)")
    proc = subprocess.Popen([sys.executable, "-c", holder], stdout=subprocess.PIPE, text=True, cwd=ROOT, env=env)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "holding"
        r = run(code=f"from dualrgb.core.session.capture_session import CaptureSession\n"
                     f"CaptureSession.open({str(session)!r})")
        assert r.returncode != 0 and f"in use by another writer (pid {proc.pid}" in r.stderr, r.stderr[-2000:]
    finally:
        proc.kill()
        proc.wait(timeout=60)
        if proc.stdout is not None:
            proc.stdout.close()
