"""Reference XYZ of measured targets (eq 4.2 sum or ASTM E308) and CGATS / X-Rite import."""
from __future__ import annotations

from pathlib import Path

import colour
import numpy as np
import pytest

from dualrgb.simulation.cgats import CgatsError, read_cgats, read_cgats_spectra
from dualrgb.simulation.colorimetry import delta_e_2000, tristimulus, white_point, xyz_to_lab
from dualrgb.simulation.datasets import default_setup, load_target, target_xyz
from dualrgb.simulation.objective import PatchSet

XRITE = Path(colour.__file__).parent / "io" / "tests" / "resources" / "X-Rite_Digital_Colour_Checker.txt"


def test_eq_4_2_is_the_grid_sum_and_astm_e308_is_colour_science():
    s = default_setup()
    xyz, white = target_xyz(s, s.test)
    assert np.allclose(xyz, tristimulus(s.test.spectra, s.illuminant, s.cmfs))
    assert np.allclose(white, white_point(s.illuminant, s.cmfs))
    astm, white_astm = target_xyz(s, s.test, "astm-e308")
    table = s.test.measured
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    for j in (0, 5, 18, 23):                           # independent: one patch at a time through sd_to_XYZ
        sd = colour.SpectralDistribution(table.values[:, j], table.wavelengths)
        assert np.allclose(astm[j], colour.sd_to_XYZ(sd, cmfs, d65, method="ASTM E308"), atol=1e-9)
    assert white_astm == pytest.approx(np.asarray(colour.sd_to_XYZ(
        colour.SpectralDistribution(np.ones(len(table.wavelengths)), table.wavelengths), cmfs, d65,
        method="ASTM E308")), abs=1e-9)
    # the documented difference between the two integrations on the packaged CC24
    de = delta_e_2000(xyz_to_lab(xyz, white), xyz_to_lab(astm, white_astm))
    assert de.mean() == pytest.approx(0.078, abs=0.001) and de.max() == pytest.approx(0.256, abs=0.001)


def test_setup_option_reaches_the_simulation():
    s = default_setup(reference_xyz="astm-e308")
    assert s.reference_xyz == "astm-e308" and default_setup().reference_xyz == "eq-4.2"
    ps = PatchSet(s, s.train)
    assert np.allclose(ps.xyz, target_xyz(s, s.train)[0]) and ps.white[0] == pytest.approx(95.047, abs=0.01)
    with pytest.raises(ValueError, match="astm-e309"):
        default_setup(reference_xyz="astm-e309")


# ---- CGATS / X-Rite ---------------------------------------------------------------------------------------
def test_xrite_file_matches_colour_science_reader():
    ref = colour.read_sds_from_xrite_file(XRITE)
    table = read_cgats_spectra(XRITE)
    assert table.columns == list(ref)
    for j, name in enumerate(table.columns):
        assert np.allclose(table.wavelengths, ref[name].wavelengths)
        assert np.allclose(table.values[:, j], ref[name].values)


CGATS17 = """CGATS.17
ORIGINATOR "test"
NUMBER_OF_FIELDS 8
BEGIN_DATA_FORMAT
SAMPLE_ID SAMPLE_NAME SPECTRAL_NM400 SPECTRAL_NM500 SPECTRAL_NM600 SPECTRAL_NM700 SPECTRAL_NM780 XYZ_Y
END_DATA_FORMAT
NUMBER_OF_SETS 3
BEGIN_DATA
1 "dark skin" 5.0 6.0 12.0 20.0 22.0 10.1
2 "light skin" 20.0 30.0 55.0 60.0 61.0 35.2   # a comment
3 white 90.0 91.0 90.5 90.0 89.0 90.3
END_DATA
"""


def test_cgats17_spectra_in_percent_become_a_target(tmp_path):
    p = tmp_path / "chart.txt"
    p.write_text(CGATS17)
    t = read_cgats(p)
    assert t.fields[-1] == "XYZ_Y" and t.keywords["ORIGINATOR"] == "test" and t.row_lines == [9, 10, 11]
    target = load_target(p)                                # through the same entry point as spectral CSVs
    assert target.patch_names == ["dark skin", "light skin", "white"]
    assert np.allclose(target.measured.values[:, 1], [0.2, 0.3, 0.55, 0.6, 0.61])       # percent -> factors
    assert np.allclose(target.measured.wavelengths, [400, 500, 600, 700, 780])
    s = default_setup()
    xyz, white = target_xyz(s, target, "astm-e308")
    assert xyz.shape == (3, 3) and 85 < xyz[2, 1] < 95 and white[1] == pytest.approx(100.0)


@pytest.mark.parametrize("edit,message", [
    (lambda t: t.replace('3 white 90.0 91.0', '3 white 90.0'), ":11: 7 values, expected 8"),
    (lambda t: t.replace("NUMBER_OF_SETS 3", "NUMBER_OF_SETS 4"), "NUMBER_OF_SETS says 4 but 3 data rows"),
    (lambda t: t.replace("20.0 30.0", "20.0 n/a"), ":10: field SPECTRAL_NM500 'n/a' is not a number"),
    (lambda t: t.replace("5.0 6.0", "-5.0 6.0"), ":9: negative value -0.05 at 400 nm"),
    (lambda t: t.replace("SPECTRAL_NM", "REFL_"), "no spectral fields"),
    (lambda t: t.replace('"light skin"', '"light skin'), ":10: No closing quotation"),
    (lambda t: t.replace("BEGIN_DATA_FORMAT", "BEGIN_FORMAT"), "BEGIN_DATA before any BEGIN_DATA_FORMAT"),
])
def test_cgats_errors_are_one_line_naming_file_and_line(tmp_path, edit, message):
    p = tmp_path / "bad.cgats"
    p.write_text(edit(CGATS17))
    with pytest.raises(CgatsError) as exc:
        read_cgats_spectra(p)
    text = str(exc.value)
    assert message in text and "\n" not in text and str(p) in text
