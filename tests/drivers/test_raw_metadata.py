"""drivers.raw_metadata on real public raw files (tests/data/raw: a Blackmagic DNG, a Coolscan scanner NEF) and on
the virtual camera's DNGs: levels, CFA, camera, serial and the shot from the file, through LibRaw and exiftool."""
from __future__ import annotations

import shutil
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest

from dualrgb.drivers.raw import RawFileError, load_raw
from dualrgb.drivers.raw_metadata import exif_time, exiftool_tags, read_raw_metadata
from dualrgb.drivers.virtual.dng import DngInfo, save_dng

RAW = Path(__file__).resolve().parents[1] / "data" / "raw"
BLACKMAGIC, SCANNER = RAW / "Blackmagic.dng", RAW / "Nikon_uncompressed.nef"
needs_exiftool = pytest.mark.skipif(shutil.which("exiftool") is None, reason="exiftool is not installed")


def test_a_real_blackmagic_dng_gives_its_levels_camera_and_serial():
    """The levels, CFA and size LibRaw reads (the same as load_raw's), the model from UniqueCameraModel and the
    serial from CameraSerialNumber; this file records no exposure, ISO, aperture or time: they stay empty."""
    m = read_raw_metadata(BLACKMAGIC)
    frame = load_raw(BLACKMAGIC)
    assert (m.width, m.height, m.cfa) == (4128, 2176, "RGGB") == (frame.width, frame.height, frame.cfa_pattern)
    assert m.black_levels == frame.black_levels == (512, 512, 512, 512) and m.white_level == frame.white_level == 65535
    assert m.camera == "Blackmagic Pocket Cinema Camera 4K" and m.format == "DNG"
    assert m.serial == "f6845270-68de-40e7-9688-2492e35e94c0"
    assert (m.exposure_s, m.iso, m.aperture, m.captured_at) == (None, None, None, None)
    assert 0.0 < m.extra["signal"] < 1.0


def test_a_film_scanner_nef_is_refused_in_one_line():
    with pytest.raises(RawFileError) as err:
        read_raw_metadata(SCANNER)
    assert str(err.value) == f"{SCANNER}: not a Bayer mosaic (the file holds demosaiced/linear RGB data)"


@needs_exiftool
def test_exiftool_reads_what_libraw_does_not_say():
    """exiftool (one run for every file) gives the scanner's make and model; a file it cannot read is absent."""
    tags = exiftool_tags([BLACKMAGIC, SCANNER])
    assert tags[SCANNER]["Model"] == "Nikon COOLSCAN IV ED" and set(tags) == {BLACKMAGIC, SCANNER}
    assert exiftool_tags([]) == {} and exiftool_tags([BLACKMAGIC], executable="/nonexistent/exiftool") == {}


def _virtual(tmp_path: Path, **info) -> Path:
    mosaic = np.full((160, 240), 600, np.uint16)
    mosaic[::2, ::2] += 3000
    return save_dng(tmp_path / "V.dng", mosaic, DngInfo(**info))


@pytest.mark.parametrize("tool", [False, pytest.param(True, marks=needs_exiftool)])
def test_a_virtual_dng_gives_every_field(tmp_path, tool):
    """Exposure, ISO, aperture, capture time, make, model and serial: from LibRaw and the TIFF tags alone (no
    exiftool, as on Windows) and with exiftool (its exact rationals)."""
    when = datetime(2026, 3, 4, 5, 6, 7).timestamp()
    path = _virtual(tmp_path, exposure_s=1 / 60, iso=100, aperture=8.0, serial="SN-42", captured_at=when,
                    model="Nikon D610")
    m = read_raw_metadata(path, exiftool_tags([path]).get(path) if tool else None)
    assert m.exposure_s == pytest.approx(1 / 60, rel=1e-6) and (m.iso, m.aperture) == (100, 8.0)
    assert (m.make, m.model, m.serial, m.camera) == ("Nikon", "Nikon D610", "SN-42", "Nikon D610")
    assert m.captured_at is not None and m.captured_at.minute == 6
    assert m.extra["signal"] == pytest.approx(3000 / 4 / (15520 - 600), rel=1e-3)


def test_no_serial_stays_empty(tmp_path):
    assert read_raw_metadata(_virtual(tmp_path, exposure_s=0.5)).serial == ""


def test_exif_times_with_sub_seconds():
    assert exif_time("2026:03:04 05:06:07", "25") == datetime(2026, 3, 4, 5, 6, 7, 250000)
    assert exif_time("2026:03:04 05:06:07") == datetime(2026, 3, 4, 5, 6, 7)
    assert exif_time("0000:00:00 00:00:00") is None and exif_time(None) is None


def test_a_damaged_file_is_one_line(tmp_path):
    path = _virtual(tmp_path, exposure_s=0.5)
    path.write_bytes(path.read_bytes()[:5000])
    with pytest.raises(RawFileError, match="truncated or damaged"):
        read_raw_metadata(path)
