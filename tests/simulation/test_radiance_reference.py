"""Radiance references of a monochromator's output: spectroradiometer spectra (CSV, CGATS), radiance tables and a
calibrated photodiode, checked against hand computations; the virtual instruments' files read back; one-line
errors for bad files."""
from __future__ import annotations

import numpy as np
import pytest

from dualrgb.drivers.virtual.monochromator_light import MonochromatorOptics
from dualrgb.drivers.virtual.radiometers import VirtualPhotodiode, VirtualSpectroradiometer
from dualrgb.simulation.radiance_reference import (
    REDUCTION_METHODS,
    RadianceDataError,
    read_photodiode_reference,
    read_radiance_reference,
)
from dualrgb.simulation.spectral_io import SpectralDataError

WL = np.arange(380, 781, 1.0)


def triangle(centre: float, fwhm: float, peak: float) -> np.ndarray:
    return peak * np.clip(1 - np.abs(WL - centre) / fwhm, 0, None)


def write_spectra(path, columns: dict[str, np.ndarray], meta: str = "") -> None:
    lines = [meta, "wavelength_nm," + ",".join(columns)] if meta else ["wavelength_nm," + ",".join(columns)]
    lines += [f"{w:g}," + ",".join(f"{columns[c][i]:.9g}" for c in columns) for i, w in enumerate(WL)]
    path.write_text("\n".join(lines) + "\n")


def test_spectra_reduce_to_the_band_integral_or_the_peak(tmp_path):
    # triangles of known area: peak x FWHM (hand computation), on a 1 nm grid the trapezoid rule is exact
    p = tmp_path / "tsr.csv"
    write_spectra(p, {"mono_450": triangle(450, 5, 2.0), "550": triangle(550, 8, 3.0), "set_650nm":
                      triangle(650, 8, 1.5) + 0.001}, "# uncertainty_percent: 0.5")
    ref = read_radiance_reference(p)
    assert list(ref.wavelengths) == [450, 550, 650] and ref.kind == "spectroradiometer"
    assert ref.at(450) == pytest.approx((2.0 * 5, 0.005))
    assert ref.at(550)[0] == pytest.approx(3.0 * 8)
    assert ref.at(650)[0] == pytest.approx(1.5 * 8 + 0.001 * 40)          # the floor within +-20 nm counts
    assert ref.at(500)[0] == pytest.approx((10 + 24) / 2)                 # between readings: linear
    peak = read_radiance_reference(p, method="peak")
    assert [peak.at(w)[0] for w in (450, 550)] == pytest.approx([2.0, 3.0])
    assert set(REDUCTION_METHODS) == {"integral", "peak"}


def test_virtual_spectroradiometer_csv_and_cgats_agree_with_the_band_it_measured(tmp_path):
    optics = MonochromatorOptics()
    tsr = VirtualSpectroradiometer(optics, repeatability=0.0, sample_noise=0.0, floor=0.0)
    set_nm = [400.0, 550.0, 700.0]
    a = read_radiance_reference(tsr.write_csv(tmp_path / "r.csv", set_nm))
    b = read_radiance_reference(tsr.write_cgats(tmp_path / "r.cgats", set_nm))
    for nm in set_nm:
        wl = np.arange(nm - 7, nm + 7.001, 0.001)                           # the band, integrated finely by hand
        expected = np.sum(optics.spectrum(nm, wl)) * 0.001
        # sampled every 1 nm, the 6.4 nm triangle's corners fall between samples: +0.6 % (the same at every
        # wavelength, so the normalised CSRF does not see it)
        assert a.at(nm)[0] == pytest.approx(expected, rel=1e-2)
        assert b.at(nm)[0] == pytest.approx(a.at(nm)[0], rel=1e-6)


def test_radiance_table_with_uncertainty(tmp_path):
    p = tmp_path / "table.csv"
    p.write_text("wavelength_nm,radiance,u_radiance\n400,2.0,0.02\n410,4.0,0.2\n")
    ref = read_radiance_reference(p)
    assert ref.kind == "radiance table" and ref.at(410) == pytest.approx((4.0, 0.05))


def test_photodiode_gives_power_current_over_responsivity(tmp_path):
    resp, cur = tmp_path / "resp.csv", tmp_path / "cur.csv"
    resp.write_text("wavelength_nm,responsivity,u_responsivity\n400,0.2,0.002\n600,0.4,0.004\n")
    cur.write_text("wavelength_nm,photocurrent,u_photocurrent\n400,1e-9,3e-12\n500,3e-9,0\n600,2e-9,2e-11\n")
    ref = read_photodiode_reference(resp, cur)
    assert ref.at(400) == pytest.approx((1e-9 / 0.2, np.hypot(0.01, 0.003)))
    assert ref.at(500)[0] == pytest.approx(3e-9 / 0.3)                    # responsivity interpolated: 0.3 A/W
    assert ref.at(600) == pytest.approx((2e-9 / 0.4, np.hypot(0.01, 0.01)))


def test_virtual_photodiode_power_follows_the_band(tmp_path):
    optics = MonochromatorOptics()
    diode = VirtualPhotodiode(optics, noise=0.0)
    set_nm = [450.0, 600.0]
    diode.write(tmp_path / "r.csv", tmp_path / "i.csv", set_nm)
    ref = read_photodiode_reference(tmp_path / "r.csv", tmp_path / "i.csv")
    for nm in set_nm:
        wl = np.arange(nm - 7, nm + 7.001, 0.001)
        band = np.sum(optics.spectrum(nm, wl)) * 0.001
        assert ref.at(nm)[0] / 1e-6 == pytest.approx(band, rel=2e-3)         # etendue 1e-6 m2 sr


BAD = [
    ("wavelength_nm,mono_450,banana\n450,1,1\n451,1,1\n", "'banana' does not name a set wavelength"),
    ("wavelength_nm,radiance,extra\n450,1,1\n460,1,1\n", "unexpected column(s) extra"),
    ("wavelength_nm,radiance\n450,1\n460,-1\n", "column 'radiance' is negative"),
    ("wavelength_nm,mono_450,mono_450\n450,1,1\n451,1,1\n", "measured twice"),
    ("wavelength_nm,mono_700\n450,1\n451,1\n", "no positive reading within +-20 nm"),
    ("# uncertainty_percent: lots\nwavelength_nm,mono_450\n450,1\n451,1\n", "uncertainty_percent 'lots'"),
]


@pytest.mark.fault("input")
@pytest.mark.parametrize("text,fragment", BAD, ids=[b[1][:24] for b in BAD])
def test_bad_files_are_one_line_errors_naming_the_file(tmp_path, text, fragment):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(SpectralDataError) as info:
        read_radiance_reference(p)
    msg = str(info.value)
    assert "\n" not in msg and str(p) in msg and fragment in msg


@pytest.mark.fault("input")
def test_a_wavelength_outside_the_readings_is_refused(tmp_path):
    p = tmp_path / "table.csv"
    p.write_text("wavelength_nm,radiance\n400,2.0\n410,4.0\n")
    with pytest.raises(RadianceDataError, match="no reading at 420 nm"):
        read_radiance_reference(p).at(420)


@pytest.mark.fault("input")
def test_photodiode_outside_its_calibration_is_refused(tmp_path):
    resp, cur = tmp_path / "resp.csv", tmp_path / "cur.csv"
    resp.write_text("wavelength_nm,responsivity\n400,0.2\n600,0.4\n")
    cur.write_text("wavelength_nm,photocurrent\n380,1e-9\n600,2e-9\n")
    with pytest.raises(RadianceDataError, match="responsivity covers 400-600 nm"):
        read_photodiode_reference(resp, cur)
