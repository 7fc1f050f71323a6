"""The GUI on Qt's real xcb platform plugin under Xvfb (issue 13, "The GUI on a real display"): the start-up probe
(app/gui/platform_check.py) passes, the window opens on xcb, and real mouse clicks go connect -> capture ->
results on the virtual lab. Skipped, saying why, where Xvfb or the xcb plugin's system libraries are missing
(CI has no Xvfb; `apt-get install xvfb` and the libraries docs/how-to/install.md names run it)."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def xvfb_skip_reason() -> str:
    if not sys.platform.startswith("linux"):
        return "the xcb platform plugin is for Linux / X11"
    if shutil.which("Xvfb") is None:
        return "Xvfb is not installed (Debian/Ubuntu: apt-get install xvfb)"
    from dualrgb.app.gui.platform_check import missing_xcb_libraries

    missing = missing_xcb_libraries()
    if missing:
        return f"the xcb plugin's system libraries are missing ({', '.join(missing)}): see docs/how-to/install.md"
    return ""


@pytest.fixture
def xvfb_display():
    """A private Xvfb server; yields its DISPLAY (':N', the number Xvfb chose itself)."""
    read, write = os.pipe()
    proc = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", "1400x900x24", "-nolisten", "tcp"],
                            pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    os.close(write)
    with os.fdopen(read) as pipe:
        number = pipe.readline().strip()
    try:
        if not number.isdigit():
            pytest.fail(f"Xvfb did not start: {proc.stderr.read().decode(errors='replace')[-500:]}")
        yield f":{number}"
    finally:
        proc.terminate()
        proc.wait(10)


@pytest.mark.skipif(bool(xvfb_skip_reason()), reason=xvfb_skip_reason() or "runs")
def test_gui_on_the_real_xcb_plugin(xvfb_display, tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    env.update(DISPLAY=xvfb_display, QT_QPA_PLATFORM="xcb", HOME=str(tmp_path), PYTHONUNBUFFERED="1")
    out = tmp_path / "report.json"
    proc = subprocess.run([sys.executable, "-m", "tests.gui.xcb_clickthrough", str(out)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=540)
    assert out.exists(), proc.stderr[-3000:]
    report = json.loads(out.read_text())
    assert report["probe"] is None, report["probe"]                       # the start-up probe finds nothing wrong
    assert report["platform"] == "xcb" and report["exposed"]
    assert proc.returncode == 0, (report, proc.stderr[-3000:])
    assert report["done"][-1] == "results" and report["test_mean_de00"] < 2.0
    assert all("colour accuracy only" in b for b in report["badges"])
    assert report["errors"] == [] and report["light_on"] is False
