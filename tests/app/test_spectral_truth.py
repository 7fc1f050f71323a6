"""Per-pixel spectral RMSE against a ground truth (app.lab.spectral_truth), checked by hand: a constant
offset d at every wavelength is an RMSE of d; zero-mean noise that alternates between the pixels of a material
costs its amplitude per pixel and nothing per material; NaN spectra are counted, not compared."""
from __future__ import annotations

import numpy as np
import pytest

from dualrgb.app.lab.spectral_truth import SpectralTruth, compare_spectra_to_ground_truth, write_rmse_map_png

WL = np.arange(410.0, 790.0, 10.0)


def truth(h: int = 20, w: int = 30) -> SpectralTruth:
    rng = np.random.default_rng(0)
    labels = np.zeros((h, w), np.uint16)
    labels[:, w // 2:] = 1
    labels[h // 2:, :] += 2                              # four materials in quadrants
    return SpectralTruth(labels, rng.uniform(0.05, 0.9, (4, len(WL))), WL)


def test_a_constant_offset_is_its_own_rmse():
    t = truth()
    est = t.rows(0, 20) + 0.03
    r = compare_spectra_to_ground_truth(est, t, band_rows=6)
    assert r.mean == pytest.approx(0.03) and r.p90 == pytest.approx(0.03) and r.max == pytest.approx(0.03)
    assert r.material_mean == pytest.approx(0.03) and r.n_materials == 4 and r.n_pixels == 600


def test_noise_averages_out_per_material_but_not_per_pixel():
    t = truth()
    sign = np.where((np.indices((20, 30)).sum(0) % 2) == 0, 1.0, -1.0)[..., None]   # checkerboard: mean 0
    sign = sign * np.where(np.arange(len(WL)) % 2 == 0, 1.0, -1.0)                    # and across wavelengths
    est = t.rows(0, 20) + 0.05 * sign
    r = compare_spectra_to_ground_truth(est, t)
    assert r.mean == pytest.approx(0.05) and r.material_mean == pytest.approx(0.0, abs=1e-12)


def test_nan_spectra_are_counted_not_compared(tmp_path):
    t = truth()
    est = t.rows(0, 20).copy()
    est[3, 4] = np.nan
    est[0, 0] += 0.2                                     # one bad pixel: the max and the map show it
    r = compare_spectra_to_ground_truth(lambda r0, r1: est[r0:r1], t, band_rows=4)
    assert r.n_invalid == 1 and r.n_pixels == 599 and r.max == pytest.approx(0.2)
    assert np.isnan(r.rmse_map[3, 4]) and r.rmse_map[0, 0] == pytest.approx(0.2)
    assert write_rmse_map_png(tmp_path / "map.png", r.rmse_map, title="test").stat().st_size > 1000


def test_a_cube_of_another_size_is_refused_in_one_line():
    t = truth()
    with pytest.raises(ValueError) as info:
        compare_spectra_to_ground_truth(np.zeros((20, 29, len(WL))), t)
    assert "30 x 20 x 38" in str(info.value) and "\n" not in str(info.value)
