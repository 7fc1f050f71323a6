"""Spectral metrics against hand computations and colour-science (sd_to_XYZ, XYZ_to_Lab, delta_E)."""
from __future__ import annotations

import colour
import numpy as np
import pytest

from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.spectral_metrics import (
    OTHER_LIGHTS,
    delta_e_under,
    gfc,
    light_spd,
    seen_wavelengths,
    spectral_figures,
    spectral_rmse,
)


def test_rmse_and_gfc_by_hand():
    ref = np.array([[0.2, 0.4, 0.6, 0.8], [0.5, 0.5, 0.5, 0.5]])
    est = np.array([[0.1, 0.4, 0.7, 0.8], [1.0, 1.0, 1.0, 1.0]])
    assert np.allclose(spectral_rmse(est, ref), [np.sqrt(0.02 / 4), 0.5])
    assert np.allclose(spectral_rmse(est, ref, np.array([True, False, False, False])), [0.1, 0.5])
    dot = 0.02 + 0.16 + 0.42 + 0.64
    assert np.allclose(gfc(est, ref)[0], dot / np.sqrt((0.01 + 0.16 + 0.49 + 0.64) * (0.04 + 0.16 + 0.36 + 0.64)))
    assert gfc(est, ref)[1] == pytest.approx(1.0)                # proportional spectra fit perfectly
    assert gfc(np.zeros(4), ref[0]) == 0.0
    cube = np.broadcast_to(est[0], (3, 5, 4))                    # per pixel: any leading shape
    assert spectral_rmse(cube, ref[0]).shape == (3, 5)


def test_the_warm_white_led_exists_in_colour_science():
    assert set(OTHER_LIGHTS) == {"D65", "A", "D50", "FL11", "LED 2880 K"}
    assert "Luxeon WW 2880" in colour.SDS_LIGHT_SOURCES


@pytest.mark.parametrize("light", list(OTHER_LIGHTS))
def test_delta_e_under_other_lights_matches_colour_science(light):
    s = default_setup("reflective")
    rng = np.random.default_rng(1)
    ref = s.test.spectra[:6]
    est = np.clip(ref + rng.normal(0, 0.03, ref.shape), 0, 1)
    got = delta_e_under(est, ref, light, s.grid, s.cmfs)
    shape = colour.SpectralShape(410, 780, 10)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape)
    kind, key = OTHER_LIGHTS[light]
    spd = (colour.SDS_ILLUMINANTS if kind == "illuminant" else colour.SDS_LIGHT_SOURCES)[key].copy().align(shape)
    white = colour.sd_to_XYZ(colour.SpectralDistribution(np.ones(38), shape), cmfs, spd, method="Integration")
    xy = colour.XYZ_to_xy(white)
    expected = []
    for e, r in zip(est, ref, strict=True):
        labs = [colour.XYZ_to_Lab(colour.sd_to_XYZ(colour.SpectralDistribution(v, shape), cmfs, spd,
                                                     method="Integration") / 100, xy) for v in (r, e)]
        expected.append(colour.delta_E(labs[0], labs[1], method="CIE 2000"))
    assert np.allclose(light_spd(light, s.grid), spd.values)
    assert np.allclose(got, expected, atol=1e-6)


def test_figures_summarise_every_light_and_the_seen_range():
    s = default_setup("reflective")
    ref = s.test.spectra
    est = np.clip(ref * 1.05, 0, 1)
    f = spectral_figures(est, ref, s.grid, s.cmfs, seen_wavelengths(s.camera))
    assert set(f["de00"]) == set(OTHER_LIGHTS) and f["gfc"]["mean"] == pytest.approx(1.0)
    assert f["rmse"]["mean"] == pytest.approx(float(spectral_rmse(est, ref).mean()))
    assert f["gfc"]["very_good"] == 1.0 and f["rmse_seen"]["max"] <= f["rmse"]["max"] + 0.01
    seen = seen_wavelengths(s.camera)
    assert seen[0] and not seen[-1] and s.grid.wavelengths[seen].max() < 720      # the camera is blind in the NIR


def test_rmse_and_gfc_only_where_the_reference_was_measured():
    """The packaged CC24 (BabelColor) was measured to 730 nm; on the 410-780 nm grid its 740-780 nm values are the
    730 nm value held. The figures judge an estimate on 410-730 nm only (RMSE and GFC by hand there), the
    camera-seen RMSE on the measured wavelengths the camera sees; an error confined to 740-780 nm counts nowhere."""
    s = default_setup("reflective")
    wl = s.grid.wavelengths
    assert s.test.measured_range == (380.0, 730.0) and s.train.measured_range == (380.0, 780.0)
    keep = s.test.measured_mask(wl)
    assert wl[keep][0] == 410 and wl[keep][-1] == 730 and keep.sum() == 33
    ref = s.test.spectra
    est = ref.copy()
    est[:, wl > 730] = 0.0                                      # wrong only where nothing was measured
    est[:, wl == 500] += 0.02
    seen = seen_wavelengths(s.camera)
    f = spectral_figures(est, ref, s.grid, s.cmfs, seen, keep)
    assert f["rmse"]["mean"] == pytest.approx(np.sqrt(0.02 ** 2 / 33))
    by_hand = [np.dot(e[keep], r[keep]) / np.sqrt(np.dot(e[keep], e[keep]) * np.dot(r[keep], r[keep]))
               for e, r in zip(est, ref, strict=True)]
    assert f["gfc"]["mean"] == pytest.approx(float(np.mean(by_hand)))
    assert f["rmse_seen"]["mean"] == pytest.approx(np.sqrt(0.02 ** 2 / (keep & seen).sum()))
    assert f["wavelengths"] == {"measured": [410.0, 730.0], "seen": [410.0, float(wl[keep & seen][-1])]}
    everywhere = spectral_figures(est, ref, s.grid, s.cmfs, seen)
    assert everywhere["rmse"]["mean"] > 5 * f["rmse"]["mean"]         # the held values would dominate the figure
    with pytest.raises(ValueError, match="measured at none"):
        spectral_figures(est, ref, s.grid, s.cmfs, seen, np.zeros(len(wl), bool))


def test_a_stands_own_chart_keeps_its_measured_range_to_the_calibration():
    """A chart file measured 380-730 nm (X-Rite style, tests/data/charts) keeps that range through the chart and
    the calibration's TargetSpec, so the calibration's spectral figures count 410-730 nm only."""
    from pathlib import Path

    from dualrgb.app.workflow.calibration.targets import TargetSpec
    from dualrgb.core.vocabulary import Subject
    from dualrgb.simulation.charts import read_chart

    s = default_setup("reflective")
    path = Path(__file__).resolve().parents[1] / "data" / "charts" / "sg140_layout.txt"
    chart = read_chart(path, s.grid, role="train", mode="reflective")
    assert chart.target.measured_range == (380.0, 730.0) and chart.reference().measured_range == (380.0, 730.0)
    spec = TargetSpec(Subject.target("train"), np.zeros((len(chart.used), 3)), list(chart.target.patch_names),
                      chart=chart)
    assert spec.measured_range == (380.0, 730.0)
    assert TargetSpec(Subject.target("train"), np.zeros((1, 3)), ["x"]).measured_range is None
