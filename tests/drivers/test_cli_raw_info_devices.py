"""``dualrgb raw-info`` and ``dualrgb devices``: in-process through app.cli.main, and once each as a real
process for exit codes and the absence of tracebacks."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from rawtestfiles import D610_WHITE, mosaic_14bit, write_dng

import dualrgb.app.commands.devices as devices_cmd
from dualrgb.app.cli import main
from dualrgb.drivers.usb_discovery import CameraInfo, DeviceReport, SerialPortInfo

ROOT = Path(__file__).resolve().parents[2]


def run_cli(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    full_env = {k: v for k, v in os.environ.items() if k != "VCAMERADIR"}
    full_env.update(env or {})
    return subprocess.run([sys.executable, "-m", "dualrgb", *args], cwd=ROOT, env=full_env, capture_output=True,
                          text=True, timeout=120)


@pytest.fixture
def dng(tmp_path):
    data = mosaic_14bit(32, 48, seed=7)
    return write_dng(tmp_path / "DSC_0042.dng", data, cfa="GRBG"), data


# --------------------------------------------------------------------------------------------- raw-info
def test_raw_info_text(dng, capsys):
    path, data = dng
    assert main(["raw-info", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"file       {path}" in out
    assert "format     DNG" in out
    assert "camera     Nikon D610" in out
    assert "CFA        GRBG" in out
    assert "mosaic     48 x 32 px (W x H)" in out
    assert f"white      {D610_WHITE}" in out
    assert "exposure   1/125 s" in out
    for name in ("R", "G1", "G2", "B"):
        assert any(line.split()[0] == name for line in out.splitlines())


def test_raw_info_json_statistics(dng, capsys):
    path, data = dng
    assert main(["raw-info", str(path), "--json", "-"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["format"] == "dualrgb-raw-info/1" and info["software"]["libraw"]
    assert info["cfa_pattern"] == "GRBG"
    assert (info["width"], info["height"]) == (48, 32)
    assert info["white_level"] == D610_WHITE
    # GRBG: G1 at (0,0), R at (0,1), B at (1,0), G2 at (1,1)
    planes = {"G1": data[0::2, 0::2], "R": data[0::2, 1::2], "B": data[1::2, 0::2], "G2": data[1::2, 1::2]}
    assert list(info["channels"]) == ["R", "G1", "G2", "B"]
    for name, plane in planes.items():
        assert info["channels"][name]["mean"] == pytest.approx(plane.mean())
        assert info["channels"][name]["max"] == int(plane.max())
        assert info["channels"][name]["black"] == 600
    assert info["channels"]["G1"]["clipped_fraction"] == pytest.approx(1 / planes["G1"].size)


@pytest.mark.parametrize("content, words", [
    (b"just some notes\n", "not a raw file"),
    (b"", "file is empty"),
])
def test_raw_info_bad_file_in_process(tmp_path, capsys, content, words):
    bad = tmp_path / "bad.nef"
    bad.write_bytes(content)
    assert main(["raw-info", str(bad)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"dualrgb: error: {bad}: ") and words in err
    assert "\n" not in err


def test_raw_info_truncated_file_as_a_process(dng, tmp_path):
    path, _ = dng
    cut = tmp_path / "cut.dng"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    proc = run_cli("raw-info", str(cut))
    assert proc.returncode == 1
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"dualrgb: error: {cut}: truncated")
    assert "Traceback" not in proc.stderr


# ---------------------------------------------------------------------------------------------- devices
def test_devices_nothing_attached_in_process(monkeypatch, capsys):
    monkeypatch.setattr("dualrgb.drivers.usb_discovery.discover",
                        lambda probe, timeout_s: DeviceReport(serial_ports=[SerialPortInfo("/dev/ttyS0")]))
    assert main(["devices"]) == 1
    cap = capsys.readouterr()
    assert cap.out == ""
    assert cap.err.strip() == f"dualrgb: error: {devices_cmd.NOTHING_FOUND}"


def test_devices_lists_cameras_ports_and_hints(monkeypatch, capsys):
    report = DeviceReport(
        gphoto_cameras=[CameraInfo("Nikon DSC D610", "gphoto2", "usb:001,007", 0x04B0, 0x0434, 1, 7,
                                   status="open camera: ... claimed ... [gphoto2 -53]")],
        usb_cameras=[CameraInfo("Nikon D610", "usb", "", 0x04B0, 0x0434, 1, 7)],
        serial_ports=[SerialPortInfo("/dev/ttyS0"),
                      SerialPortInfo("/dev/ttyACM0", "Arduino Uno", vendor_id=0x2341, product_id=0x0043)],
        hints=["Nikon DSC D610 on usb:001,007 cannot be opened: claimed [gphoto2 -53]"])
    seen = {}

    def fake(probe, timeout_s):
        seen.update(probe=probe, timeout_s=timeout_s)
        return report

    monkeypatch.setattr("dualrgb.drivers.usb_discovery.discover", fake)
    assert main(["devices"]) == 0
    out = capsys.readouterr().out
    assert seen == {"probe": True, "timeout_s": 3.0}
    assert "Nikon DSC D610" in out and "usb:001,007" in out and "[04b0:0434]" in out and "NOT USABLE" in out
    assert out.count("Nikon") == 2        # the camera once (gphoto2 entry), plus the hint
    assert "/dev/ttyACM0" in out and "[2341:0043]" in out
    assert "/dev/ttyS0" not in out and "1 built-in" not in out
    assert "hint: Nikon DSC D610 on usb:001,007 cannot be opened" in out
    assert main(["devices", "--all", "--no-probe"]) == 0
    assert "/dev/ttyS0" in capsys.readouterr().out and seen["probe"] is False
    assert main(["devices", "--json", "-"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["format"] == "dualrgb-devices/1"
    assert d["gphoto_cameras"][0]["usb_id"] == "04b0:0434" and d["nothing_found"] is False


def test_devices_as_a_process_with_nothing_attached(tmp_path):
    proc = run_cli("devices", env={"XDG_CONFIG_HOME": str(tmp_path)})
    if proc.returncode == 0:
        pytest.skip(f"this machine has a camera or USB serial port attached:\n{proc.stdout}")
    assert proc.returncode == 1
    assert proc.stdout == ""
    assert proc.stderr.strip() == f"dualrgb: error: {devices_cmd.NOTHING_FOUND}"
    assert "Traceback" not in proc.stderr


def test_devices_as_a_process_with_the_virtual_camera(tmp_path):
    pytest.importorskip("gphoto2")
    folder = tmp_path / "vcamera"
    folder.mkdir()
    write_dng(folder / "VIRT_0001.DNG", mosaic_14bit(32, 32))
    proc = run_cli("devices", env={"VCAMERADIR": str(folder), "XDG_CONFIG_HOME": str(tmp_path / "xdg")})
    assert proc.returncode == 0, proc.stderr
    assert "Nikon DSC D750" in proc.stdout and "usb:001,001" in proc.stdout and "ready" in proc.stdout
    assert "Traceback" not in proc.stderr
