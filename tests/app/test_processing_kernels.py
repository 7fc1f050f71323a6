"""The fused numba kernels give what the numpy formulation gives; raw files open without copies and bad files
give drivers.raw's one-line errors."""
from __future__ import annotations

import numpy as np
import pytest

from app.processing.calibration import combine_darks
from app.processing.hdr import HdrMerge, exposure_weight
from app.processing.mosaic import iter_open_raw, open_raw
from drivers.raw import RawFileError
from synthetic_frames import BLACK, WHITE, write_dng


def test_hdr_kernel_matches_numpy_reference():
    rng = np.random.default_rng(0)
    raws = [rng.integers(0, 16000, (30, 40)).astype(np.uint16) for _ in range(3)]
    darks = [rng.uniform(590, 620, (30, 40)).astype(np.float32) for _ in range(3)]
    times = [0.01, 0.1, 1.0]
    res = HdrMerge.merge(raws, times, darks, white_level=WHITE, black_level=BLACK)
    num = np.zeros((30, 40))
    den = np.zeros((30, 40))
    for x, d, t in zip(raws, darks, times):
        v = x.astype(np.float32) - d
        w = exposure_weight(x, v, WHITE, BLACK, 11000)
        num += w * v / t
        den += w
    ref = np.where(den > 0, num / np.where(den > 0, den, 1), (raws[0].astype(np.float32) - darks[0]) / 0.01)
    assert np.allclose(res.radiance, ref, rtol=1e-5, atol=1e-3)
    assert res.clipped == int((den == 0).sum())


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
