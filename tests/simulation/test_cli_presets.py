import json
import subprocess
import sys

import pytest

from dualrgb.app.cli import main
from dualrgb.simulation.presets import PresetError, load_preset


def test_simulate_json_schema_and_preset(tmp_path, capsys):
    out, preset = tmp_path / "r.json", tmp_path / "p.json"
    assert main(["simulate", "--method", "exhaustive", "--top", "3", "--json", str(out),
                 "--preset-out", str(preset)]) == 0
    table = capsys.readouterr().out
    assert "(1, 6, 8)" in table and "(3, 5, 9)" in table
    data = json.loads(out.read_text())
    assert {"mode", "method", "seed", "elapsed_s", "evaluations", "three_channel", "results"} <= set(data)
    assert set(data["three_channel"]) == {"train", "test"}
    r0 = data["results"][0]
    assert r0["source1"] == [1, 6, 8] and r0["source2"] == [3, 5, 9]
    assert r0["intensities1"] == [1.0, 1.0, 1.0]
    assert r0["train_de00_mean"] <= data["results"][1]["train_de00_mean"]
    p = load_preset(preset)
    assert [s.leds for s in p.sources] == [(1, 6, 8), (3, 5, 9)] and p.method == "exhaustive"


def test_three_channel_method(tmp_path):
    out = tmp_path / "r.json"
    assert main(["simulate", "--method", "three-channel", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["results"] == [] and 1.0 < data["three_channel"]["train"] < 1.5


def test_bad_csv_is_one_line_error_without_traceback(tmp_path):
    bad = tmp_path / "cam.csv"
    bad.write_text("wavelength_nm,R,G,B\n400,1,2\n")
    r = subprocess.run([sys.executable, "-m", "dualrgb", "simulate", "--camera-csv", str(bad)],
                       capture_output=True, text=True)
    assert r.returncode == 1
    assert r.stderr.strip().count("\n") == 0 and "Traceback" not in r.stderr
    assert f"{bad}:2:" in r.stderr


@pytest.mark.parametrize("text,fragment", [
    ("{", "not valid JSON"),
    ('{"sources": []}', "non-empty 'sources'"),
    ('{"sources": [{"leds": [11], "levels": [1]}]}', "source 1: LED 11 is outside"),
])
def test_bad_presets(tmp_path, text, fragment):
    p = tmp_path / "p.json"
    p.write_text(text)
    with pytest.raises(PresetError, match=fragment):
        load_preset(p)


def test_cli_modes_and_methods_match_the_simulation():
    from dualrgb.app.commands import simulate
    from dualrgb.simulation.datasets import MODES
    from dualrgb.simulation.runner import METHODS
    assert simulate.MODES == MODES and simulate.METHODS == METHODS


def test_simulate_takes_its_default_grid_from_the_parsimony_study_per_mode(tmp_path, monkeypatch):
    import dualrgb.simulation.defaults as defaults

    chosen = {"reflective": (410.0, 20.0), "transmissive": (380.0, 5.0)}

    def fake(mode, path=None):
        start, step = chosen[mode]
        return {**defaults.FALLBACK_DEFAULTS, "spectral_start_nm": start, "spectral_step_nm": step}

    monkeypatch.setattr(defaults, "load_defaults", fake)
    out = tmp_path / "r.json"
    assert main(["simulate", "--method", "three-channel", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["setup"]["grid"] == "410-780 nm / 20 nm"
    assert main(["simulate", "--mode", "transmissive", "--method", "three-channel", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["setup"]["grid"] == "380-780 nm / 5 nm"
    assert main(["simulate", "--method", "three-channel", "--step", "5", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["setup"]["grid"] == "410-780 nm / 5 nm"


def test_simulate_objectives_and_capture_options(tmp_path):
    """Issue 14: the default objective is the expected captured error; --objective noise-free is the thesis'."""
    out = {}
    for objective in ("expected-captured", "noise-free"):
        out[objective] = tmp_path / f"{objective}.json"
        assert main(["simulate", "--mode", "transmissive", "--method", "exhaustive", "--objective", objective,
                     "--top", "2", "--json", str(out[objective])]) == 0
    ec, nf = (json.loads(out[k].read_text()) for k in ("expected-captured", "noise-free"))
    assert ec["objective"] == "expected-captured" and ec["capture"]["sphere"]["min_stable_level"] == 0.01
    assert (ec["results"][0]["source1"], ec["results"][0]["source2"]) == ([1, 6, 8], [3, 5, 9])
    assert (nf["results"][0]["source1"], nf["results"][0]["source2"]) == ([2, 5, 9], [2, 6, 9])
    for r in ec["results"] + nf["results"]:
        assert r["expected_train_de00_mean"] >= r["train_de00_mean"] - 1e-3
    default = tmp_path / "default.json"
    assert main(["simulate", "--mode", "transmissive", "--method", "exhaustive", "--min-level", "0.02",
                 "--reference-sd", "0.01", "--pixels", "400", "--json", str(default)]) == 0
    d = json.loads(default.read_text())
    assert d["capture"]["reference_gain_sd"] == 0.01 and d["capture"]["camera"]["pixels_per_patch"] == 400
    r = subprocess.run([sys.executable, "-m", "dualrgb", "simulate", "--min-level", "2"], capture_output=True,
                       text=True)
    assert r.returncode != 0 and "--min-level" in r.stderr and "Traceback" not in r.stderr
