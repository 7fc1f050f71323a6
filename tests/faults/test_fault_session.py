"""Fault injection, session integrity (issue 9 items 5-10): sessions that cannot mix, double-write, lose the
light dose, process damaged frames, half-write a file or die on a strange manifest line."""
from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import textwrap

import pytest
from fault_rigs import ROOT

from dualrgb.app.demo import DemoSettings
from dualrgb.app.sequences.calibration import DarkSeries
from dualrgb.common.atomic_files import InsufficientSpaceError
from dualrgb.core.engine import RunEngine, StandDevices
from dualrgb.core.light_safety import SafetySettings
from dualrgb.core.session import capture_session as session_mod
from dualrgb.core.session.capture_session import MANIFEST, CaptureSession
from dualrgb.core.session.manifest import (
    DamagedFramesError,
    DefinitionMismatch,
    SessionEntry,
    SessionLockedError,
    light_definition,
)
from dualrgb.core.shooter import Shooter
from dualrgb.core.vocabulary import EventKind
from dualrgb.simulation.lightsource import LightSource

pytestmark = pytest.mark.fault("session integrity")

LS1 = LightSource((1, 6, 7), (0.0, 0.42, 1.0), "LS1")
DEFINITION = {"mode": "reflective", "frame_size": [600, 400], "seed": 0,
              "lights": {"dual_rgb_pso": [light_definition(LS1)]}, "camera": {"model": "D610", "iso": 100}}


def shooter_for(session, rig) -> Shooter:
    """The run engine's frame action (core.shooter) on the counting rig."""
    camera, sphere = rig
    return Shooter(camera, sphere, session, safety=SafetySettings(settle_s=0.0))


def engine_for(session, rig) -> RunEngine:
    camera, sphere = rig
    return RunEngine("test", StandDevices(camera, sphere, session, stand=lambda _what, _nd: None),
                     safety=SafetySettings(settle_s=0.0))


def cli(*argv: str, timeout: float = 120) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONWARNINGS": "ignore"}
    return subprocess.run([sys.executable, "-m", "dualrgb", *argv], capture_output=True, text=True, env=env,
                          cwd=ROOT, timeout=timeout)


# ---- 5. a resume with another definition is refused, naming the difference -------------------------------
@pytest.mark.parametrize("key,value", [
    ("mode", "transmissive"), ("seed", 7), ("frame_size", [4000, 3000]),
    ("lights", {"dual_rgb_pso": [{**light_definition(LS1), "levels": [0.0, 0.4200001, 1.0]}]}),
    ("camera", {"model": "D610", "iso": 200}),
])
def test_resume_with_another_definition_is_refused_naming_it(tmp_path, key, value):
    CaptureSession.create(tmp_path / "s", definition=DEFINITION).close()
    with pytest.raises(DefinitionMismatch) as info:
        CaptureSession.open(tmp_path / "s", definition={**DEFINITION, key: value})
    message = str(info.value)
    assert "\n" not in message and message.split(": ")[1:] and key in message
    assert CaptureSession.open(tmp_path / "s", definition=DEFINITION).definition == DEFINITION


def test_exposure_plan_decided_later_must_match_too(tmp_path):
    s = CaptureSession.create(tmp_path / "s", definition=DEFINITION)
    s.extend_definition(exposures={"LS1": [0.0125]})
    s.close()
    s = CaptureSession.open(tmp_path / "s", definition=DEFINITION)
    s.extend_definition(exposures={"LS1": [0.0125]})                  # the same plan resumes
    with pytest.raises(DefinitionMismatch, match=r"exposures\.LS1"):
        s.extend_definition(exposures={"LS1": [0.01]})


def test_new_session_when_asked_keeps_the_old_one(tmp_path):
    CaptureSession.create(tmp_path / "s", definition=DEFINITION).close()
    other = CaptureSession.resume(tmp_path / "s", {**DEFINITION, "seed": 7}, new_if_different=True)
    assert other.path.name == "s-2" and other.definition["seed"] == 7
    other.close()
    again = CaptureSession.resume(tmp_path / "s", {**DEFINITION, "seed": 7}, new_if_different=True)
    assert again.path.name == "s-2"                                  # resumes the matching sibling
    assert CaptureSession.open(tmp_path / "s", readonly=True).definition["seed"] == 0


@pytest.mark.parametrize("argv,key", [(["--mode", "transmissive"], "mode"), (["--seed", "7"], "seed"),
                                      (["--frame-size", "320x240"], "frame_size")])
def test_demo_resume_with_other_options_is_refused_before_anything_runs(tmp_path, argv, key):
    out = tmp_path / "demo"
    first = DemoSettings(out=out, frame_size=(240, 160), dark_frames=3)
    CaptureSession.create(out / "session", definition=first.definition()).close()
    r = cli("demo", "--out", str(out), "--frame-size", "240x160", "--dark-frames", "3", *argv)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1 and lines[0].startswith("dualrgb: error: "), r.stderr
    assert key in lines[0] and "--new-session" in lines[0]
    assert not (out / "report.json").exists() and not (out / "presets").exists()   # nothing ran


# ---- 6. one writer per session folder ----------------------------------------------------------------
HOLDER = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, {root!r})
    from dualrgb.core.session.capture_session import CaptureSession
    s = CaptureSession.open({path!r})
    print("holding", flush=True)
    time.sleep(120)
""")


@pytest.fixture()
def held_session(tmp_path):
    CaptureSession.create(tmp_path / "s").close()
    proc = subprocess.Popen([sys.executable, "-c", HOLDER.format(root=str(ROOT), path=str(tmp_path / "s"))],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "holding"
        yield tmp_path / "s", proc
    finally:
        proc.kill()
        proc.wait(timeout=30)
        proc.stdout.close()


def test_second_writer_is_refused_naming_the_holder(held_session):
    path, proc = held_session
    with pytest.raises(SessionLockedError) as info:
        CaptureSession.open(path)
    assert f"pid {proc.pid}" in str(info.value) and " since " in str(info.value)
    assert info.value.holder["pid"] == proc.pid and info.value.holder["host"]
    assert CaptureSession.open(path, readonly=True).entries() == []     # reading stays possible
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    CaptureSession.open(path).close()                                   # the OS released the dead holder's lock


def test_second_demo_on_the_same_out_is_refused(tmp_path):
    settings = DemoSettings(out=tmp_path, frame_size=(240, 160), dark_frames=3)
    path = str(tmp_path / "session")
    code = HOLDER.format(root=str(ROOT), path=path).replace(
        f"CaptureSession.open({path!r})", f"CaptureSession.resume({path!r}, {settings.definition()!r})")
    holder = subprocess.Popen([sys.executable, "-c", code],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "holding"
        r = cli("demo", "--out", str(tmp_path), "--frame-size", "240x160", "--dark-frames", "3")
        assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert f"in use by another writer (pid {holder.pid}" in r.stderr
    finally:
        holder.kill()
        holder.wait(timeout=30)
        holder.stdout.close()


# ---- 7. the light dose is in the manifest as it happens -------------------------------------------------
def test_light_dose_survives_a_crash_and_resume(tmp_path, rig):
    s = CaptureSession.create(tmp_path / "s")
    first = shooter_for(s, rig)
    for i in range(3):
        first.shoot("flat", LS1, 1 / 60, f"flat/{i}")
    del first, s                                                         # killed: nothing closed
    resumed = CaptureSession.open(tmp_path / "s")
    second = shooter_for(resumed, rig)
    for i in range(5):
        second.shoot("flat", LS1, 1 / 60, f"flat/{i}")                   # 0..2 skipped, 3..4 shot
    doses = [json.loads(line) for line in (tmp_path / "s" / MANIFEST).read_text().splitlines()
             if json.loads(line).get("kind") == "dose"]
    assert len(doses) == 5 and all(d["light"]["levels"] == [0.0, 0.42, 1.0] for d in doses)
    total = CaptureSession.open(tmp_path / "s", readonly=True).light_dose()
    assert total.on_s == pytest.approx(sum(d["on_s"] for d in doses))
    assert total.on_s > second.dose.on_s > 0                             # the in-memory dose saw 2 of 5
    with pytest.raises(ValueError):
        SessionEntry.from_dict(doses[0])                                 # an old reader skips the line


def test_dose_whose_write_fails_is_kept_and_written_with_the_next_line(tmp_path, monkeypatch):
    s = CaptureSession.create(tmp_path / "s")

    def full(*_a):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(session_mod.os, "write", full)
    s.record_dose(LS1, 0.5, step_id="flat/0")                           # never raises: the light was on
    monkeypatch.undo()
    s.record_dose(LS1, 0.25, step_id="flat/1")
    assert CaptureSession.open(tmp_path / "s", readonly=True).light_dose().on_s == pytest.approx(0.75)


# ---- 8. damaged frames are never processed and are shot again on resume -----------------------------------
def _shoot_darks(session, rig, n=4):
    sh = shooter_for(session, rig)
    return [sh.shoot("dark", None, 1 / 60, f"dark/{i}") for i in range(n)]


@pytest.mark.parametrize("damage", ["flip 8 bytes", "truncate", "delete"])
def test_damaged_frame_refuses_processing_naming_the_file(tmp_path, rig, damage):
    s = CaptureSession.create(tmp_path / "s")
    entries = _shoot_darks(s, rig)
    victim = s.file_path(entries[2])
    data = bytearray(victim.read_bytes())
    if damage == "flip 8 bytes":
        data[100:108] = bytes(b ^ 0xFF for b in data[100:108])
        victim.write_bytes(bytes(data))
    elif damage == "truncate":
        victim.write_bytes(bytes(data[:500]))
    else:
        victim.unlink()
    from dualrgb.app.workflow.calibration.session_processing import session_frames
    with pytest.raises(DamagedFramesError) as info:
        session_frames(s)
    assert str(info.value).startswith(str(victim)) and "\n" not in str(info.value)


def test_resume_sets_damaged_frames_aside_and_shoots_them_again(tmp_path, rig):
    s = CaptureSession.create(tmp_path / "s")
    entries = _shoot_darks(s, rig)
    corrupted, deleted = s.file_path(entries[1]), s.file_path(entries[3])
    bad = bytearray(corrupted.read_bytes())
    bad[50] ^= 0x01
    corrupted.write_bytes(bytes(bad))
    deleted.unlink()
    s.close()
    resumed = CaptureSession.resume(tmp_path / "s", {})
    assert not resumed.has_step("dark/1") and not resumed.has_step("dark/3") and resumed.has_step("dark/0")
    assert (tmp_path / "s" / "damaged" / entries[1].file).read_bytes() == bytes(bad)   # kept, never deleted
    camera = rig[0]
    before = camera.captures
    _shoot_darks(resumed, rig)
    assert camera.captures == before + 2                                  # exactly the two bad steps
    report = CaptureSession.open(tmp_path / "s", readonly=True).verify()
    assert report.valid and len(report.ok) == 4 and sorted(report.set_aside) == sorted([entries[1].file,
                                                                                          entries[3].file])


# ---- 9. atomic writes and the free-space check ---------------------------------------------------------
WRITERS = {
    "report.json": "from dualrgb.common.atomic_files import atomic_write; atomic_write(path, '{\"x\": 1}' * 400000)",
    "preset": ("from dualrgb.simulation.presets import Preset, save_preset; "
               "from dualrgb.simulation.lightsource import LightSource; "
               "save_preset(Preset('p' * 2000000, (LightSource((1,), (1.0,)),)), path)"),
    "rgb tiff": ("import numpy as np; "
                 "from dualrgb.app.processing.outputs import TiffMetadata, icc_profile, write_tiff; "
                 "write_tiff(path, np.ones((400, 400, 3), np.uint16), TiffMetadata('dualrgb'), photometric='rgb', "
                 "icc=icc_profile('sRGB'))"),
    "channels tiff": ("import numpy as np; from dualrgb.app.processing.outputs import TiffMetadata, write_tiff; "
                      "write_tiff(path, np.ones((300, 300, 6), np.uint16), TiffMetadata('dualrgb'))"),
    "patch csv": ("import numpy as np; from dualrgb.app.processing.outputs import write_patch_csv; n = 20000; "
                  "write_patch_csv(path, [str(i) for i in range(n)], np.ones((n, 6)), list('abcdef'), "
                  "np.ones((n, 3)), {}, {})"),
    "png figure": ("from dualrgb.app.processing.figure_files import new_figure, save_figure; "
                   "fig = new_figure(6, 6); ax = fig.add_subplot(111); "
                   "ax.imshow(__import__('numpy').random.rand(300, 300)); "
                   "save_figure(fig, path)"),
    "spectral csv": ("import numpy as np; from dualrgb.simulation.spectral_io import write_spectral_csv; "
                     "write_spectral_csv(path, np.arange(20000.), np.ones((20000, 8)), list('abcdefgh'), {})"),
    "session settings": ("from dualrgb.core.session.capture_session import CaptureSession; "
                         "s = CaptureSession.open(path.parent); s.update_settings(notes='n' * 300000)"),
}
FULL_DISK = textwrap.dedent("""
    import json, os, resource, signal, sys
    from pathlib import Path
    sys.path.insert(0, {root!r})
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)          # writes past the limit fail with EFBIG, like ENOSPC
    resource.setrlimit(resource.RLIMIT_FSIZE, (4096, resource.RLIM_INFINITY))
    results = {{}}
    for what, (path, code) in json.loads(sys.argv[1]).items():
        path = Path(path)
        try:
            exec(code)
        except OSError as exc:
            results[what] = "ERROR " + str(exc)
        else:
            results[what] = "WROTE"
    print(json.dumps(results))
""")
TARGET_NAMES = {"session settings": "s/session.json", "rgb tiff": "out.tif", "channels tiff": "out.tif",
                "png figure": "out.png"}


@pytest.fixture(scope="module")
def full_disk_results(tmp_path_factory):
    """Every writer once, in one process whose files may not grow past 4 KiB (a disk that fills up)."""
    root = tmp_path_factory.mktemp("full")
    jobs, before = {}, {}
    for what, code in WRITERS.items():
        target = root / what.replace(" ", "_") / TARGET_NAMES.get(what, "out.dat")
        target.parent.mkdir(parents=True)
        if what == "session settings":
            CaptureSession.create(target.parent).close()
        else:
            target.write_bytes(b"previous version\n")
        jobs[what] = (str(target), code)
        before[what] = (target, target.read_bytes())
    r = subprocess.run([sys.executable, "-c", FULL_DISK.format(root=str(ROOT)), json.dumps(jobs)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1]), before


@pytest.mark.parametrize("what", sorted(WRITERS))
def test_a_full_disk_leaves_the_previous_file_and_names_the_file(full_disk_results, what):
    results, before = full_disk_results
    target, old = before[what]
    assert results[what].startswith("ERROR") and str(target) in results[what], results[what]
    assert "\n" not in results[what]
    assert target.read_bytes() == old                                   # never a half-written file
    assert not [p for p in target.parent.iterdir() if p.name.endswith(".tmp")]


def test_sequence_larger_than_the_free_space_is_refused_before_any_shot(tmp_path, rig, monkeypatch):
    import shutil
    from collections import namedtuple

    s = CaptureSession.create(tmp_path / "s")
    camera, sphere = rig
    camera.frame_size_bytes = 30 * 2**20
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda _p: usage(2**40, 2**40 - 200 * 2**20, 200 * 2**20))
    engine = engine_for(s, rig)
    seq = DarkSeries(engine.facts, [1 / 60, 1 / 125], frames=10)      # 20 x 30 MiB > 200 MiB
    with pytest.raises(InsufficientSpaceError, match="dark series .*20 frames.* needs about") as info:
        engine.run_plan(seq)
    assert str(s.path) in str(info.value) and camera.captures == 0 and sphere.calls == []
    camera.frame_size_bytes = 1 * 2**20
    events = engine.run_plan(DarkSeries(engine.facts, [1 / 60], frames=3))
    assert len([e for e in events if e.kind is EventKind.FRAME]) == 3


# ---- 10. strange manifest lines, interrupted creation ------------------------------------------------
GOOD = {"seq": 1, "file": "0001_dark_a.NEF", "role": "dark", "sha256": "0" * 64, "size": 3}


@pytest.mark.parametrize("line", [
    "123", "null", "[1, 2]", '"text"', "true", "1.5e400",
    json.dumps({**GOOD, "seq": "1"}), json.dumps({**GOOD, "size": None}), json.dumps({**GOOD, "seq": True}),
    json.dumps({**GOOD, "file": "../../etc/passwd"}), json.dumps({**GOOD, "sha256": "xyz"}),
    json.dumps({**GOOD, "light": 5}), json.dumps({**GOOD, "light": {"leds": "123", "levels": []}}),
    json.dumps({**GOOD, "meta": []}), json.dumps({**GOOD, "exposure_s": "fast"}),
    json.dumps({"kind": "dose", "light": {"leds": [1], "levels": [1]}, "on_s": -1}),
    json.dumps({"kind": "dose", "light": None, "on_s": 1}), json.dumps({"kind": "alien"}), "[" * 100000,
])
def test_valid_json_that_is_not_a_record_is_skipped_and_reported(tmp_path, rig, line):
    s = CaptureSession.create(tmp_path / "s")
    _shoot_darks(s, rig, 2)
    with open(tmp_path / "s" / MANIFEST, "a") as fh:
        fh.write(line + "\n")
    s.close()
    s2 = CaptureSession.open(tmp_path / "s")
    assert len(s2.entries()) == 2 and s2.verify().skipped_lines == [3]
    _shoot_darks(s2, rig, 3)                                             # and it goes on
    assert CaptureSession.open(tmp_path / "s").verify().valid


def test_killed_between_settings_and_manifest_is_resumable(tmp_path, rig, monkeypatch):
    def killed(_p):
        raise KeyboardInterrupt                                          # the process dies right here
    monkeypatch.setattr(CaptureSession, "_create_manifest", staticmethod(killed))
    with pytest.raises(KeyboardInterrupt):
        CaptureSession.create(tmp_path / "s", definition=DEFINITION)
    monkeypatch.undo()
    assert (tmp_path / "s" / "session.json").exists() and not (tmp_path / "s" / MANIFEST).exists()
    s = CaptureSession.resume(tmp_path / "s", DEFINITION)
    _shoot_darks(s, rig, 2)
    assert CaptureSession.open(tmp_path / "s").verify().valid


def test_killed_before_settings_leaves_a_folder_a_new_session_can_use(tmp_path, monkeypatch):
    def killed(*_a, **_k):
        raise KeyboardInterrupt
    monkeypatch.setattr(session_mod, "atomic_write", killed)
    with pytest.raises(KeyboardInterrupt):
        CaptureSession.create(tmp_path / "s")
    monkeypatch.undo()
    CaptureSession.resume(tmp_path / "s", DEFINITION).close()           # the lock file alone is no obstacle
