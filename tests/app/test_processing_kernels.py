"""The fused numba kernels give what the numpy formulation gives; raw files open without copies and bad files
give drivers.raw's one-line errors."""
from __future__ import annotations

import numpy as np
import pytest
from synthetic_frames import BLACK, WHITE, write_dng

from dualrgb.app.processing.calibration import combine_darks
from dualrgb.app.processing.hdr import HDR_MERGE_METHODS, HdrMerge, HdrNoise
from dualrgb.app.processing.mosaic import iter_open_raw, open_raw
from dualrgb.drivers.raw import RawFileError
from dualrgb.simulation.hdr_estimators import merge_exposures


@pytest.mark.parametrize("method", list(HDR_MERGE_METHODS))
def test_hdr_kernels_match_the_numpy_reference(method):
    """Both fused kernels (result and flat superpixel) = simulation.hdr_estimators, added in any order, on raw
    values that include dark (below the master dark), over-limit and clipped pixels."""
    rng = np.random.default_rng(0)
    shape = (30, 40)
    raws = [rng.integers(0, 16000, shape).astype(np.uint16) for _ in range(3)]
    raws[1][:, :5] = 590                                                    # below the dark in one exposure
    for r in raws:
        r[:3, :] = rng.integers(560, 600, (3, shape[1]))                   # dark in every exposure
        r[3:5, :] = 15520                                                   # clipped in every exposure
    darks = [rng.uniform(590, 620, shape).astype(np.float32) for _ in range(3)]
    times = [0.1, 0.01, 1.0]                                                # not sorted: order must not matter
    res = HdrMerge.merge(raws, times, darks, white_level=WHITE, black_level=BLACK, method=method)
    x = np.stack([r.astype(np.float32) - d for r, d in zip(raws, darks, strict=True)])
    usable = np.stack([(r <= 11000) & (r < WHITE) for r in raws])
    ref, clipped = merge_exposures(x, usable, times, method, span=WHITE - BLACK, noise=HdrNoise())
    assert np.allclose(res.radiance, ref, rtol=2e-5, atol=1e-3)
    assert res.clipped == int(clipped.sum()) and res.method == method
    assert clipped[3:5].all() and not clipped[:3].any()                     # dark pixels are never clipped
    # the fused flat-field + superpixel kernel gives the same merge
    m = HdrMerge(WHITE, black_level=BLACK, method=method)
    for r, t, d in zip(raws, times, darks, strict=True):
        m.add(r, t, d)
    white = np.full(shape, 2.0, np.float32)
    out = np.empty((shape[0] // 2, shape[1] // 2, 3), np.float32)
    assert m.flat_superpixel(white, 0.01, "RGGB", out) == res.clipped
    half = res.radiance / 2
    assert np.allclose(out[..., 0], half[0::2, 0::2], rtol=2e-5, atol=1e-3)
    assert np.allclose(out[..., 1], (half[0::2, 1::2] + half[1::2, 0::2]) / 2, rtol=2e-5, atol=1e-3)


@pytest.mark.parametrize("k", [(1, 1), (2, 1), (0, 2)])
def test_dark_kernel_matches_sorted_trimmed_mean(k):
    rng = np.random.default_rng(1)
    frames = [rng.integers(500, 9000, (12, 10)).astype(np.uint16) for _ in range(7)]
    mean, n, kh, kl, *_ = combine_darks(frames, reject_high=k[0], reject_low=k[1])
    s = np.sort(np.stack(frames).astype(float), axis=0)
    ref = s[k[1]: 7 - k[0]].mean(axis=0)
    assert (n, kh, kl) == (7, k[0], k[1])
    assert np.allclose(mean, ref, atol=1e-3)


def test_open_raw_is_a_view_and_bad_files_raise_raw_file_errors(tmp_path):
    data = np.random.default_rng(2).integers(BLACK, WHITE, (32, 48)).astype(np.uint16)   # LibRaw: >= 22 px
    p = write_dng(tmp_path / "a.dng", data)
    with open_raw(p) as v:
        assert np.array_equal(v.mosaic, data) and v.white_level == WHITE and v.cfa_pattern == "RGGB"
        assert not v.mosaic.flags["OWNDATA"]
    (tmp_path / "junk.dng").write_bytes(b"not a raw file at all" * 10)
    with pytest.raises(RawFileError, match="junk.dng"):
        with open_raw(tmp_path / "junk.dng"):
            pass
    # prefetching iteration: every file closed, an error in the middle stops cleanly
    seen = [int(f.mosaic[0, 0]) for f in iter_open_raw([p, p, p])]
    assert seen == [int(data[0, 0])] * 3
    with pytest.raises(RawFileError):
        for _ in iter_open_raw([p, tmp_path / "junk.dng", p]):
            pass


@pytest.mark.parametrize("method", list(HDR_MERGE_METHODS))
def test_hdr_kernels_average_frames_of_one_exposure_time_like_the_reference(method):
    """Flats: several frames per exposure time (12 frames, 3 times), some usable in only part of the frames; the
    slots hold 5 bytes per pixel per exposure time, however many frames."""
    rng = np.random.default_rng(5)
    shape = (20, 30)
    times = [0.5, 0.01, 0.1] * 4
    raws = [np.clip(600 + rng.normal(0, 3, shape) + rng.uniform(0, 1.5e5, shape) * t, 0, WHITE).astype(np.uint16)
            for t in times]
    raws[5][:2] = 15520                                                     # one frame clipped in two rows
    darks = [np.full(shape, 600.0, np.float32)] * len(times)
    m = HdrMerge(WHITE, black_level=BLACK, method=method, work={})
    for r, t, d in zip(raws, times, darks, strict=True):
        m.add(r, t, d)
    assert m._sums.shape[0] == 4 and sorted(m._slot_frames) == [4, 4, 4]      # 3 slots (capacity 4), not 12
    res = m.result()
    x = np.stack([r.astype(np.float32) - d for r, d in zip(raws, darks, strict=True)])
    usable = np.stack([(r <= 11000) & (r < WHITE) for r in raws])
    ref, clipped = merge_exposures(x, usable, times, method, span=WHITE - BLACK, noise=HdrNoise())
    assert np.allclose(res.radiance, ref, rtol=2e-5, atol=1e-3) and res.clipped == int(clipped.sum())


def test_hdr_merge_limits_are_one_line_errors():
    m = HdrMerge(WHITE, method="thesis")
    frame = np.full((4, 4), 700, np.uint16)
    for _ in range(15):
        m.add(frame, 0.1)
    with pytest.raises(ValueError, match="at most 15 frames per exposure time"):
        m.add(frame, 0.1)
    m = HdrMerge(WHITE, method="thesis")
    for i in range(16):
        m.add(frame, 0.001 * 2 ** i)
    with pytest.raises(ValueError, match="at most 16 exposure times"):
        m.add(frame, 100.0)
