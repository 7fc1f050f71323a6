"""Issue 22: one set of defaults (app.workflow.stand.defaults) that the CLI, the GUI and the demo read; sessions made
under a dated name in the captures folder (the per-user data folder, not the settings folder); the old default
captures folder found and moved without losing a session; each preset's expected captured error as `dualrgb
simulate` reports it for those lights."""
from __future__ import annotations

import datetime as dt
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from dualrgb import resources
from dualrgb.app.cli import build_parser, main
from dualrgb.app.commands import calibrate, stand_options
from dualrgb.app.workflow.calibration.preset_figures import preset_figures
from dualrgb.app.workflow.day.day import OriginalsQueue, OriginalState
from dualrgb.app.workflow.stand import defaults
from dualrgb.app.workflow.stand.folders import dated_name, legacy_captures, move_sessions, new_session, sessions_in
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.simulation.presets import load_preset

DAY = dt.date(2026, 11, 24)


def cli_choice(*argv: str):
    """What `dualrgb calibrate ARGV` resolves its defaults to: (preset, HDR plan, darks, flats)."""
    return calibrate.resolve(build_parser().parse_args(["calibrate", "--virtual-lab", *argv]))


def test_the_defaults_and_where_they_come_from(user_data_dir):
    d = defaults.workflow_defaults()
    packaged = json.loads(resources.path("parsimony.json").read_text())      # read here, not through the app
    from dualrgb.simulation.capture_model import CaptureModel

    cam = CaptureModel.virtual_lab("reflective").camera       # what every preset's expected figure assumes
    assert (d.mode, d.preset, d.hdr, d.virtual_original) == ("reflective", "reflective_pso", "auto", "painting")
    assert (d.dark_frames, d.flat_frames) == (cam.dark_frames, cam.flat_frames) == (10, 3)
    entry = packaged["modes"]["reflective"]                           # dualrgb-parsimony/2: one entry per mode
    assert d.hdr_exposures == entry["hdr_exposures"] == 2
    assert d.optimise_matrix is True and defaults.workflow_defaults("transmissive").optimise_matrix is True
    assert entry["characterisation_model"] in ("linear", "de-optimised")     # evidence only (issue 40)
    assert d.spectral_grid == (entry["spectral_start_nm"], entry["spectral_end_nm"], entry["spectral_step_nm"])
    film = packaged["modes"]["transmissive"]
    assert defaults.workflow_defaults("transmissive").spectral_grid == (
        film["spectral_start_nm"], film["spectral_end_nm"], film["spectral_step_nm"])
    assert d.captures == user_data_dir / "captures"                   # DUALRGB_DATA_DIR moves it (conftest)
    assert defaults.workflow_defaults("transmissive").preset == "transmissive_pso"
    with pytest.raises(ValueError, match="mode 'film': expected reflective or transmissive"):
        defaults.workflow_defaults("film")


def test_calibrate_resolves_its_defaults_from_the_one_place(monkeypatch):
    preset, hdr, darks, flats = cli_choice()
    assert preset.name == load_preset(defaults.default_preset_path()).name == "dual-RGB-PSO reflective"
    assert (hdr, darks, flats) == ("auto", 10, 3)
    assert cli_choice("--mode", "transmissive")[0].name == "dual-RGB-PSO transmissive"
    assert cli_choice("--hdr", "off", "--dark-frames", "2")[1:3] == ("off", 2)
    monkeypatch.setitem(defaults.PRESETS, "reflective", "reflective_exhaustive")   # change the one place ...
    monkeypatch.setattr(defaults, "DARK_FRAMES", 4)
    monkeypatch.setattr(defaults, "HDR_AUTO", False)
    preset, hdr, darks, flats = cli_choice()                                      # ... and the CLI follows
    assert (preset.name, hdr, darks, flats) == ("dual-RGB reflective", "off", 4, 3)
    from dualrgb.app.demo import DemoSettings
    from dualrgb.app.workflow.stand.copystand import StandSettings

    assert StandSettings().dark_frames == DemoSettings(out=Path("x")).dark_frames == 4


def test_sessions_get_dated_names_in_the_captures_folder(tmp_path):
    root = tmp_path / "captures"
    first = new_session(root, {"operator": "J. Doe"}, {"mode": "reflective"}, today=DAY)
    (root / "2026-11-24_2").mkdir()                   # a folder someone made by hand is never reused
    second = new_session(root, today=DAY)
    assert [first.path.name, second.path.name] == ["2026-11-24_1", "2026-11-24_3"]
    assert dated_name(root, DAY) == "2026-11-24_4"
    assert first.settings["operator"] == "J. Doe" and first.definition == {"mode": "reflective"}
    first.close()
    second.close()


class _Camera:
    name = "stub camera"

    def settings(self):
        from dualrgb.drivers.camera.base import CameraSettings
        return CameraSettings(iso=100, aperture=8.0)

    def config_summary(self):
        return {"camera": "stub", "serial": "1"}


def test_the_cli_without_session_makes_a_dated_one_in_the_captures_folder(user_data_dir, capsys):
    with stand_options.open_session(None, {"workflow": "calibrate"}, _Camera(), {"mode": "reflective"}) as s:
        assert s.path.parent == defaults.captures_dir() == user_data_dir / "captures"
        assert re.fullmatch(r"\d{4}-\d{2}-\d{2}_1", s.path.name), s.path.name
    assert f"new session {s.path}" in capsys.readouterr().err


@pytest.mark.parametrize("made_by", ["copy-stand", "calibrate", "originals"])
def test_a_day_session_takes_calibrate_and_capture_alike(tmp_path, made_by):
    """Issue 27: `calibrate --session day1` then `capture --session day1` share the session (workflow
    'copy-stand'); sessions made before by `calibrate` or `capture` ('calibrate' / 'originals') resume too."""
    folder = tmp_path / "day1"
    CaptureSession.create(folder, {}, definition={"workflow": made_by, "mode": "reflective"}).close()
    for run in ({"workflow": defaults.DAY_WORKFLOW, "mode": "reflective", "preset": "p"},
                {"workflow": defaults.DAY_WORKFLOW}):
        with stand_options.open_session(folder, run, _Camera()) as s:
            assert s.definition["workflow"] == made_by
    demo = CaptureSession.create(tmp_path / "demo", {}, definition={"workflow": "demo"})
    demo.close()
    from dualrgb.core.session.manifest import DefinitionMismatch

    with pytest.raises(DefinitionMismatch, match="workflow: session 'demo', this run 'copy-stand'"):
        stand_options.open_session(tmp_path / "demo", {"workflow": defaults.DAY_WORKFLOW}, _Camera())


def _old_session(folder: Path, name: str, delivered: str = "") -> Path:
    s = CaptureSession.create(folder / name, {"operator": "x"}, definition={"mode": "reflective"})
    if delivered:                          # a delivered original, as CopyStand records it (absolute sidecar)
        sidecar = s.path / "deliverables" / delivered / f"{delivered}.json"
        sidecar.parent.mkdir(parents=True)
        sidecar.write_text(json.dumps({"files": {"srgb": f"{delivered}_srgb_16bit.tif"}, "qa": {"text": "ok"}}))
        s.update_settings(originals={delivered: {"identifier": delivered, "sidecar": str(sidecar)}})
    s.close()
    return s.path


def test_the_old_default_captures_folder_is_found_and_moved_whole(tmp_path, user_data_dir):
    settings_dir, new = tmp_path / "config" / "dualrgb", defaults.captures_dir()
    old = settings_dir / "captures"
    assert legacy_captures(settings_dir, new) is None                       # nothing there: nothing offered
    first = _old_session(old, "session-20260101-090000", delivered="ACC-1")
    open_here = _old_session(old, "session-20260102-090000")
    (old / "test-shots").mkdir()
    found = legacy_captures(settings_dir, new)
    assert found is not None and found.sessions == [first, open_here] and "2 sessions" in found.text()
    assert legacy_captures(settings_dir, old) is None                       # it is the folder in use
    report = move_sessions(old, new, busy=[open_here])
    assert [p.name for p in report.moved] == ["session-20260101-090000", "test-shots"]
    assert report.kept == [(open_here, "open in this window")] and open_here.is_dir()
    moved = CaptureSession.open(new / first.name)                           # still a session, and its
    queue = OriginalsQueue.from_session(moved)                              # delivered original is found
    assert [(r.identifier, r.state) for r in queue.rows] == [("ACC-1", OriginalState.DELIVERED)]
    assert queue.rows[0].main_file == new / first.name / "deliverables" / "ACC-1" / "ACC-1_srgb_16bit.tif"
    moved.close()
    assert move_sessions(old, new).moved == [new / open_here.name] and not old.exists()
    assert sessions_in(new) == [new / first.name, new / open_here.name]


def test_a_session_another_program_holds_is_not_moved(tmp_path):
    old, new = tmp_path / "old", tmp_path / "new"
    held = _old_session(old, "held")
    code = ("import sys, time; from dualrgb.core.session import lock; lock.acquire(sys.argv[1]); print('locked', "
            "flush=True); time.sleep(60)")
    proc = subprocess.Popen([sys.executable, "-c", code, str(held)], stdout=subprocess.PIPE, text=True,
                            cwd=Path(__file__).resolve().parents[2], env={**os.environ})
    try:
        assert proc.stdout.readline().strip() == "locked"
        report = move_sessions(old, new)
    finally:
        proc.kill()
        proc.wait()
    assert report.moved == [] and report.kept[0][0] == held and "in use (pid" in report.kept[0][1]
    assert held.is_dir() and (held / "session.json").is_file()


@pytest.mark.parametrize("mode", ["reflective", "transmissive"])
def test_preset_figures_are_what_simulate_reports_for_those_lights(mode, tmp_path):
    out = tmp_path / "r.json"
    assert main(["simulate", "--mode", mode, "--method", "exhaustive", "--top", "1", "--json", str(out)]) == 0
    best = json.loads(out.read_text())["results"][0]
    exhaustive = load_preset(resources.path("presets", f"{mode}_exhaustive.json"))
    assert [list(s.leds) for s in exhaustive.sources] == [best["source1"], best["source2"]]
    fig = preset_figures(exhaustive)
    assert (round(fig.train, 4), round(fig.test, 4)) == (best["expected_train_de00_mean"],
                                                         best["expected_test_de00_mean"])
    recommended = preset_figures(load_preset(defaults.default_preset_path(mode)))
    assert recommended.train < fig.train and recommended.test < fig.test   # the default is the better choice
    assert recommended.text() == (f"expected ΔE00 {recommended.train:.2f} / {recommended.test:.2f}, per pixel "
                                  f"{recommended.pixel_test:.2f}")
    assert fig.pixel_test is not None and round(fig.pixel_test, 4) == best["per_pixel_test_de00_mean"]
    assert recommended.pixel_test is not None and recommended.pixel_test < fig.pixel_test    # per pixel too
