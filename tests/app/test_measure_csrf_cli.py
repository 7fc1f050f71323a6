"""``dualrgb measure csrf``: the virtual lab end to end through the command line (camera CSV, JSON, the session
resumed), and one-line errors for options that cannot work, before any device is opened."""
from __future__ import annotations

import json

import pytest

from dualrgb.app.cli import main
from dualrgb.app.commands.measure_csrf import RADIANCE_METHODS
from dualrgb.simulation.radiance_reference import REDUCTION_METHODS
from dualrgb.simulation.spectral_io import read_spectral_csv

SHORT = ["--start", "500", "--end", "600", "--step", "50", "--frame-size", "96x64"]


def test_virtual_lab_writes_the_camera_csv_and_json(tmp_path, capsys):
    out = tmp_path / "cam.csv"
    args = ["measure", "csrf", "--virtual-lab", *SHORT, "--out", str(out), "--json", str(tmp_path / "r.json")]
    assert main(args) == 0
    stdout, stderr = capsys.readouterr()
    assert "camera CSV:" in stdout and "RMS error against the rendering camera" in stdout
    assert "[  3/4] 600 nm" in stderr and "virtual spectroradiometer" in stderr
    table = read_spectral_csv(out)
    assert list(table.wavelengths) == [500, 550, 600] and table.values[:, 1].max() == pytest.approx(1.0)
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["format"] == "dualrgb-csrf/1" and set(doc["rms_percent_of_peak"]) == {"red", "green", "blue"}
    assert (tmp_path / "cam-session" / "radiance-virtual.csv").is_file()
    # the same command again resumes the session: nothing is shot again
    n_files = len(list((tmp_path / "cam-session").glob("*.DNG")))
    assert main(args) == 0
    assert "kept" in capsys.readouterr().err and len(list((tmp_path / "cam-session").glob("*.DNG"))) == n_files


def test_the_world_is_rendered_and_recorded_in_the_session(tmp_path, capsys):
    out = tmp_path / "cam.csv"
    args = ["measure", "csrf", "--virtual-lab", *SHORT, "--out", str(out), "--world", "nikon-d700"]
    assert main(args) == 0
    definition = json.loads((tmp_path / "cam-session" / "session.json").read_text())["definition"]
    assert definition["world"].startswith("nikon-d700 (")
    capsys.readouterr()
    assert main(args[:-1] + ["sony-ilce-7rm2"]) == 1            # the same session in another world: refused
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "world" in err[0], err


BAD = [
    (["--manual", "--radiance", "{radiance}"], "name the camera"),
    (["--monochromator", "/dev/null", "--camera", "auto"], "needs the monochromator's radiance"),
    (["--virtual-lab", "--photodiode", "{radiance}"], "--photodiode and --photocurrent go together"),
    (["--virtual-lab", "--camera", "auto"], "--camera is for a real camera"),
    (["--manual", "--camera", "auto", "--radiance", "{radiance}", "--world", "nikon-d700"],
     "use it with --virtual-lab"),
    (["--virtual-lab", "--start", "700", "--end", "600"], "range 700-600 nm"),
    (["--virtual-lab", "--radiance", "{bad}"], "does not name a set wavelength"),
]


@pytest.mark.fault("input")
@pytest.mark.parametrize("args,fragment", BAD, ids=[b[1][:20] for b in BAD])
def test_bad_options_are_one_line_errors(tmp_path, capsys, args, fragment):
    radiance = tmp_path / "r.csv"
    radiance.write_text("wavelength_nm,radiance\n500,1\n600,1\n")
    bad = tmp_path / "bad.csv"
    bad.write_text("wavelength_nm,banana\n500,1\n600,1\n")
    args = [a.format(radiance=radiance, bad=bad) for a in args]
    assert main(["measure", "csrf", *args, "--out", str(tmp_path / "o.csv")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dualrgb: error: ") and fragment in err[0], err
    assert not (tmp_path / "o-session").exists()                       # refused before anything was opened


def test_the_parser_offers_the_reductions_the_reader_knows():
    assert set(RADIANCE_METHODS) == set(REDUCTION_METHODS)
