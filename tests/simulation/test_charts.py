"""Spectral reference files as the field writes them (issue 27) and charts as data: NUMBER_OF_FIELDS that
disagrees with the format list is a warning, wavelengths from SPECTRAL_START_NM / _END_NM (3.33 nm files), the
extension beyond a file's measured range said in one warning line and refused beyond the limit, .ti3 written with
DEVICE_CLASS (ArgyllCMS's spec2cie reads it), and a chart's layout, patch placement, left-out patches, kind and
the profile's record."""
from __future__ import annotations

import logging
import shutil
import subprocess
from pathlib import Path

import colour
import numpy as np
import pytest

from dualrgb.simulation.cgats import CgatsError, read_cgats, read_cgats_spectra, write_cgats_spectra
from dualrgb.simulation.charts import ChartError, grid_labels, parse_layout, place_patches, read_chart
from dualrgb.simulation.datasets import MAX_EXTENSION_NM, default_setup, load_target
from dualrgb.simulation.grid import SpectralGrid
from dualrgb.simulation.spectral_io import SpectralDataError, write_spectral_csv

DATA = Path(__file__).resolve().parents[1] / "data" / "charts"
SG, CC24 = DATA / "sg140_layout.txt", DATA / "cc24_test.cie"
ARGYLL_CC24 = Path("/usr/share/color/argyll/ref/ColorChecker.cie")
GRID = default_setup("reflective").grid


def _cgats(path: Path, fields: list[str], rows: list[list[str]], keywords: str = "", n_fields: int | None = None):
    text = (f"CGATS.17\n{keywords}NUMBER_OF_FIELDS {n_fields or len(fields)}\nBEGIN_DATA_FORMAT\n{' '.join(fields)}\n"
            f"END_DATA_FORMAT\nNUMBER_OF_SETS {len(rows)}\nBEGIN_DATA\n" + "".join(" ".join(r) + "\n" for r in rows)
            + "END_DATA\n")
    path.write_text(text)
    return path


def test_number_of_fields_that_disagrees_with_the_format_is_a_warning(tmp_path, caplog):
    """A vendor file whose NUMBER_OF_FIELDS says 48 while DATA_FORMAT lists 46 (issue 27): read by the list, as
    ArgyllCMS does, with one warning line naming the file; the spectra are colour-science's reading of them."""
    fields = ["SAMPLE_ID", *(f"nm{w}" for w in range(380, 731, 10))]
    rows = [[f"P{i}", *(f"{0.1 + 0.01 * i + 0.001 * k:.4f}" for k in range(36))] for i in range(3)]
    path = _cgats(tmp_path / "vendor.txt", fields, rows, n_fields=len(fields) + 2)
    with caplog.at_level(logging.WARNING):
        table = read_cgats_spectra(path)
    line = f"{path}: NUMBER_OF_FIELDS says 39 but the data format lists 37 fields; the data rows match the list"
    assert table.warnings and table.warnings[0].startswith(line) and "\n" not in table.warnings[0]
    assert any(r.getMessage().startswith(line) for r in caplog.records if r.levelno == logging.WARNING)
    assert np.allclose(table.values[:, 2], [0.12 + 0.001 * k for k in range(36)])


def test_a_row_that_disagrees_with_the_format_list_is_still_refused(tmp_path):
    fields = ["SAMPLE_ID", "nm400", "nm500", "nm600"]
    path = _cgats(tmp_path / "short.txt", fields, [["A", "0.1", "0.2"]], n_fields=3)
    with pytest.raises(CgatsError, match=r"short.txt:8: 3 values, expected 4"):
        read_cgats(path)


def test_wavelengths_come_from_spectral_start_and_end_not_rounded_names(tmp_path):
    """A 3.33 nm file (106 bands over 380-730 nm) names its fields SPEC_383, SPEC_387 ...: the wavelengths are
    SPECTRAL_START_NM + k (END - START) / (BANDS - 1), exactly; names off by more than half a step are refused."""
    wl = np.linspace(380.0, 730.0, 106)
    fields = ["SAMPLE_ID", *(f"SPEC_{w:.0f}" for w in wl)]
    keywords = ('SPECTRAL_BANDS "106"\nSPECTRAL_START_NM "380.000000"\nSPECTRAL_END_NM "730.000000"\n'
                'SPECTRAL_NORM "1.0"\n')
    path = _cgats(tmp_path / "i1.ti3", fields, [["A", *(f"{0.5:.3f}" for _ in wl)]], keywords)
    table = read_cgats_spectra(path)
    assert np.allclose(table.wavelengths, wl, atol=1e-9) and table.wavelengths[1] == pytest.approx(383.333333)
    bad = _cgats(tmp_path / "bad.ti3", fields, [["A", *("0.5" for _ in wl)]],
                 keywords.replace('"730.000000"', '"780.000000"'))
    with pytest.raises(CgatsError, match=r"bad.ti3: SPECTRAL_START_NM / SPECTRAL_END_NM \(380-780 nm over 106 bands\)"):
        read_cgats_spectra(bad)


def test_an_extension_beyond_the_measured_range_is_said_and_refused_beyond_the_limit(tmp_path, caplog):
    """380-730 nm (vendors', an i1Pro's range) on the 410-780 nm grid: one warning line (file, range, how), and the
    note kept on the target; a file ending 60+ nm short of the grid is refused, naming the limit."""
    wl = np.arange(380.0, 731.0, 10.0)
    path = tmp_path / "i1pro.csv"
    write_spectral_csv(path, wl, np.full((len(wl), 2), 0.4), ["a", "b"], {"units": "reflectance factor"})
    with caplog.at_level(logging.WARNING):
        target = load_target(path, GRID)
    note = "380-730 nm measured; 730-780 nm held at the 730 nm values"
    assert target.extended == note
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warnings == [f"{path}: {note} (grid 410-780 nm / 10 nm)"]
    assert np.allclose(target.spectra[:, -5:], 0.4)
    short = tmp_path / "short.csv"
    cut = wl[wl <= 780 - MAX_EXTENSION_NM - 10]
    write_spectral_csv(short, cut, np.full((len(cut), 1), 0.4), ["a"], {})
    with pytest.raises(SpectralDataError, match=r"covers 380-710 nm .* at most 60 nm at either end is extended"):
        load_target(short, GRID)


def test_packaged_cc24_extension_is_recorded_not_warned(caplog):
    with caplog.at_level(logging.WARNING):
        test = default_setup("reflective", SpectralGrid(410, 780, 5)).test     # a fresh grid: read again
    assert test.extended == "380-730 nm measured; 730-780 nm held at the 730 nm values"
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_ti3_is_written_with_device_class_and_spec2cie_reads_it(tmp_path):
    wl = np.arange(380.0, 731.0, 10.0)
    path = write_cgats_spectra(tmp_path / "s.ti3", wl, np.full((len(wl), 2), 0.5), ["a", "b"])
    assert read_cgats(path).keywords["DEVICE_CLASS"] == "EMISSION"
    if shutil.which("spec2cie") is None:
        pytest.skip("ArgyllCMS (spec2cie) is not installed")
    out = tmp_path / "out.ti3"
    r = subprocess.run(["spec2cie", str(path), str(out)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "XYZ_Y" in read_cgats(out).fields


# ---- charts ----------------------------------------------------------------------------------------------
def test_layouts_and_grid_names():
    assert parse_layout("10x14") == (10, 14) and parse_layout(" 4 × 6 ") == (4, 6)
    with pytest.raises(ChartError, match="layout '10': expected ROWSxCOLUMNS"):
        parse_layout("10")
    assert grid_labels(["A1", "N10", "A01"]) is None                    # A1 and A01 are the same cell
    assert grid_labels(["A01", "B02"]) == [(0, 0), (1, 1)] and grid_labels(["dark skin"]) is None
    sg = [f"{chr(65 + c)}{r + 1}" for c in range(14) for r in range(10)]       # X-Rite's order: column by column
    cells = place_patches(sg, (10, 14))
    assert cells[:3] == [0, 14, 28] and cells[10] == 1 and sorted(cells) == list(range(140))    # letters: columns
    classic = [f"{chr(65 + r)}{c + 1}" for r in range(4) for c in range(6)]
    assert place_patches(classic, (4, 6)) == list(range(24))                      # letters: rows
    assert place_patches(["x", "y", "z"], (2, 2)) == [0, 1, 2]                    # other names: file order
    with pytest.raises(ChartError, match="they do not fit a 4x6 layout"):
        place_patches(sg[:20], (4, 6))


def test_the_sg_layout_chart_reads_with_its_layout_and_left_out_patches():
    border = [f"{chr(65 + c)}{r + 1}" for c in range(14) for r in range(10) if c in (0, 13) or r in (0, 9)]
    chart = read_chart(SG, GRID, role="train", mode="reflective", layout="10x14", leave_out=border[:4])
    assert (len(chart.target), chart.layout, len(chart.used)) == (140, (10, 14), 136)
    assert chart.cells[chart.target.patch_names.index("N10")] == 139
    assert chart.cells[chart.target.patch_names.index("B1")] == 1
    ref = chart.reference()
    assert len(ref) == 136 and "A1" not in ref.patch_names and ref.measured.values.shape == (36, 136)
    render = chart.render_target()
    assert render.layout == (10, 14) and len(render) == 140
    k = chart.target.patch_names.index("C5")
    assert np.array_equal(render.spectra[chart.cells[k]], chart.target.spectra[k])
    record = chart.record()
    assert record["file"] == "sg140_layout.txt" and len(record["sha256"]) == 64 and record["patches"] == 140
    assert record["used"] == 136 and record["wavelength_range_nm"] == [380.0, 730.0] and record["kind"] == "reflective"
    assert "NUMBER_OF_FIELDS says 40" in record["warnings"][0] and record["extended"].startswith("380-730 nm")


def test_a_chart_placed_out_of_file_order_renders_empty_cells_grey(tmp_path):
    wl = np.arange(380.0, 781.0, 10.0)
    path = tmp_path / "c.csv"
    x = np.maximum(wl - GRID.wavelengths[0], 0.0) / 400.0      # independent: 0.1, 0.5, 0.9 at the grid start
    write_spectral_csv(path, wl, np.stack([0.1 + 0.3 * x, 0.5 + 0.3 * x ** 2, 0.9 - 0.4 * x], axis=1),
                       ["B2", "A1", "A2"], {"units": "reflectance factor"})
    chart = read_chart(path, GRID, role="test", mode="reflective", layout="2x2")
    assert chart.cells == [3, 0, 1]
    render = chart.render_target()
    assert np.allclose(render.spectra[:, 0], [0.5, 0.9, 0.18, 0.1]) and render.patch_names[2] == "(empty 2)"


def test_the_reference_xyz_of_a_chart_file_matches_colour_science():
    """The CC24 test file's ASTM E308 XYZ against colour-science's own integration of Ohta's spectra."""
    from dualrgb.simulation.datasets import target_xyz

    chart = read_chart(CC24, GRID, role="test", mode="reflective")
    xyz, _ = target_xyz(default_setup("reflective"), chart.reference(), "astm-e308")
    ohta = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    d65, cmfs = colour.SDS_ILLUMINANTS["D65"], colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    ref = np.array([colour.sd_to_XYZ(sd, cmfs, d65, method="ASTM E308") for sd in ohta.values()])
    assert np.allclose(xyz, ref, atol=0.02)


@pytest.mark.fault("input")
@pytest.mark.parametrize("kwargs, says", [
    ({"layout": "3x5"}, "24 patches do not fit a 3x5 layout (15 cells)"),
    ({"leave_out": "A1,Z9"}, "cannot leave out 'Z9': no such patch"),
    ({"mode": "transmissive"}, "cc24_test.cie: a reflective"),
])
def test_a_chart_that_cannot_be_used_is_one_line(kwargs, says):
    options = {"role": "test", "mode": "reflective", **kwargs}
    grid = default_setup(options["mode"]).grid
    if kwargs.get("mode") == "transmissive":
        from dualrgb.app.workflow.calibration.targets import chart_of

        chart = read_chart(CC24, GRID, role="test", mode="reflective")
        with pytest.raises(ChartError, match=says):
            chart_of("transmissive", "test", {"test": chart})
        return
    with pytest.raises(ChartError) as info:
        read_chart(CC24, grid, **options)
    assert says in str(info.value) and "\n" not in str(info.value)


@pytest.mark.fault("input")
def test_a_transmittance_file_is_refused_for_a_reflective_calibration(tmp_path):
    wl = np.arange(380.0, 781.0, 10.0)
    path = tmp_path / "film.csv"
    x = (wl - wl[0]) / 400.0
    write_spectral_csv(path, wl, np.stack([0.2 + 0.3 * x, 0.5 + 0.3 * x ** 2, 0.8 - 0.4 * x], axis=1), ["a", "b", "c"],
                       {"units": "transmittance 0..1"})
    with pytest.raises(ChartError, match="holds transmittances .film., but this is a reflective calibration"):
        read_chart(path, GRID, role="train", mode="reflective")
    assert read_chart(path, default_setup("transmissive").grid, role="train", mode="transmissive").kind == \
        "transmissive"


@pytest.mark.fault("input")
def test_argyll_colorimetric_reference_is_refused_saying_spectra_are_needed():
    """ArgyllCMS's ref/ColorChecker.cie (Lab only, names A01 .. D06): refused in one line; its names place."""
    if not ARGYLL_CC24.is_file():
        pytest.skip("ArgyllCMS's reference files (argyll-ref) are not installed")
    with pytest.raises(CgatsError, match="no spectral fields .*LAB_L"):
        read_chart(ARGYLL_CC24, GRID, role="test", mode="reflective")
    names = read_cgats(ARGYLL_CC24).names()
    assert place_patches(names, (4, 6)) == list(range(24))
