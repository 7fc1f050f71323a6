"""simulation/led_fit.py and the spectral CGATS files (simulation/cgats.py), against independent numbers:
colour-science's LED model with its FWHM solved by hand, exact synthetic curves, hand-written ArgyllCMS files."""
from __future__ import annotations

import colour
import numpy as np
import pytest
from scipy.optimize import brentq

from dualrgb.simulation.cgats import CgatsError, read_cgats_emission, read_cgats_spectra, write_cgats_spectra
from dualrgb.simulation.led_fit import band_output, fit_drift, fit_low_level, led_band, led_shape, min_stable_level
from dualrgb.simulation.sphere import LowLevelResponse


def _ohno_fwhm(half_width: float) -> float:
    """FWHM of Ohno's LED model S = (g + 2 g^5) / 3, g = exp(-(x / w)^2): solve S = 1/2 for x."""
    x = brentq(lambda x: (np.exp(-(x / half_width) ** 2) + 2 * np.exp(-(x / half_width) ** 2) ** 5) / 3 - 0.5,
               0.0, 3 * half_width)
    return 2 * x


@pytest.mark.parametrize("peak,width,step", [(550.0, 25.0, 1.0), (551.3, 25.0, 5.0), (447.6, 28.0, 5.0),
                                             (680.2, 22.0, 2.0)])
def test_led_shape_finds_peak_and_fwhm_of_colour_led_model(peak, width, step):
    sd = colour.sd_single_led(peak, shape=colour.SpectralShape(380, 780, 0.1), half_spectral_width=width)
    wl = np.arange(380, 780 + step / 2, step)
    spectrum = 3.0 * np.interp(wl, sd.wavelengths, sd.values)
    shape = led_shape(wl, spectrum)
    assert shape.peak_nm == pytest.approx(peak, abs=0.02)
    assert shape.fwhm_nm == pytest.approx(_ohno_fwhm(width), rel=0.005)
    assert shape.peak_value == pytest.approx(3.0 * sd.values.max(), rel=0.005)


def test_band_output_integrates_only_the_leds_band():
    wl = np.arange(380.0, 781.0)
    full = np.exp(-((wl - 500) / 20) ** 2)
    band = led_band(full)
    noise_elsewhere = full * 0.5 + np.where(band, 0.0, 0.3)
    assert band_output(wl, noise_elsewhere, band) == pytest.approx(0.5 * band_output(wl, full, band))


def test_min_stable_level_by_hand():
    levels = np.array([0.0, 0.002, 0.01, 0.02, 0.05, 1.0])
    outputs = np.array([0.0, 0.0005, 0.0096, 0.0205, 0.05, 1.0])      # 0.002: -75 %; 0.01: -4 %
    assert min_stable_level(levels, outputs, 0.05) == 0.01
    assert min_stable_level(levels, outputs, 0.03) == 0.02
    assert min_stable_level([0.5, 1.0], [0.5, 0.5], 0.05) == 1.0        # even full level off: nothing stable


@pytest.mark.parametrize("truth", [LowLevelResponse(0.008, 0.05, 1.6), LowLevelResponse(0.003, 0.02, 2.2),
                                   LowLevelResponse(0.0, 0.0, 1.0)])
def test_fit_low_level_recovers_exact_curves(truth):
    levels = np.array([0, 0.002, 0.004, 0.006, 0.008, 0.01, 0.0125, 0.015, 0.02, 0.025, 0.03, 0.04, 0.05, 0.06,
                       0.08, 0.1, 0.2, 0.5, 1.0])
    outputs = np.asarray(truth.output(levels.copy()), dtype=float)
    fit = fit_low_level(levels, outputs)
    fine = np.linspace(0.002, 0.1, 981)          # below the lowest measured level nothing constrains the fit
    np.testing.assert_allclose(fit.response.output(fine.copy()), truth.output(fine.copy()), atol=2e-4)
    assert fit.response.dead_band == pytest.approx(truth.dead_band, abs=2e-3)  # resolved to the level sampling
    if not truth.identity:
        assert fit.response.dead_band == pytest.approx(truth.dead_band, abs=3e-4)
        assert fit.response.knee == pytest.approx(truth.knee, abs=2e-3)
        assert fit.response.exponent == pytest.approx(truth.exponent, abs=0.05)


def test_fit_low_level_needs_the_low_end():
    with pytest.raises(ValueError, match="at least 4"):
        fit_low_level([0.5, 1.0], [0.5, 1.0])


def test_fit_drift_recovers_a_saturating_shift():
    t = np.arange(0, 3541, 60.0)
    truth = 4.0 * -np.expm1(-np.maximum(t - 10.0, 0) / 900.0)
    fit = fit_drift(t, truth + np.random.default_rng(1).normal(0, 0.02, t.size))
    assert fit.max_shift_nm == pytest.approx(4.0, abs=0.08) and fit.tau_s == pytest.approx(900, rel=0.05)
    np.testing.assert_allclose(fit.shift(t), truth, atol=0.05)
    flat = fit_drift(t, np.random.default_rng(2).normal(0, 0.02, t.size))
    assert np.abs(flat.shift(t)).max() < 0.05          # amplitude and time constant trade off: check the curve


# ---- spectral CGATS ---------------------------------------------------------------------------------------
ARGYLL_SP = """SPECT

DESCRIPTOR "Argyll spectral data"
ORIGINATOR "Argyll CMS"
KEYWORD "SPECTRAL_BANDS"
SPECTRAL_BANDS "5"
KEYWORD "SPECTRAL_START_NM"
SPECTRAL_START_NM "400.000000"
KEYWORD "SPECTRAL_END_NM"
SPECTRAL_END_NM "440.000000"
KEYWORD "SPECTRAL_NORM"
SPECTRAL_NORM "100.000000"

NUMBER_OF_FIELDS 5
BEGIN_DATA_FORMAT
SPEC_400 SPEC_410 SPEC_420 SPEC_430 SPEC_440
END_DATA_FORMAT

NUMBER_OF_SETS 1
BEGIN_DATA
10.0 50.0 -0.2 30.0 5.0
END_DATA
"""


def test_argyll_sp_file_reads_with_its_norm_and_file_name(tmp_path):
    path = tmp_path / "LED3_level0.05.sp"
    path.write_text(ARGYLL_SP)
    table = read_cgats_emission(path)
    assert table.columns == ["LED3_level0.05"]
    assert table.wavelengths.tolist() == [400, 410, 420, 430, 440]
    np.testing.assert_allclose(table.values[:, 0], [0.1, 0.5, -0.002, 0.3, 0.05])     # / SPECTRAL_NORM, negatives kept
    reflect = read_cgats_spectra(path)                                                # as reflectance: clipped at 0
    assert reflect.values.min() == 0.0 and reflect.values.max() == pytest.approx(0.5)


def test_cgats_spectral_keywords_must_match_the_fields(tmp_path):
    path = tmp_path / "bad.sp"
    path.write_text(ARGYLL_SP.replace('SPECTRAL_BANDS "5"', 'SPECTRAL_BANDS "36"'))
    with pytest.raises(CgatsError, match=r"bad.sp: SPECTRAL_BANDS '36' does not match"):
        read_cgats_emission(path)
    path.write_text(ARGYLL_SP.replace('SPECTRAL_NORM "100.000000"', 'SPECTRAL_NORM "zero"'))
    with pytest.raises(CgatsError, match="SPECTRAL_NORM 'zero'"):
        read_cgats_emission(path)


def test_cgats_writer_round_trips_through_the_reader(tmp_path):
    wl = np.arange(380.0, 781.0, 5.0)
    values = np.stack([np.sin(wl / 50) * 1e-3, np.cos(wl / 70) * 2e-5], axis=1)
    path = write_cgats_spectra(tmp_path / "r.ti3", wl, values, ["LED1_level1", "LED1_t60.0"],
                               keywords={"MEAS_TYPE": "EMISSION", "DUALRGB_UNITS": "W sr^-1 m^-2 nm^-1"})
    text = path.read_text()
    for needle in ('SPECTRAL_BANDS "81"', 'SPECTRAL_START_NM "380.000000"', 'SPECTRAL_END_NM "780.000000"',
                   'SPECTRAL_NORM "1.000000"', "SAMPLE_ID SPEC_380 SPEC_385"):
        assert needle in text
    table = read_cgats_emission(path)
    assert table.columns == ["LED1_level1", "LED1_t60.0"] and table.meta["dualrgb_units"] == "W sr^-1 m^-2 nm^-1"
    np.testing.assert_allclose(table.values, values, rtol=1e-7)
    with pytest.raises(ValueError, match="evenly spaced"):
        write_cgats_spectra(tmp_path / "x.ti3", np.array([380.0, 385.0, 395.0]), np.ones((3, 1)), ["a"])
