"""Every JSON output starts with a format tag and the software versions (one function builds them); what the
app writes at run time goes to the per-user data folder, the packaged files stay the fallback."""
from __future__ import annotations

import json
from importlib import metadata
from pathlib import Path

import pytest

from dualrgb import resources
from dualrgb.simulation.versions import SOFTWARE, output_header, software_versions, stamped


def test_header_names_the_format_and_the_installed_versions():
    h = output_header("dualrgb-simulation/1")
    assert h["format"] == "dualrgb-simulation/1"
    for name in ("numpy", "numba", "colour-science", "rawpy"):
        assert name in SOFTWARE and h["software"][name] == metadata.version(name)
    assert h["software"]["dualrgb"] == metadata.version("dualrgb")
    import rawpy

    assert h["software"]["libraw"] == ".".join(map(str, rawpy.libraw_version))
    h["software"]["numpy"] = "changed"
    assert software_versions()["numpy"] == metadata.version("numpy")        # callers get their own copy
    with pytest.raises(ValueError, match="format tag 'preset'"):
        output_header("preset")
    assert stamped("dualrgb-x/1", {"format": "old", "a": 1}) == {**output_header("dualrgb-x/1"), "a": 1}


def test_simulate_json_and_preset_carry_the_header(tmp_path):
    from dualrgb.app.cli import main
    from dualrgb.simulation.presets import load_preset

    out, preset = tmp_path / "r.json", tmp_path / "p.json"
    assert main(["simulate", "--method", "three-channel", "--json", str(out)]) == 0
    assert main(["simulate", "--method", "exhaustive", "--top", "1", "--preset-out", str(preset)]) == 0
    for path, fmt in ((out, "dualrgb-simulation/1"), (preset, "dualrgb-preset/1")):
        data = json.loads(path.read_text())
        assert data["format"] == fmt and data["software"] == software_versions()
    assert load_preset(preset).method == "exhaustive"


def test_simulate_json_to_stdout_is_only_json(capsys):
    from dualrgb.app.cli import main

    assert main(["simulate", "--method", "three-channel", "--json", "-"]) == 0
    data = json.loads(capsys.readouterr().out)                # no table mixed in
    assert data["format"] == "dualrgb-simulation/1" and data["method"] == "three-channel"


def test_study_output_json_keeps_its_own_format(tmp_path):
    from dualrgb.simulation.studies.common import StudyOutput

    out = StudyOutput(tmp_path)
    a = json.loads(out.write_json("speed_accuracy.json", {"runs": []}).read_text())
    b = json.loads(out.write_json("parsimony.json", {"format": "dualrgb-parsimony/1", "x": 1}).read_text())
    assert a["format"] == "dualrgb-study-speed-accuracy/1" and a["software"] == software_versions()
    assert b["format"] == "dualrgb-parsimony/1" and b["x"] == 1


def test_user_path_follows_the_environment(user_data_dir, monkeypatch):
    assert resources.user_path("studies", "x") == user_data_dir / "studies" / "x"
    monkeypatch.delenv("DUALRGB_DATA_DIR")
    import platformdirs

    assert resources.user_path() == Path(platformdirs.user_data_dir("dualrgb", appauthor=False))


def test_parsimony_defaults_user_copy_wins_packaged_is_the_fallback(user_data_dir):
    from dualrgb.simulation.defaults import FORMAT, load_defaults

    packaged = json.loads(resources.path("parsimony.json").read_text())
    for mode in ("reflective", "transmissive"):
        assert load_defaults(mode)["spectral_step_nm"] == packaged["modes"][mode]["spectral_step_nm"]
    mine = resources.user_path("parsimony.json")
    mine.parent.mkdir(parents=True)
    mine.write_text(json.dumps({"format": FORMAT, "modes": {"transmissive": {
        "spectral_step_nm": 5.0, "characterisation_model": "linear", "hdr_exposures": 3}}}))
    assert load_defaults("transmissive") == {"spectral_step_nm": 5.0, "spectral_start_nm": 410.0,
                                             "spectral_end_nm": 780.0, "characterisation_model": "linear",
                                             "hdr_exposures": 3, "hdr_merge": "thesis"}   # missing keys: the thesis'


def test_study_parsimony_writes_defaults_and_charts_to_the_user_folder(user_data_dir, monkeypatch, capsys):
    """The CLI wiring only (the study itself is tested in test_studies): a stub result stands in, once per mode."""
    import dualrgb.app.commands.study as study_cmd
    import dualrgb.simulation.studies.parsimony as parsimony
    import dualrgb.simulation.studies.parsimony_report as parsimony_report

    written = {}

    def fake_write_outputs(results, out, target):
        written.update(folder=out.folder, target=target, modes=[r.mode for r in results])

    class Result:
        def __init__(self, mode):
            self.mode, self.elapsed_s = mode, 0.0

        @staticmethod
        def defaults():
            return {"spectral_step_nm": 10.0, "spectral_start_nm": 410.0, "spectral_end_nm": 780.0,
                    "thesis_grid_acceptable": True, "characterisation_model": "linear", "hdr_exposures": 2}

    monkeypatch.setattr(parsimony, "parsimony", lambda spec, cfg, progress=None: Result(spec.mode))
    monkeypatch.setattr(parsimony_report, "write_outputs", fake_write_outputs)
    monkeypatch.setattr(study_cmd, "_done", lambda out, lines: 0)
    from dualrgb.app.cli import main

    assert main(["study", "parsimony", "--budget", "tiny", "--write-defaults"]) == 0
    assert written == {"folder": user_data_dir / "studies" / "parsimony",
                       "target": str(user_data_dir / "parsimony.json"), "modes": ["reflective", "transmissive"]}
    packaged = resources.path("parsimony.json")
    assert user_data_dir not in packaged.parents
