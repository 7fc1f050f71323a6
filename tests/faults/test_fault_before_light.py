"""Known before the light, said before the light (issue 28 item 3, 6): every check that depends only on the inputs
runs before any device acts. The exposure plan against the light-on cap with the settle time, free space for the
frames and the deliverables, preset levels that light nothing, camera curves and LED readings that cannot be
measurements: each is refused in one line and the sphere emulator's own record shows no lit period."""
from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from light_record import lit_spans
from workflow_profiles import make_profile

from dualrgb.app.cli import main
from dualrgb.app.session.capture_session import CaptureSession
from dualrgb.app.workflow.copystand import CopyStand, StandSettings
from dualrgb.app.workflow.light_safety import LightSafetyError
from dualrgb.app.workflow.metadata import Original
from dualrgb.app.workflow.queue_run import capture_queue
from dualrgb.common.atomic_files import InsufficientSpaceError

LAB_SHAPE = (64, 96)            # the fault suite's virtual lab (tests/faults/conftest.py)


@pytest.fixture
def stand(lab, tmp_path):
    def make(**settings):
        session = CaptureSession.create(tmp_path / f"session{len(made)}", {"test": "before the light"})
        made.append(session)

        def place(what: str, nd: bool = False):
            return lab.place("original:painting" if what.startswith("original:") else what, nd)
        return CopyStand(lab.camera, lab.sphere, session, stand=place,
                         settings=StandSettings(force=True, **settings))
    made: list = []
    yield make
    for session in made:
        session.close()


@pytest.mark.fault("light safety")
def test_an_exposure_plan_over_the_cap_with_the_settle_time_is_refused_before_metering(lab, stand, tmp_path):
    profile = make_profile(tmp_path / "cal", shape=LAB_SHAPE)                       # exposures 0.01 s and 0.5 s
    copy_stand = stand(settle_s=8.7)              # 8.7 + 0.5 + the camera's 1 s latency > 10 s; 0.01 s fits
    since = lab.emulator.clock()
    with pytest.raises(LightSafetyError, match=r"calibration cal-test, P light 1: exposure 0.5 s would keep the "
                                               r"light on up to 10.2 s \(settle 8.7 s"):
        copy_stand.capture(Original("ACC-1"), profile)
    assert lit_spans(lab.emulator, since) == [] and copy_stand.session.entries() == []


@pytest.mark.fault("session integrity")
@pytest.mark.parametrize("queue", [1, 3])
def test_no_room_for_the_deliverables_is_refused_before_the_first_frame(lab, stand, tmp_path, monkeypatch, queue):
    profile = make_profile(tmp_path / "cal", shape=LAB_SHAPE)
    copy_stand = stand(settle_s=0.0)
    from dualrgb.app.workflow import preflight

    frames = preflight.capture_frames(profile, 1, copy_stand.hdr_exposures(profile.mode)) * lab.camera.frame_bytes()
    room = int(1.1 * frames * queue) + 1024                        # the frames fit, the deliverables do not
    monkeypatch.setattr("dualrgb.common.atomic_files.free_bytes", lambda folder: room)
    since = lab.emulator.clock()
    originals = [Original(f"ACC-{i}") for i in range(queue)]
    with pytest.raises(InsufficientSpaceError, match=f"{queue} originals? .its raw frames and its deliverables. "
                                                     "needs about"):
        capture_queue(copy_stand, originals, profile)
    assert lit_spans(lab.emulator, since) == [] and copy_stand.session.entries() == []


def _preset(path: Path, levels) -> Path:
    path.write_text(json.dumps({"format": "dualrgb-preset/1", "name": "dark", "mode": "reflective",
                                "sources": [{"leds": [1, 6, 7], "levels": levels},
                                            {"leds": [3, 5, 9], "levels": [1.0, 1.0, 1.0]}]}))
    return path


def _spectral_csv(path: Path, header: str, row) -> Path:
    path.write_text(header + "\n" + "\n".join(row(w) for w in range(380, 790, 10)) + "\n")
    return path


BEFORE_DEVICES = {
    "a preset light with every level 0": (
        lambda tmp: ["calibrate", "--preset", str(_preset(tmp / "dark.json", [0.0, 0.0, 0.0]))],
        "dark light 1 ((1, 6, 7) @ (0, 0, 0)) has every LED level at 0, so it lights nothing"),
    "a preset light below the sphere's smallest step": (
        lambda tmp: ["calibrate", "--preset", str(_preset(tmp / "dim.json", [1e-7, 0.0, 0.0]))],
        "has every LED level at 0"),
    "an all-zero camera CSV": (
        lambda tmp: ["calibrate", "--camera-csv", str(_spectral_csv(tmp / "cam.csv", "wavelength_nm,R,G,B",
                                                                    lambda w: f"{w},0,0,0"))],
        "cam.csv: column 'R' is 0 at every wavelength; a camera channel must respond somewhere"),
    "a camera CSV without green": (
        lambda tmp: ["calibrate", "--camera-csv", str(_spectral_csv(tmp / "cam.csv", "wavelength_nm,R,G,B",
                                                                    lambda w: f"{w},0.5,0,0.2"))],
        "column 'G' is 0 at every wavelength"),
    "a NaN camera CSV": (
        lambda tmp: ["calibrate", "--camera-csv", str(_spectral_csv(tmp / "cam.csv", "wavelength_nm,R,G,B",
                                                                    lambda w: f"{w},0.5,NaN,0.2"))],
        "column 'G': NaN is not a finite number"),
}


@pytest.mark.fault("input")
@pytest.mark.parametrize("case", list(BEFORE_DEVICES))
def test_inputs_that_cannot_light_or_measure_are_refused_before_any_device(tmp_path, capsys, monkeypatch, case):
    args, says = BEFORE_DEVICES[case]
    opened = []
    monkeypatch.setattr("dualrgb.drivers.virtual.lab.VirtualLab.start", lambda self: opened.append(self))
    rc = main([*args(tmp_path), "--virtual-lab", "--session", str(tmp_path / "session")])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 1 and len(lines) == 1 and lines[0].startswith("dualrgb: error: ") and says in lines[0], err
    assert opened == [] and not (tmp_path / "session").exists()


def _readings(path: Path, full, low=0.01) -> Path:
    """One LED's readings at level 1 and 0.05 as a spectral CSV (``full(w)`` the full-level value)."""
    return _spectral_csv(path, "wavelength_nm,LED1_level1,LED1_level0.05",
                         lambda w: f"{w},{full(w)},{full(w) * 0.05 if isinstance(full(w), float) else full(w)}")


READINGS = {
    "1e308": (lambda w: 1e308, "value 1e+308 is not a radiance an LED gives"),
    "all zero": (lambda w: 0.0, "LED 1: every lit reading is 0 or below at every wavelength"),
    "negative": (lambda w: -0.02 if w == 500 else 0.1, "LED 1: a reading reaches -0.02, below the instrument noise"),
}


@pytest.mark.fault("input")
@pytest.mark.parametrize("case", list(READINGS))
def test_import_leds_refuses_readings_that_cannot_be_radiances(tmp_path, capsys, case):
    full, says = READINGS[case]
    rc = main(["measure", "import-leds", str(_readings(tmp_path / "r.csv", full)), "--out", str(tmp_path / "stand")])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 1 and len(lines) == 1 and says in lines[0], err
    assert not (tmp_path / "stand").exists()


@pytest.mark.fault("session integrity")
def test_a_camera_at_another_frame_size_than_the_calibration_is_refused_before_metering(lab, stand, tmp_path):
    profile = make_profile(tmp_path / "cal", shape=(160, 240))
    copy_stand = stand(settle_s=0.0)
    since = lab.emulator.clock()
    with pytest.raises(ValueError, match="the camera's frames are 96x64 px but calibration cal-test was made at "
                                         "240x160 px: set the same image size and area"):
        copy_stand.capture(Original("ACC-1"), profile)
    assert lit_spans(lab.emulator, since) == [] and copy_stand.session.entries() == []


@pytest.mark.fault("session integrity")
def test_a_session_resumed_at_another_frame_size_is_refused_at_once(tmp_path, capsys):
    profile = make_profile(tmp_path / "cal", shape=LAB_SHAPE).path
    session = tmp_path / "session"
    args = ["capture", "--virtual-lab", "--calibration", str(profile), "--id", "ACC-1", "--session", str(session),
            "--force", "--settle", "0"]
    main([*args, "--frame-size", "96x64"])                          # shot (delivered or not: the frames stay)
    capsys.readouterr()
    shot = sorted(p.name for p in session.iterdir())
    assert any(name.endswith(".DNG") for name in shot)
    rc = main([*args, "--frame-size", "128x96"])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 1 and len(lines) == 1, err
    assert "the session was made with other settings: image_area: session '96x64 px', this run '128x96 px'" \
        in lines[0], lines[0]
    assert sorted(p.name for p in session.iterdir()) == shot              # nothing shot, nothing re-used


def _sparse(path: Path, size: int = 2 ** 30) -> Path:
    """A file of ``size`` bytes that takes no disk (what a 1 GB export looks like to a reader)."""
    path.touch()
    os.truncate(path, size)
    return path


OVERSIZED = {
    "queue CSV": (lambda tmp: ["capture", "--virtual-lab", "--calibration", str(make_profile(tmp / "cal").path),
                               "--queue", str(_sparse(tmp / "q.csv")), "--session", str(tmp / "session")],
                  "q.csv: 1024.0 MiB is not a day's queue (at most 16 MiB)"),
    "patch grid JSON": (lambda tmp: ["calibrate", "--virtual-lab", "--train-grid", str(_sparse(tmp / "g.json")),
                                     "--session", str(tmp / "session")],
                        "g.json: 1024.0 MiB is too large for a patch grid JSON file (limit 1 MiB)"),
    "CGATS readings": (lambda tmp: ["measure", "import-leds", str(_sparse(tmp / "r.ti3")), "--out",
                                    str(tmp / "stand")], "r.ti3: 1024.0 MiB is too large"),
    "CSV readings": (lambda tmp: ["measure", "import-leds", str(_sparse(tmp / "r.csv")), "--out",
                                  str(tmp / "stand")], "r.csv: 1024.0 MiB is too large for a CSV file"),
    "calibration JSON": (lambda tmp: ["calibration", "show", str(_sparse(tmp / "c.json"))],
                         "c.json: 1024.0 MiB is too large for a calibration JSON file (limit 16 MiB)"),
}


@pytest.mark.fault("input")
@pytest.mark.parametrize("case", list(OVERSIZED))
def test_an_oversized_input_is_refused_before_it_is_read(tmp_path, capsys, monkeypatch, case):
    args, says = OVERSIZED[case]
    real = Path.read_bytes

    def read_bytes(self: Path) -> bytes:
        assert self.stat().st_size < 2 ** 29, f"{self} was read"
        return real(self)
    monkeypatch.setattr(Path, "read_bytes", read_bytes)
    rc = main(args(tmp_path))
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 1 and len(lines) == 1 and says in lines[0], err
    assert not (tmp_path / "session").exists()


PARSE_TIME = {
    "empty --id": (["capture", "--calibration", "{profile}", "--id", "  ", "--virtual-lab"], 2,
                   "argument --id: '  ': expected the original's identifier"),
    "--port without --camera": (["capture", "--calibration", "{profile}", "--id", "A", "--port", "/dev/ttyACM0"], 1,
                                "--port /dev/ttyACM0 without --camera"),
    "--camera without --port": (["calibrate", "--camera", "auto"], 1, "--camera 'auto' without --port"),
    "no devices": (["calibration", "show", "{profile}", "--camera", "auto"], 1, "without --port"),
}
PROBE = """
import sys
from dualrgb.app.cli import main
try:
    rc = main({argv!r})
except SystemExit as exc:
    rc = exc.code
print("RC", rc, "HEAVY", sorted(m for m in ("numpy", "colour", "rawpy", "numba", "scipy") if m in sys.modules))
"""


@pytest.mark.fault("input")
@pytest.mark.parametrize("case", list(PARSE_TIME))
def test_parse_time_errors_answer_before_the_heavy_imports(tmp_path, case):
    import subprocess
    import sys

    from fault_rigs import ROOT

    argv, code, says = PARSE_TIME[case]
    argv = [a.replace("{profile}", str(tmp_path / "cal.json")) for a in argv]
    (tmp_path / "cal.json").write_text("{}")
    r = subprocess.run([sys.executable, "-c", PROBE.format(argv=argv)], capture_output=True, text=True, cwd=ROOT,
                       timeout=120)
    assert f"RC {code} HEAVY []" in r.stdout, (r.stdout, r.stderr[-2000:])
    assert says in r.stderr.strip().splitlines()[-1]


@pytest.mark.fault("input")
@pytest.mark.parametrize("rows, says", [
    (",bad\n", "1 refused row (listed above); nothing was shot: fix it; no row is valid"),
    (",bad\nACC-1,good\n", "fix it, or --skip-invalid to shoot the other one")])
def test_a_queue_with_bad_rows_says_what_is_left(tmp_path, capsys, rows, says):
    queue = tmp_path / "q.csv"
    queue.write_text("identifier,title\n" + rows)
    rc = main(["capture", "--virtual-lab", "--calibration", str(make_profile(tmp_path / "cal").path), "--queue",
               str(queue), "--session", str(tmp_path / "session")])
    assert rc == 1 and says in capsys.readouterr().err.strip().splitlines()[-1]
