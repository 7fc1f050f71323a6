"""dualrgb.core.session: durable writes, manifest, resume, verify, SIGKILL mid-writes and disk-full behaviour."""
from __future__ import annotations

import errno
import hashlib
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from dualrgb.core.session import capture_session as session_mod
from dualrgb.core.session.capture_session import MANIFEST, CaptureSession
from dualrgb.core.session.manifest import SessionError
from dualrgb.drivers.camera.base import RawCapture
from dualrgb.simulation.lightsource import LightSource

ROOT = Path(__file__).resolve().parents[2]


def capture(i: int, size: int = 1000) -> RawCapture:
    data = (bytes([i % 251]) * size) + i.to_bytes(4, "little")
    return RawCapture(data=data, filename=f"DSC_{i:04d}.NEF", exposure_s=1 / 60, iso=100, aperture=8.0,
                      camera="Nikon D610")


def test_create_record_reopen(tmp_path):
    s = CaptureSession.create(tmp_path / "s1", {"operator": "ana", "object": "film 12"})
    light = LightSource((1, 6, 8), (1.0, 0.5, 1.0), name="light 1")
    e = s.record(capture(1), "dark", step_id="dark/0.0167/1", light=light, sphere_temperature_c=31.5,
                 settings={"iso": 100}, target="train")
    assert (s.path / e.file).read_bytes() == capture(1).data
    assert e.sha256 == hashlib.sha256(capture(1).data).hexdigest()
    s.record(capture(2), "flat", step_id="flat/light1/1", light=light)
    s2 = CaptureSession.open(s.path)
    assert s2.settings["operator"] == "ana"
    assert [x.role for x in s2.entries()] == ["dark", "flat"]
    assert s2.has_step("dark/0.0167/1") and not s2.has_step("dark/0.0167/2")
    d = s2.entries("dark")[0]
    assert d.light == {"leds": [1, 6, 8], "levels": [1.0, 0.5, 1.0], "name": "light 1"}
    assert d.sphere_temperature_c == 31.5 and d.exposure_s == pytest.approx(1 / 60) and d.meta["target"] == "train"
    assert d.iso == 100 and d.camera == "Nikon D610" and d.camera_filename == "DSC_0001.NEF"
    # manifest: one JSON object per line
    lines = (s.path / MANIFEST).read_text().splitlines()
    assert len(lines) == 2 and all(json.loads(x)["sha256"] for x in lines)
    assert s2.verify().valid and len(s2.verify().ok) == 2


def test_create_refuses_non_empty_folder(tmp_path):
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "junk").write_text("1")
    with pytest.raises(SessionError, match="not empty"):
        CaptureSession.create(tmp_path / "x")
    with pytest.raises(SessionError, match="not a capture session"):
        CaptureSession.open(tmp_path / "x")


def test_retake_supersedes_and_settings_update(tmp_path):
    s = CaptureSession.create(tmp_path / "s")
    s.record(capture(1), "target", step_id="t/1")
    s.record(capture(2), "target", step_id="t/1")
    assert len(s.entries()) == 1 and s.entries()[0].seq == 2
    assert len(s.entries(include_superseded=True)) == 2
    s.update_settings(lights=[{"name": "a"}])
    assert CaptureSession.open(s.path).settings["lights"] == [{"name": "a"}]


def test_verify_detects_corruption_missing_and_orphans(tmp_path):
    s = CaptureSession.create(tmp_path / "s")
    a = s.record(capture(1), "dark")
    b = s.record(capture(2), "dark")
    (s.path / a.file).write_bytes(b"x" * a.size)          # same size, other content
    os.unlink(s.path / b.file)
    (s.path / "stray.NEF").write_bytes(b"abc")
    rep = CaptureSession.open(s.path).verify()
    assert rep.corrupted == [a.file] and rep.missing == [b.file] and rep.orphans == ["stray.NEF"]
    assert not rep.valid


def test_truncated_last_line_is_ignored_and_next_append_is_clean(tmp_path, caplog):
    s = CaptureSession.create(tmp_path / "s")
    s.record(capture(1), "dark")
    with open(s.path / MANIFEST, "ab") as fh:       # what a kill in the middle of an append leaves
        fh.write(b'{"seq": 2, "file": "0002_dark_DS')
    s2 = CaptureSession.open(s.path)
    assert len(s2.entries()) == 1
    assert "truncated" in caplog.text
    s2.record(capture(3), "dark")
    s3 = CaptureSession.open(s.path)
    assert [e.seq for e in s3.entries()] == [1, 2]
    assert s3.verify().valid and len(s3.verify().skipped_lines) == 1


def _enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_disk_full_while_writing_raw(tmp_path, monkeypatch):
    s = CaptureSession.create(tmp_path / "s")
    s.record(capture(1), "dark")
    monkeypatch.setattr(session_mod.os, "write", _enospc)
    with pytest.raises(SessionError, match="disk full") as info:
        s.record(capture(2), "dark", step_id="d/2")
    assert info.value.errno == errno.ENOSPC
    monkeypatch.undo()
    assert not list(s.path.glob(".*.tmp")), "temp file must be removed"
    assert not s.has_step("d/2")
    s2 = CaptureSession.open(s.path)
    assert s2.verify().valid and not s2.verify().orphans and len(s2.entries()) == 1
    s2.record(capture(2), "dark", step_id="d/2")           # retry after freeing space works
    assert CaptureSession.open(s.path).has_step("d/2")


def test_disk_full_while_appending_manifest(tmp_path, monkeypatch):
    s = CaptureSession.create(tmp_path / "s")
    s.record(capture(1), "dark")
    before = (s.path / MANIFEST).read_bytes()
    real_write = os.write
    calls = {"n": 0}

    def flaky(fd, data):
        calls["n"] += 1
        if calls["n"] == 2:                # first call writes the raw file, second the manifest line
            real_write(fd, bytes(data)[:10])                 # a partial line reaches the disk, then ENOSPC
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, data)

    monkeypatch.setattr(session_mod.os, "write", flaky)
    with pytest.raises(SessionError, match="disk full"):
        s.record(capture(2), "dark")
    monkeypatch.undo()
    assert (s.path / MANIFEST).read_bytes() == before, "manifest rolled back to its last complete line"
    rep = CaptureSession.open(s.path).verify()
    assert rep.valid and not rep.orphans and not rep.skipped_lines


WRITER = textwrap.dedent("""
    import sys
    sys.path.insert(0, {root!r})
    from dualrgb.core.session.capture_session import CaptureSession
    from dualrgb.drivers.camera.base import RawCapture
    s = CaptureSession.open({path!r})
    i = 0
    while True:
        i += 1
        data = bytes([i % 251]) * 300000 + i.to_bytes(4, "little")
        e = s.record(RawCapture(data=data, filename="DSC_%04d.NEF" % i, exposure_s=0.01), "dark",
                     step_id="dark/%d" % i)
        print(e.step_id, e.file, flush=True)
""")


def test_sigkill_mid_writes_loses_nothing_recorded(tmp_path):
    s = CaptureSession.create(tmp_path / "s")
    s.close()                                      # the writer process takes the session's lock
    code = WRITER.format(root=str(ROOT), path=str(s.path))
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    confirmed = []
    try:
        deadline = time.monotonic() + 60
        while len(confirmed) < 15 and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            confirmed.append(line.split()[0])
        time.sleep(0.003)                          # land somewhere inside the next write
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
        proc.stdout.close()
    assert len(confirmed) >= 15, "writer did not get going"
    s2 = CaptureSession.open(s.path)                # removes temp files, tolerates a truncated line
    rep = s2.verify()
    assert rep.valid, rep.summary()
    for step in confirmed:                          # everything record() confirmed is there and intact
        assert s2.has_step(step)
    assert not list(s.path.glob(".*.tmp"))
    # the session can be resumed: the sequence skips recorded steps and goes on
    nxt = f"dark/{len(s2.entries(include_superseded=True)) + 1}"
    assert not s2.has_step(nxt)
    s2.record(capture(99), "dark", step_id=nxt)
    assert CaptureSession.open(s.path).verify().valid
