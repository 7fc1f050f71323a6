"""The virtual lab is devices, nothing more (issue 36): `dualrgb lab serve` in a process of its own prints one line
per instrument, and `dualrgb calibrate` / `capture` drive its addresses exactly as a physical stand's (`--port`,
`--camera`, `--stand`, the grids placed by hand as files, the target's width typed); `--virtual-lab` is the same
through a child process; the truth is `dualrgb lab score`, a separate step, and no sidecar carries it."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dualrgb.app.lab.process import LabOptions, LabProcess
from dualrgb.drivers.virtual.lab_server import lit_periods

FRAME = (240, 160)
ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}


def dualrgb(*args: str, ok: bool = True) -> subprocess.CompletedProcess:
    r = subprocess.run([sys.executable, "-m", "dualrgb", *args], capture_output=True, text=True, env=ENV, timeout=600)
    if ok:
        assert r.returncode == 0, r.stderr[-3000:]
    return r


def test_lab_serve_prints_one_line_per_instrument_and_stops_on_sigterm(tmp_path):
    record = tmp_path / "light.jsonl"
    p = subprocess.Popen([sys.executable, "-m", "dualrgb", "lab", "serve", "--frame-size", "96x64",
                          "--light-record", str(record)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env=ENV)
    try:
        lines = [p.stdout.readline().strip() for _ in range(5)]                  # type: ignore[union-attr]
        names = [line.split(" ", 1)[0] for line in lines]
        assert names == ["sphere", "camera", "stand", "monochromator", "spectroradiometer"], lines
        addresses = dict(line.split(" ", 1) for line in lines)
        assert addresses["camera"].startswith("tcp://127.0.0.1:")
        assert all(addresses[n].startswith("socket://127.0.0.1:") for n in names if n != "camera")
        dualrgb("sphere", "--port", addresses["sphere"], "set", "4", "0.5")
        dark = _read(addresses["spectroradiometer"], b"MEAS?\n")
        dualrgb("sphere", "--port", addresses["sphere"], "on", "--max-on", "5")          # lit for 5 s at most
        lit = _read(addresses["spectroradiometer"], b"MEAS?\n")          # the spectroradiometer sees this sphere
        dualrgb("sphere", "--port", addresses["sphere"], "on", "--max-on", "0.3")       # ...at most 0.3 s from now
        deadline = time.monotonic() + 60                                                 # a hang guard
        while not (record.exists() and lit_periods(record)) and time.monotonic() < deadline:
            time.sleep(0.05)                                 # the lab writes the period's end as it happens
    finally:
        p.send_signal(signal.SIGTERM)
        assert p.wait(60) == 0
    (period,) = lit_periods(record)
    assert period["ended_by"] == "on-time limit" and period["levels"][3] == pytest.approx(0.5, abs=1e-4)
    assert dark[:2] == ["OK", "MEAS"] and lit[:2] == ["OK", "MEAS"]
    n = int(lit[3])
    radiance = [float(v) for v in lit[4:]]
    assert n == len(radiance) == 401 and max(radiance) > 50 * max(abs(float(v)) for v in dark[4:])
    from dualrgb.drivers.virtual.sphere_light import SphereLight
    from dualrgb.drivers.virtual.world import load_world

    leds = SphereLight(load_world(None))
    led4_peak = float(leds.wavelengths[int(leds.spectra(None).argmax(axis=1)[3])])   # the nominal world's LED 4
    assert abs(380 + radiance.index(max(radiance)) - led4_peak) <= 2


def _read(address: str, request: bytes) -> list[str]:
    """One request to a line instrument of the lab and its reply's words."""
    import serial

    with serial.serial_for_url(address, timeout=10) as port:
        port.write(request)
        return port.read_until(b"\n").decode().split()


@pytest.fixture(scope="module")
def lab():
    with LabProcess(LabOptions(frame_size=FRAME, stand_in="painting")) as running:
        yield running.addresses


def _grid_files(folder: Path) -> list[str]:
    """The targets' grids as a person would place them on this lab's frames (app.lab.targets), as files."""
    from dualrgb.app.lab.targets import lab_grids

    args = []
    for role, grid in lab_grids("reflective", FRAME).items():
        path = folder / f"{role}-grid.json"
        path.write_text(json.dumps({"corners": grid.corners.tolist(), "rows": grid.rows, "cols": grid.cols}))
        args += [f"--{role}-grid", str(path)]
    return args


def test_calibrate_and_capture_drive_the_lab_as_a_physical_stand(lab, tmp_path):
    stand = ["--port", lab["sphere"], "--camera", lab["camera"], "--stand", lab["stand"], "--settle", "0"]
    dualrgb("calibrate", "--session", str(tmp_path / "day"), "--hdr", "off", "--dark-frames", "2", "--flat-frames",
            "3", "--no-de-fit", "--target-width-mm", "280", *_grid_files(tmp_path), *stand,
            "--json", str(tmp_path / "cal.json"))
    cal = json.loads((tmp_path / "cal.json").read_text())
    assert cal["camera"]["world"].startswith("nominal (") and cal["ppi"] > 0
    assert cal["statistics"]["methods"][cal["statistics"]["best"]]["test"]["mean"] < 1.5
    dualrgb("capture", "--session", str(tmp_path / "day"), "--id", "ACC-1", *stand, "--resolution", "half",
            "--json", str(tmp_path / "ACC-1.json"))
    capture = json.loads((tmp_path / "ACC-1.json").read_text())
    side = json.loads(Path(capture["sidecar"]).read_text())
    assert "virtual_truth" not in side and "virtual truth" not in capture["qa"]["text"]
    score = json.loads(dualrgb("lab", "score", str(tmp_path / "day"), "--json", "-").stdout)
    (acc,) = score["originals"]
    assert score["format"] == "dualrgb-lab-score/1" and acc["identifier"] == "ACC-1"
    assert acc["shown_as"] == "painting" and acc["resolution"] == "half" and 0 < acc["xyz"]["mean"] < 3.0
    assert 0 < acc["spectral"]["rmse_mean"] < 0.1
    line = dualrgb("lab", "score", str(tmp_path / "day")).stdout
    assert line.startswith("ACC-1: virtual truth (painting, half): dE00 mean ")


@pytest.mark.fault("input")
def test_lab_score_names_an_original_the_session_did_not_deliver(tmp_path):
    (tmp_path / "session.json").write_text(json.dumps({"originals": {}}))
    r = dualrgb("lab", "score", str(tmp_path), "--original", "ACC-9=shadow", ok=False)
    assert r.returncode == 1 and "no delivered original ACC-9 (delivered: none)" in r.stderr
    r = dualrgb("lab", "score", str(tmp_path), "--original", "ACC-9", ok=False)
    assert r.returncode == 1 and "expected ID=NAME" in r.stderr


def test_a_capture_refused_for_its_iso_leaves_the_camera_and_the_plain_one_delivers(lab, tmp_path):
    """Over a lab served as a physical stand's devices (one camera across runs, as a tethered body): a capture asking
    for another ISO and aperture than the session was shot with is refused before the camera is set, so the run
    without them is not refused for what the refused one would have set."""
    stand = ["--port", lab["sphere"], "--camera", lab["camera"], "--stand", lab["stand"], "--settle", "0"]
    day = str(tmp_path / "day")
    dualrgb("calibrate", "--session", day, "--hdr", "off", "--dark-frames", "1", "--flat-frames", "1",
            "--no-de-fit", *_grid_files(tmp_path), *stand)
    refused = dualrgb("capture", "--session", day, "--id", "ACC-1", *stand, "--iso", "800", "--aperture", "11",
                      ok=False)
    assert refused.returncode == 1, refused.stderr[-3000:]
    dualrgb("capture", "--session", day, "--id", "ACC-1", *stand, "--resolution", "half")     # not refused
    assert (tmp_path / "day" / "deliverables" / "ACC-1" / "ACC-1.json").is_file()
    assert "--iso 800: session" in refused.stderr and "ISO 50; nothing was set on the camera" in refused.stderr
