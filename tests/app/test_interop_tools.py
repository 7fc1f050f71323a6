"""Every delivered file read right by the tools an archive uses (issue 31), each where it is installed (the Makefile's
CI installs them; here a test skips with the Debian package to install):

* the ICC profiles are version 2.4 (the header's bytes), and ArgyllCMS' ``iccdump`` reads them (it refuses v4);
* LittleCMS (``tificc``) converts the XYZ master through its embedded profile to the same colours as the sRGB
  deliverable (mean dE00 < 0.05): the XYZ-identity profile says what the file holds;
* ImageMagick and GDAL read the XYZ and camera-RGB TIFFs as three colour channels (no alpha, not grey); Pillow
  opens every TIFF;
* exiftool reads the exact Unicode description from the XMP (dc:description); the ImageDescription stays 7-bit
  ASCII, as baseline TIFF wants (exiftool's ``-use MWG`` prefers a non-empty EXIF ImageDescription to the XMP, by
  the MWG's reading rule: docs/notes/issue-31.md).
"""
from __future__ import annotations

import json
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest
import tifffile
from workflow_profiles import make_profile

from dualrgb.app.processing.outputs import icc_profile, xyz_icc
from dualrgb.app.processing.pipeline import ChannelStack
from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver

TITLE = "Stillleben mit Äpfeln – 静物"


def tool(name: str, package: str):
    if shutil.which(name) is None:
        pytest.skip(f"{name} is not installed (Debian: apt-get install {package})")
    return name


@pytest.fixture(scope="module")
def delivered(tmp_path_factory):
    root = tmp_path_factory.mktemp("interop")
    prof = make_profile(root / "cal", shape=(48, 64))
    rng = np.random.default_rng(2)
    cells = rng.uniform(0.03, 0.95, (6, 8, 3))
    data = np.repeat(np.repeat(cells, 8, 0), 8, 1).astype(np.float32)          # 48 x 64, flat patches
    source = replace(ChannelStack(data, ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0}), resolution="full")
    return deliver(source, prof, Original("ACC-ö", title=TITLE), root / "out", camera=prof.camera,
                   dose=LightDoseRecord(1.0, 0.1))


@pytest.mark.parametrize("which", ["sRGB", "ProPhoto RGB", "XYZ"])
def test_icc_profiles_are_v2_and_argyll_reads_them(tmp_path, which):
    data = xyz_icc([95.047, 100.0, 108.883]) if which == "XYZ" else icc_profile(which)
    assert data[8:10] == b"\x02\x40" and data[36:40] == b"acsp"          # version 2.4, an ICC profile
    path = tmp_path / "p.icc"
    path.write_bytes(data)
    r = subprocess.run([tool("iccdump", "argyll"), "-v1", str(path)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "Version      = 2.4.0" in r.stdout, r.stdout + r.stderr


def test_delivered_tiffs_embed_the_v2_profiles(delivered):
    for key in ("srgb", "prophoto", "xyz"):
        with tifffile.TiffFile(delivered.files[key]) as t:
            icc = bytes(t.pages[0].tags[34675].value)
        assert icc[8:10] == b"\x02\x40", key


def test_littlecms_reads_the_xyz_master_as_the_colours_it_holds(delivered, tmp_path):
    colour = pytest.importorskip("colour")
    out = tmp_path / "xyz_as_srgb.tif"
    r = subprocess.run([tool("tificc", "liblcms2-utils"), "-t1", "-c0", "-w16", "-o*sRGB", str(delivered.files["xyz"]),
                        str(out)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr

    def lab(path):
        return colour.XYZ_to_Lab(colour.sRGB_to_XYZ(tifffile.imread(path).astype(float) / 65535))
    de = colour.delta_E(lab(out), lab(delivered.files["srgb"]), method="CIE 2000")
    assert de.mean() < 0.05 and np.percentile(de, 99) < 0.2


@pytest.mark.parametrize("key", ["xyz", "channels_1", "srgb"])
def test_imagemagick_and_gdal_read_three_colour_channels(delivered, key):
    path = str(delivered.files[key])
    im = subprocess.run([tool("identify", "imagemagick"), "-format", "%[channels] %[colorspace] %z", path],
                        capture_output=True, text=True, timeout=60)
    assert im.returncode == 0 and im.stdout.split() == ["srgb", "sRGB", "16"], im.stdout + im.stderr
    gdal = subprocess.run([tool("gdalinfo", "gdal-bin"), "-json", path], capture_output=True, text=True, timeout=60)
    bands = json.loads(gdal.stdout)["bands"]
    assert [(b["colorInterpretation"], b["type"]) for b in bands] == [("Red", "UInt16"), ("Green", "UInt16"),
                                                                      ("Blue", "UInt16")]


def test_pillow_opens_every_tiff(delivered):
    from PIL import Image

    for path in delivered.files.values():
        with Image.open(path) as im:
            im.load()
            assert im.size == (64, 48) and im.getbands() == ("R", "G", "B"), path.name


def test_exiftool_reads_the_exact_description_from_the_xmp(delivered):
    path = str(delivered.files["xyz"])
    r = subprocess.run([tool("exiftool", "libimage-exiftool-perl"), "-b", "-XMP-dc:Description", path],
                       capture_output=True, timeout=60)
    assert r.stdout.decode("utf-8").startswith(f"ACC-ö - {TITLE}; CIE XYZ (2 deg) as R, G, B")
    with tifffile.TiffFile(path) as t:
        assert t.pages[0].tags["ImageDescription"].value.startswith("ACC-o - Stillleben mit Apfeln - ??; CIE XYZ")
