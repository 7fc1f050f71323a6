import numpy as np
import pytest

from dualrgb.simulation.datasets import default_setup, load_camera, load_leds, load_target
from dualrgb.simulation.spectral_io import SpectralDataError, read_spectral_csv, write_spectral_csv

GOOD = "# units: relative\n# source: test\nwavelength_nm,R,G,B\n400,0.1,0.2,0.3\n410,0.2,0.3,0.4\n420,0.3,0.4,0.5\n"


def _write(tmp_path, text, name="x.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_reads_good_file_with_meta(tmp_path):
    t = read_spectral_csv(_write(tmp_path, GOOD))
    assert t.columns == ["R", "G", "B"] and t.values.shape == (3, 3)
    assert t.meta["units"] == "relative"


@pytest.mark.parametrize("text,line,fragment", [
    ("wavelength_nm,R,G,B\n400,0.1,0.2,0.3\n410,0.2,0.3\n", 3, "expected 4 columns"),
    ("wavelength_nm,R,G,B\n400,0.1,0.2,0.3\n390,0.2,0.3,0.4\n", 3, "must increase strictly"),
    ("wavelength_nm,R,G,B\n400,0.1,0.2,0.3\n400,0.2,0.3,0.4\n", 3, "must increase strictly"),
    ("wavelength_nm,R,G,B\n400,0.1,nan,0.3\n410,0.2,0.3,0.4\n", 2, "not a finite number"),
    ("wavelength_nm,R,G,B\n400,0.1,-0.2,0.3\n410,0.2,0.3,0.4\n", 2, "negative value"),
    ("wavelength_nm,R,G,B\n400,0.1,abc,0.3\n410,0.2,0.3,0.4\n", 2, "is not a number"),
    ("wavelength_nm,R,G,B\n0.4,0.1,0.2,0.3\n0.41,0.2,0.3,0.4\n", 2, "outside"),
    ("400,0.1,0.2,0.3\n410,0.2,0.3,0.4\n", 1, "expected a header row"),
    ("wavelength_nm,R,G,B\n400,0.1,0.2,0.3\n", 2, "at least two wavelength rows"),
])
def test_bad_files_give_one_line_errors_naming_file_and_line(tmp_path, text, line, fragment):
    p = _write(tmp_path, text)
    with pytest.raises(SpectralDataError) as err:
        read_spectral_csv(p)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith(f"{p}:{line}:")
    assert fragment in msg


def test_camera_needs_three_columns(tmp_path):
    p = _write(tmp_path, "wavelength_nm,R,G\n" + "".join(f"{w},0.1,0.2\n" for w in range(400, 790, 10)))
    with pytest.raises(SpectralDataError, match="expected 3 data columns"):
        load_camera(p)


def test_target_values_above_range_rejected(tmp_path):
    p = _write(tmp_path, "wavelength_nm,p1\n" + "".join(f"{w},2.5\n" for w in range(400, 790, 10)))
    with pytest.raises(SpectralDataError, match="exceeds 2"):
        load_target(p)


def test_data_not_covering_grid_rejected(tmp_path):
    p = _write(tmp_path, "wavelength_nm,p1\n" + "".join(f"{w},0.5\n" for w in range(500, 600, 10)))
    with pytest.raises(SpectralDataError, match="covers 500-590 nm"):
        load_target(p)


def test_user_csv_roundtrip_replaces_packaged_data(tmp_path):
    base = default_setup()
    p = tmp_path / "cam.csv"
    write_spectral_csv(p, base.grid.wavelengths, base.camera * 0.5, ["R", "G", "B"], {"units": "relative"})
    s = default_setup(camera_csv=str(p))
    assert np.allclose(s.camera, base.camera * 0.5)
    leds = tmp_path / "leds.csv"
    write_spectral_csv(leds, base.grid.wavelengths, base.leds.T, [f"LED{i}" for i in range(1, 11)], {})
    assert np.allclose(load_leds(leds, base.grid), base.leds)


def test_packaged_resources_have_provenance_headers():
    from dualrgb import resources
    for sub in ("leds", "cameras", "targets"):
        for f in resources.path(sub).glob("*.csv"):
            t = read_spectral_csv(f, allow_negative=False)
            assert {"units", "source", "generated_by"} <= set(t.meta), f


@pytest.mark.parametrize("step,n", [(1, 371), (5, 75), (10, 38), (20, 19)])
def test_every_grid_step_builds_a_consistent_setup(step, n):
    from dualrgb.simulation.grid import SpectralGrid
    s = default_setup("reflective", SpectralGrid(410, 780, step))
    assert len(s.grid) == n and s.cmfs.shape == (n, 3) and s.illuminant.shape == (n,)
    assert s.leds.shape == (10, n) and s.camera.shape == (n, 3) and s.train.spectra.shape[1] == n
