"""HDR merge (eq 8.9, 8.2.2, 8.2.3) against known radiance; CaptureProcessor end to end on arrays."""
from __future__ import annotations

import logging

import numpy as np
import pytest

from app.processing.hdr import HdrMerge, exposure_weight, triangle_weight
from app.processing.pipeline import CaptureProcessor, ExposureRef
from simulation.progress import CancelToken, Cancelled
from synthetic_frames import BLACK, WHITE, dark_frames, expose, mosaic_scene, patch_reflectance, vignette


def test_eq_8_9_weight_scaled_to_the_usable_range():
    raw = np.array([600, 4600, 600 + (WHITE - 600) / 2, 11000, 11001, WHITE - 1, WHITE, 16000], dtype=float)
    w = exposure_weight(raw, raw - 600, WHITE, 600, 11000)
    span = WHITE - 600
    assert w[0] == 0 and w[1] == pytest.approx(4000 / span)
    assert w[2] == pytest.approx(0.5)                                  # peak at half the usable range
    assert w[3] == pytest.approx(1 - 10400 / span)                     # falling side up to the linear limit
    assert np.all(w[4:] == 0)                                          # non-linear / clipped: excluded
    # thesis form f(x) = x below 8192, 16383 - x above, for 14-bit dark-corrected x
    x = np.array([100.0, 8000, 9000, 16000])
    assert np.allclose(triangle_weight(x, 16383) * 16383, [100, 8000, 16383 - 9000, 16383 - 16000], atol=0.01)


def scene_radiance(h, w):
    """Radiance (DN/s) spanning ~1000:1 across the frame (log ramp) with a patch pattern."""
    x = np.linspace(0, 1, w)[None, :] * np.ones((h, 1))
    return 300.0 * 10 ** (3 * x) * (0.6 + 0.4 * (np.indices((h, w)).sum(0) % 3 == 0))


def test_hdr_recovers_radiance_that_one_exposure_clips():
    h, w = 40, 120
    L = scene_radiance(h, w)                               # 180 .. 300 000 DN/s
    t_short, t_long = 0.03, 1.0                            # brightest at t_short: 9000 DN; t_long clips a lot
    d_short = dark_frames(h, w, t_short, n=1, noise=0)[1]
    d_long = dark_frames(h, w, t_long, n=1, noise=0)[1]
    darks = [d_short, d_long]
    # noise-free: exact up to the 1-DN quantisation of the short frame in the deepest shadows
    raw_s, raw_l = expose(L, t_short, d_short), expose(L, t_long, d_long)
    assert (raw_l >= WHITE).mean() > 0.3, "the long exposure must clip a large part of the scene"
    res = HdrMerge.merge([raw_s, raw_l], [t_short, t_long], darks, white_level=WHITE, black_level=BLACK)
    assert res.clipped == 0
    assert (np.abs(res.radiance - L) / L).max() < 0.01
    long_only = (raw_l - d_long) / t_long
    assert (np.abs(long_only - L) / L).max() > 0.5         # the long exposure alone is badly wrong
    # with read noise (3 DN): right on average, and far less noisy in the shadows than the short frame alone
    raw_s, raw_l = expose(L, t_short, d_short, noise=3.0, seed=1), expose(L, t_long, d_long, noise=3.0, seed=2)
    res = HdrMerge.merge([raw_s, raw_l], [t_short, t_long], darks, white_level=WHITE, black_level=BLACK)
    rel = np.abs(res.radiance - L) / L
    assert rel.mean() < 0.01
    short_only = (raw_s.astype(float) - d_short) / t_short
    shadows = L < 3000
    assert rel[shadows].mean() < 0.2 * (np.abs(short_only - L) / L)[shadows].mean()


def test_hdr_equals_single_exposure_when_scene_fits():
    h, w = 30, 40
    L = np.random.default_rng(0).uniform(1000, 9000, (h, w))
    d = dark_frames(h, w, 0.5, n=1, noise=0)[1]
    raw = expose(L, 0.5, d, noise=2.0)
    res = HdrMerge.merge([raw], [0.5], [d], white_level=WHITE, black_level=BLACK)
    assert np.allclose(res.radiance, (raw.astype(np.float64) - d) / 0.5, rtol=1e-5, atol=1e-3)
    # and two noiseless exposures that both fit give the same radiance as either alone
    d2 = dark_frames(h, w, 0.25, n=1, noise=0)[1]
    res2 = HdrMerge.merge([expose(L, 0.25, d2), expose(L, 0.5, d)], [0.25, 0.5], [d2, d], white_level=WHITE, black_level=BLACK)
    assert np.allclose(res2.radiance, L, rtol=2e-3)


def test_pixels_clipped_in_every_exposure_use_the_shortest(caplog):
    L = np.full((4, 6), 1000.0)
    L[0, 0] = 1e6
    d = np.full((4, 6), 600.0)
    with caplog.at_level(logging.WARNING):
        res = HdrMerge.merge([expose(L, 0.1, d), expose(L, 1.0, d)], [0.1, 1.0], [d, d], white_level=WHITE, black_level=BLACK)
    assert res.clipped == 1 and "exceed the linear limit" in caplog.text
    assert res.radiance[0, 0] == pytest.approx((WHITE - 600) / 0.1)
    assert np.allclose(res.radiance[1:], 1000.0, rtol=0.01)


def test_hdr_rejects_bad_input_and_cancels():
    m = HdrMerge(WHITE)
    with pytest.raises(ValueError, match="exposure time must be positive"):
        m.add(np.zeros((4, 4), np.uint16), 0.0)
    m.add(np.zeros((4, 4), np.uint16), 1.0)
    with pytest.raises(ValueError, match="shape"):
        m.add(np.zeros((4, 6), np.uint16), 1.0)
    tok = CancelToken()
    tok.cancel()
    with pytest.raises(Cancelled):
        HdrMerge.merge([np.zeros((4, 4), np.uint16)], [1.0], white_level=WHITE, cancel=tok)


def test_processor_hdr_white_and_flat_fielded_hdr_image_recover_reflectance():
    """8.2.1-8.2.3 end to end: darks per exposure, HDR white, HDR scene, eq 7.1, superpixel, 2 lights."""
    rows, cols, cell = 2, 3, 6
    refl = patch_reflectance(rows, cols, seed=4)
    scene = mosaic_scene(refl, rows, cols, cell)                          # (24, 36) reflectance mosaic
    h, w = scene.shape
    times = (0.02, 0.5)
    darks = []
    for t in times:
        frames, _, _ = dark_frames(h, w, t, n=6, noise=1.5, spikes=0.02, seed=int(t * 100))
        darks += [ExposureRef(f, t) for f in frames]
    proc = CaptureProcessor(dark_frames=darks, white_level=WHITE, black_level=BLACK)
    scenes = {}
    for li, gain in enumerate((1.0, 0.35)):
        light = 400000.0 * gain * vignette(h, w, 0.5)                    # white would clip at 0.5 s
        whites = [ExposureRef(expose(light, t, dark_frames(h, w, t, n=1, noise=0)[1], noise=1.5, seed=li + 7), t)
                  for t in times]
        proc.set_white(f"light {li + 1}", whites)
        scenes[f"light {li + 1}"] = [
            ExposureRef(expose(light * scene, t, dark_frames(h, w, t, n=1, noise=0)[1], noise=1.5, seed=li + 9), t)
            for t in times]
    stack = proc.stack(scenes)
    assert stack.channels == ["R1", "G1", "B1", "R2", "G2", "B2"] and stack.data.shape == (12, 18, 6)
    for k in range(rows * cols):
        r, c = divmod(k, cols)
        cellv = stack.data[r * cell + 2: r * cell + 4, c * cell + 2: c * cell + 4].reshape(-1, 6)
        assert np.allclose(cellv, np.r_[refl[k], refl[k]], atol=0.01), (k, cellv, refl[k])
    assert sorted(proc.darks.exposures) == list(times)
