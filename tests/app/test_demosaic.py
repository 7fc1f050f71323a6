"""The Malvar-He-Cutler demosaic kernel (app.processing.demosaic) against an independent implementation:
colour-demosaicing's ``demosaicing_CFA_Bayer_Malvar2004`` (scipy convolutions and masks) over whole frames, the
border pixels included (the reference gets the same mirrored frame: numpy's ``reflect`` padding, then cropped), for
every Bayer pattern, even and odd sizes; linear in the data; NaN confined to the 5x5 support."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from dualrgb.app.processing.demosaic import HALO, demosaic

colour_demosaicing = pytest.importorskip("colour_demosaicing")


def reference(mosaic: np.ndarray, cfa: str) -> np.ndarray:
    """colour-demosaicing on the frame mirrored by HALO pixels (the kernel's border rule), cropped back."""
    padded = np.pad(np.asarray(mosaic, np.float64), HALO, mode="reflect")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)         # its scipy.ndimage.filters import
        out = colour_demosaicing.demosaicing_CFA_Bayer_Malvar2004(padded, cfa)
    return out[HALO:-HALO, HALO:-HALO]


@pytest.mark.parametrize("cfa", ["RGGB", "BGGR", "GRBG", "GBRG"])
@pytest.mark.parametrize("shape", [(3, 3), (6, 8), (7, 9), (33, 50)])
def test_every_pixel_is_colour_demosaicings(cfa, shape):
    rng = np.random.default_rng(sum(map(ord, cfa)) + shape[0])
    mosaic = rng.uniform(0.0, 2.0, shape).astype(np.float32)          # HDR-like: values above the white too
    got = demosaic(mosaic, cfa)
    ref = reference(mosaic, cfa)
    assert got.shape == shape + (3,) and got.dtype == np.float32
    np.testing.assert_allclose(got, ref, rtol=0, atol=2e-6)


def test_a_photosites_own_value_is_kept_and_the_filter_is_linear():
    rng = np.random.default_rng(3)
    a, b = rng.uniform(0, 1, (20, 24)).astype(np.float32), rng.uniform(0, 1, (20, 24)).astype(np.float32)
    out = demosaic(a, "RGGB")
    assert np.array_equal(out[0::2, 0::2, 0], a[0::2, 0::2]) and np.array_equal(out[1::2, 1::2, 2], a[1::2, 1::2])
    assert np.array_equal(out[0::2, 1::2, 1], a[0::2, 1::2])
    np.testing.assert_allclose(demosaic(2 * a - 0.5 * b), 2 * demosaic(a) - 0.5 * demosaic(b), atol=1e-5)
    flat = demosaic(np.full((10, 12), 0.37, np.float32))           # a flat field stays flat (the gains sum to 1)
    np.testing.assert_allclose(flat, 0.37, atol=1e-6)


def test_nan_reaches_only_the_pixels_whose_support_holds_it():
    mosaic = np.ones((20, 20), np.float32)
    mosaic[10, 9] = np.nan
    bad = np.isnan(demosaic(mosaic)).any(-1)
    rows, cols = np.nonzero(bad)
    assert bad[10, 9] and rows.min() >= 8 and rows.max() <= 12 and cols.min() >= 7 and cols.max() <= 11
    assert not bad[:7].any() and not bad[13:].any()


def test_too_small_a_frame_is_one_line():
    with pytest.raises(ValueError, match=r"mosaic of shape \(2, 5\)"):
        demosaic(np.zeros((2, 5), np.float32))
