"""Master darks (8.2.1) and eq 7.1 flat fielding against known truth."""
from __future__ import annotations

import logging

import numpy as np
import pytest
from synthetic_frames import dark_frames, expose, mosaic_scene, patch_image, patch_reflectance, vignette

from dualrgb.app.processing.calibration import FlatField, MasterDark, combine_darks
from dualrgb.app.processing.mosaic import mosaic_from_rgb, row_bands, superpixel


def test_master_dark_rejects_transient_outliers_and_keeps_hot_pixels():
    h, w = 60, 80
    frames, truth, spiked = dark_frames(h, w, 0.5, n=10, noise=2.0, spikes=0.02)
    md = MasterDark()
    d = md.add(0.5, frames)
    err = np.abs(d.mean - truth)
    plain = np.mean(np.stack(frames).astype(float), axis=0)
    assert spiked.sum() > 50
    assert np.abs(plain - truth)[spiked].max() > 25, "the spikes must matter for a plain mean"
    # noise of an 8-sample mean ~ 2/sqrt(8) = 0.7 DN (+ rounding): no spike leaks through
    assert err[spiked].max() < 4.0
    assert err.mean() < 1.0
    hot = truth > truth.mean() + 500                   # persistent hot pixels stay in the master dark
    assert hot.sum() >= 10 and err[hot].max() < 4.0
    assert d.n_frames == 10 and d.rejected_high == 1 and d.rejected_low == 1
    assert d.spikes > 0.5 * spiked.sum()
    assert 1.0 < d.noise_dn < 3.5


def test_master_dark_by_exposure():
    md = MasterDark()
    for t in (1 / 60, 1 / 8):
        md.add(t, dark_frames(20, 30, t, n=5)[0])
    assert np.array_equal(md.get(0.0167), md.get(1 / 60))       # 1/60 s matches 0.0167 s (2 % tolerance)
    assert md.get(1 / 8).mean() > md.get(1 / 60).mean()
    with pytest.raises(KeyError, match="no master dark for 2 s"):
        md.get(2.0)


def test_few_dark_frames_fall_back_to_plain_mean(caplog):
    frames = dark_frames(10, 12, 1.0, n=3, spikes=0)[0]
    with caplog.at_level(logging.WARNING):
        mean, n, k_hi, k_lo, *_ = combine_darks(frames)
    assert (n, k_hi, k_lo) == (3, 0, 0) and "plain mean" in caplog.text
    assert np.allclose(mean, np.mean(np.stack(frames).astype(float), axis=0), atol=1e-3)


def flat_field_71(raw, dark, white, white_dark=None, *, raw_exposure_s=1.0, white_exposure_s=1.0):
    """Eq 7.1 with each image divided by its exposure time, through FlatField (as the pipeline uses it)."""
    white_dark = dark if white_dark is None else white_dark
    ff = FlatField((np.asarray(white, np.float32) - white_dark) / np.float32(white_exposure_s))
    return ff.apply((np.asarray(raw, np.float32) - dark) / np.float32(raw_exposure_s))


def test_eq_7_1_recovers_reflectance_under_vignetting():
    rows, cols = 3, 4
    refl = patch_reflectance(rows, cols)
    scene = mosaic_scene(refl, rows, cols, cell=8)                    # (48, 64) reflectance mosaic
    h, w = scene.shape
    light = 40000.0 * vignette(h, w, 0.6) * np.where(np.indices((h, w)).sum(0) % 2 == 0, 1.0, 0.7)
    dark = dark_frames(h, w, 0.1, n=1, noise=0)[1]
    white = expose(light, 0.1, dark)
    raw = expose(light * scene, 0.1, dark)
    ff = flat_field_71(raw, dark, white)
    assert np.nanmax(np.abs(ff - scene)) < 0.01                      # quantisation only
    # naive (no flat field) would be off by the vignetting: up to 60 %
    naive = (raw - dark) / np.median(white - dark)
    assert np.abs(naive - scene).max() > 0.2
    # different exposure times for white and image: divided by time first, then eq 7.1
    raw2 = expose(light * scene, 0.3, dark_frames(h, w, 0.3, n=1, noise=0)[1])
    ff2 = flat_field_71(raw2, dark_frames(h, w, 0.3, n=1, noise=0)[1], white, dark, raw_exposure_s=0.3,
                     white_exposure_s=0.1)
    assert np.nanmax(np.abs(ff2 - scene)) < 0.01
    # the superpixel of the flat-fielded mosaic gives the patch reflectances
    sp = superpixel(ff)
    assert np.allclose(sp[4, 4], refl[0], atol=0.01)


def test_flat_field_guards_zero_and_negative_denominators(caplog):
    white = np.full((4, 6), 1000.0)
    white[0, 0] = 0.0          # dead pixel
    white[1, 1] = -5.0         # dark larger than white
    white[2, 2] = 3.0          # below 1 % of the white level
    with caplog.at_level(logging.WARNING):
        out = FlatField(white).apply(np.full((4, 6), 500.0))
    assert np.isnan(out[0, 0]) and np.isnan(out[1, 1]) and np.isnan(out[2, 2])
    assert np.allclose(out[3], 0.5) and np.isfinite(out).sum() == 21
    assert "no usable white" in caplog.text
    with pytest.raises(ValueError, match="not brighter than the dark"):
        FlatField(np.zeros((4, 4)))


def test_flat_field_band_application_matches_whole():
    rng = np.random.default_rng(5)
    white = rng.uniform(500, 1000, (20, 10))
    img = rng.uniform(0, 800, (20, 10))
    ff = FlatField(white)
    whole = ff.apply(img)
    parts = np.empty_like(whole)
    for rows in row_bands(20, 6):
        ff.apply(img[rows], rows=rows, out=parts[rows])
    assert np.array_equal(whole, parts)


def test_superpixel_inverts_mosaic_from_rgb():
    rgb = patch_image(patch_reflectance(2, 3), 2, 3, cell=4)
    for cfa in ("RGGB", "BGGR", "GRBG", "GBRG"):
        assert np.allclose(superpixel(mosaic_from_rgb(rgb, cfa), cfa), rgb, atol=1e-6)
