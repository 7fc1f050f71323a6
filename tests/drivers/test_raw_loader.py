"""dualrgb.drivers.raw: DNG round-trip through drivers.virtual.dng (tifffile) -> rawpy is bit-exact; damaged files give
one-line RawFileErrors."""
from __future__ import annotations

import numpy as np
import pytest
import rawpy
from rawtestfiles import D610_BLACK, D610_WHITE, mosaic_14bit, write_dng

from dualrgb.drivers.raw import RawFileError, linear_demosaic, load_raw, superpixel


@pytest.fixture
def dng(tmp_path):
    data = mosaic_14bit(40, 60)
    return write_dng(tmp_path / "DSC_0001.dng", data), data


def test_round_trip_is_bit_exact(dng):
    path, data = dng
    frame = load_raw(path)
    assert frame.mosaic.dtype == np.uint16
    assert frame.mosaic.shape == (40, 60)
    assert np.array_equal(frame.mosaic, data)
    assert frame.cfa_pattern == "RGGB"
    assert frame.white_level == D610_WHITE
    assert frame.black_levels == (D610_BLACK,) * 4
    assert frame.camera == "Nikon D610"
    assert frame.format == "DNG"
    assert frame.exposure_s == pytest.approx(1 / 125, rel=1e-6)
    assert frame.mosaic.max() == D610_WHITE


@pytest.mark.parametrize("cfa", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_cfa_patterns_and_colour_index(tmp_path, cfa):
    data = mosaic_14bit(24, 30, seed=3)
    path = write_dng(tmp_path / f"{cfa}.dng", data, cfa=cfa)
    frame = load_raw(path)
    assert frame.cfa_pattern == cfa
    with rawpy.imread(str(path)) as raw:
        assert np.array_equal(frame.colors, raw.raw_colors_visible)
    names = [n for n, _, _ in frame.channels()]
    assert names == ["R", "G1", "G2", "B"]
    # each named plane holds the pixels of that colour
    for name, (r, c), idx in frame.channels():
        assert cfa[2 * r + c] == name[0]
        assert np.array_equal(frame.plane(name), data[r::2, c::2])
        assert frame.color_desc[idx] == name[0]


def test_superpixel_is_exact_and_matches_libraw_half_size(tmp_path):
    data = mosaic_14bit(24, 32, seed=5)
    frame = load_raw(write_dng(tmp_path / "a.dng", data))
    sp = superpixel(frame)
    assert sp.shape == (12, 16, 3) and sp.dtype == np.float32
    d = data.astype(np.float64) - D610_BLACK
    np.testing.assert_allclose(sp[..., 0], d[0::2, 0::2])
    np.testing.assert_allclose(sp[..., 1], 0.5 * (d[0::2, 1::2] + d[1::2, 0::2]))
    np.testing.assert_allclose(sp[..., 2], d[1::2, 1::2])
    half = linear_demosaic(frame, half_size=True)
    assert half.shape == (12, 16, 3) and half.dtype == np.uint16
    scale = 65535.0 / (D610_WHITE - D610_BLACK)
    # LibRaw rounds each green before averaging
    np.testing.assert_allclose(half.astype(np.float64), sp * scale, atol=2.0)


def test_linear_demosaic_is_linear_and_keeps_white_point(tmp_path):
    # a flat field at mid level and a saturated one: linear output must be proportional, white at 65535
    flat = np.full((24, 24), D610_BLACK + 7000, dtype=np.uint16)
    sat = np.full((24, 24), D610_WHITE, dtype=np.uint16)
    rgb_flat = linear_demosaic(load_raw(write_dng(tmp_path / "flat.dng", flat)))
    rgb_sat = linear_demosaic(load_raw(write_dng(tmp_path / "sat.dng", sat)))
    assert rgb_flat.shape == (24, 24, 3) and rgb_flat.dtype == np.uint16
    expected = 7000 * 65535.0 / (D610_WHITE - D610_BLACK)
    np.testing.assert_allclose(rgb_flat.astype(float), expected, atol=1.5)
    assert rgb_sat.min() == 65535


def test_unknown_demosaic_algorithm(dng):
    with pytest.raises(ValueError, match="demosaic algorithm 'NOPE' unknown"):
        linear_demosaic(load_raw(dng[0]), algorithm="NOPE")


def _one_line(exc: BaseException) -> str:
    msg = str(exc)
    assert "\n" not in msg
    return msg


def test_truncated_file(dng, tmp_path):
    path, _ = dng
    cut = tmp_path / "cut.dng"
    cut.write_bytes(path.read_bytes()[:3000])
    with pytest.raises(RawFileError) as err:
        load_raw(cut)
    assert _one_line(err.value).startswith(f"{cut}: truncated")


def test_truncated_header(dng, tmp_path):
    path, _ = dng
    cut = tmp_path / "head.dng"
    cut.write_bytes(path.read_bytes()[:200])
    with pytest.raises(RawFileError) as err:
        load_raw(cut)
    msg = _one_line(err.value)
    assert msg.startswith(str(cut)) and ("truncated" in msg or "not a raw file" in msg)


def test_corrupt_header(dng, tmp_path):
    path, _ = dng
    bad = bytearray(path.read_bytes())
    bad[8:60] = b"\xff" * 52
    p = tmp_path / "corrupt.dng"
    p.write_bytes(bytes(bad))
    with pytest.raises(RawFileError) as err:
        load_raw(p)
    assert _one_line(err.value).startswith(f"{p}: ")


def test_text_file_and_missing_and_empty(tmp_path):
    text = tmp_path / "notes.nef"
    text.write_text("hello, this is not a raw file\n")
    with pytest.raises(RawFileError, match="not a raw file") as err:
        load_raw(text)
    assert _one_line(err.value).startswith(str(text))
    with pytest.raises(RawFileError, match="no such file"):
        load_raw(tmp_path / "missing.nef")
    empty = tmp_path / "empty.dng"
    empty.write_bytes(b"")
    with pytest.raises(RawFileError, match="file is empty"):
        load_raw(empty)
    with pytest.raises(RawFileError, match="is a folder"):
        load_raw(tmp_path)


def test_non_bayer_cfa(tmp_path):
    path = write_dng(tmp_path / "rgbb.dng", mosaic_14bit(24, 24), cfa="RGBB")
    with pytest.raises(RawFileError, match="not an RGB Bayer sensor"):
        load_raw(path)


def test_raw_file_error_is_a_value_error(tmp_path):
    # the CLI turns ValueError into 'dualrgb: error: ...' and exit 1
    assert issubclass(RawFileError, ValueError)


def test_a_folder_name_that_is_not_utf8_is_read(tmp_path):
    """Issue 28: a session path with a byte that is not UTF-8 (a folder named in another encoding) was reported
    as 'damaged raw data (UnicodeEncodeError)'."""
    import os

    folder = tmp_path / os.fsdecode(b"sitzung-\xfc")                 # Latin-1 'u-umlaut'
    folder.mkdir()
    mosaic = mosaic_14bit(40, 60)
    path = write_dng(folder / "f.DNG", mosaic)
    frame = load_raw(path)
    assert np.array_equal(frame.mosaic, mosaic)
