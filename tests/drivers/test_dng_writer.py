"""dualrgb.drivers.virtual.dng: the one DNG writer carries what LibRaw and the pipeline read, checked through rawpy and
tifffile (independent readers), and rejects what it cannot write."""
from __future__ import annotations

import io
import shutil
import subprocess
from datetime import datetime

import numpy as np
import pytest
import rawpy
import tifffile
from rawtestfiles import D610_BLACK, D610_WHITE, mosaic_14bit

from dualrgb.drivers.raw import load_raw
from dualrgb.drivers.virtual.dng import DngInfo, dng_bytes, save_dng, write_dng

NEUTRAL = np.array([0.5, 1.0, 0.8])
MATRIX = np.array([[0.9, -0.1, 0.05], [-0.3, 1.1, 0.2], [0.01, 0.1, 0.6]])


def _info(**kw) -> DngInfo:
    base = dict(black_level=D610_BLACK, white_level=D610_WHITE, exposure_s=1 / 60, iso=200, aperture=5.6,
                model="dualrgb virtual D610", color_matrix=MATRIX, as_shot_neutral=NEUTRAL)
    return DngInfo(**{**base, **kw})


def test_libraw_reads_levels_pattern_shot_and_neutral(tmp_path):
    data = mosaic_14bit(24, 36, seed=2)
    path = save_dng(tmp_path / "a.dng", data, _info(cfa="GBRG"))
    frame = load_raw(path)
    assert np.array_equal(frame.mosaic, data)
    assert (frame.cfa_pattern, frame.white_level, frame.black_levels) == ("GBRG", D610_WHITE, (D610_BLACK,) * 4)
    assert frame.camera == "dualrgb virtual D610" and frame.make == "dualrgb"
    assert frame.exposure_s == pytest.approx(1 / 60, rel=1e-6)
    with rawpy.imread(str(path)) as raw:
        assert raw.other.aperture == pytest.approx(5.6)
        wb = np.array(raw.camera_whitebalance[:3])             # LibRaw: multipliers = 1 / AsShotNeutral
        np.testing.assert_allclose(wb / wb[1], NEUTRAL[1] / NEUTRAL, rtol=1e-4)


def test_dng_tags_as_tifffile_reads_them():
    data = mosaic_14bit(8, 8)
    with tifffile.TiffFile(io.BytesIO(dng_bytes(data, _info()))) as tif:
        page = tif.pages[0]
        tags = {t.code: t.value for t in page.tags}
        assert np.array_equal(page.asarray(), data)
    assert tags[262] == 32803 and tags[258] == 16 and tags[259] == 1        # CFA, 16-bit words, uncompressed
    assert tags[50706] == b"\x01\x04\x00\x00"                                # DNGVersion 1.4
    assert 33434 not in tags and 34855 not in tags and 36867 not in tags      # shooting tags: in the EXIF IFD
    exif = tags[34665]
    assert exif["ISOSpeedRatings"] == 200 and exif["FNumber"] == (28, 5) and exif["ExposureTime"] == (1, 60)
    assert exif["ExifVersion"] == "0230"
    cm = np.array(tags[50721], float).reshape(9, 2)
    np.testing.assert_allclose(cm[:, 0] / cm[:, 1], MATRIX.ravel(), atol=1e-4)
    neutral = np.array(tags[50728], float).reshape(3, 2)
    np.testing.assert_allclose(neutral[:, 0] / neutral[:, 1], NEUTRAL, atol=1e-4)
    assert tags[272] == tags[50708] == "dualrgb virtual D610"


@pytest.mark.parametrize("bad, match", [("RGGX", "CFA pattern 'RGGX'"), ("RGB", "CFA pattern 'RGB'")])
def test_bad_cfa_is_one_line(bad, match):
    with pytest.raises(ValueError, match=match):
        dng_bytes(mosaic_14bit(4, 4), DngInfo(cfa=bad))


def test_libraw_reads_iso_and_capture_time_from_the_exif_ifd(tmp_path):
    """In IFD0 (before issue 31) LibRaw read ISO 0 and a 1970 timestamp: it reads both only from the EXIF IFD."""
    when = datetime(2026, 3, 14, 15, 9, 26)
    path = save_dng(tmp_path / "a.dng", mosaic_14bit(24, 36), _info(captured_at=when.timestamp()))
    with rawpy.imread(str(path)) as raw:
        assert raw.other.iso_speed == 200
        assert raw.other.timestamp == when                   # rawpy gives LibRaw's capture time as local time
        assert raw.other.shutter_speed == pytest.approx(1 / 60) and raw.other.aperture == pytest.approx(5.6)
    assert load_raw(path).iso == 200


@pytest.mark.skipif(shutil.which("exiftool") is None, reason="exiftool not installed (apt: libimage-exiftool-perl)")
def test_exiftool_validates_the_dng_clean(tmp_path):
    path = save_dng(tmp_path / "a.dng", mosaic_14bit(16, 24), _info())
    out = subprocess.run(["exiftool", "-validate", "-warning", "-a", "-s", str(path)], capture_output=True,
                         text=True, check=True).stdout
    assert out.split() == ["Validate", ":", "OK"], out
    groups = subprocess.run(["exiftool", "-a", "-G1", "-s", "-ISO", "-ExposureTime", "-FNumber", "-DateTimeOriginal",
                             str(path)], capture_output=True, text=True, check=True).stdout.splitlines()
    assert len(groups) == 4 and all(line.startswith("[ExifIFD]") for line in groups), groups


def test_dng_into_an_open_file_after_other_bytes():
    """Offsets of the appended EXIF IFD count from the TIFF's own start, wherever the caller's file stands."""
    buf = io.BytesIO()
    buf.write(b"xyz")
    write_dng(buf, mosaic_14bit(8, 8), _info())
    with tifffile.TiffFile(io.BytesIO(buf.getvalue()[3:])) as tif:
        assert tif.pages[0].tags["ExifTag"].value["ISOSpeedRatings"] == 200


def test_virtual_camera_capture_is_a_readable_dng(tmp_path):
    from dualrgb.drivers.virtual.camera import StaticLight, VirtualCamera
    from dualrgb.drivers.virtual.scene import Scene

    levels = np.zeros(10)
    levels[[0, 5, 7]] = 1.0
    cam = VirtualCamera(lambda: StaticLight(levels), Scene.open_gate(64, 48))
    cam.open()
    cap = cam.capture(1 / 60)
    path = tmp_path / cap.filename
    path.write_bytes(cap.data)
    frame = load_raw(path)
    assert frame.mosaic.shape == (48, 64) and frame.cfa_pattern == "RGGB"
    assert frame.exposure_s == pytest.approx(1 / 60)
