"""Output TIFFs (dtype, shape, ICC), the hand-written ProPhoto ICC checked through LittleCMS, CSVs."""
from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
import tifffile

from app.processing.outputs import (apply_matrix, encode_rgb16, icc_profile, matrix_trc_icc, write_image_outputs,
                                    write_matrices_csv, write_patch_csv)
from simulation.matrix_fit import CharacterisationMatrix

D65_WHITE = np.array([95.047, 100.0, 108.883])


def test_icc_profiles_load_in_littlecms_and_prophoto_matches_colour_science():
    import colour
    from PIL import Image, ImageCms

    srgb = ImageCms.ImageCmsProfile(io.BytesIO(icc_profile("sRGB")))
    pp_bytes = matrix_trc_icc("ProPhoto RGB")
    assert pp_bytes[36:40] == b"acsp" and int.from_bytes(pp_bytes[:4], "big") == len(pp_bytes)
    pp = ImageCms.ImageCmsProfile(io.BytesIO(pp_bytes))
    assert "ProPhoto" in ImageCms.getProfileDescription(pp)
    t = ImageCms.buildTransform(pp, srgb, "RGB", "RGB", renderingIntent=ImageCms.Intent.RELATIVE_COLORIMETRIC)
    px = np.random.default_rng(1).integers(40, 200, (8, 8, 3)).astype(np.uint8)
    out = np.asarray(ImageCms.applyTransform(Image.fromarray(px), t), dtype=float)
    cs = colour.RGB_COLOURSPACES["ProPhoto RGB"]
    xyz = colour.RGB_to_XYZ(cs.cctf_decoding(px / 255.0), cs)
    ref = colour.XYZ_to_RGB(xyz, "sRGB", illuminant=cs.whitepoint, chromatic_adaptation_transform="Bradford",
                            apply_cctf_encoding=True) * 255
    inside = ((ref > 1) & (ref < 254)).all(-1)
    assert inside.sum() > 10
    assert np.abs(out - ref)[inside].max() < 1.5          # 8-bit transform: within rounding


def test_encode_white_and_grey():
    xyz = np.array([[[95.047, 100.0, 108.883], [95.047 * 0.18, 18.0, 108.883 * 0.18]]])
    srgb = encode_rgb16(xyz, "sRGB", D65_WHITE)
    pp = encode_rgb16(xyz, "ProPhoto RGB", D65_WHITE)
    assert (srgb[0, 0] == 65535).all() and (pp[0, 0] == 65535).all()          # perfect white -> max in both
    assert np.ptp(srgb[0, 1]) <= 1 and np.ptp(pp[0, 1]) <= 1                  # neutral stays neutral
    assert abs(srgb[0, 1, 0] / 65535 - 0.4614) < 0.002                        # sRGB encoding of 18 %
    with pytest.raises(ValueError, match="unknown RGB colour space"):
        encode_rgb16(xyz, "Adobe 1999", D65_WHITE)


def test_image_outputs_read_back(tmp_path):
    rng = np.random.default_rng(0)
    stack = rng.uniform(0, 1, (10, 14, 6)).astype(np.float32)
    stack[0, 0] = np.nan
    A = CharacterisationMatrix(rng.uniform(0, 40, (6, 3)), ["R1", "G1", "B1", "R2", "G2", "B2"], "least-squares")
    files = write_image_outputs(tmp_path, stack, A.channels, A, D65_WHITE, prefix="folio")
    with tifffile.TiffFile(files["channels"]) as t:
        data = t.asarray()
        assert data.dtype == np.float32 and data.shape == (10, 14, 6)
        assert json.loads(t.pages[0].description)["channels"] == A.channels
    assert np.array_equal(data, stack, equal_nan=True)
    with tifffile.TiffFile(files["xyz"]) as t:
        xyz = t.asarray()
        assert xyz.dtype == np.float32 and xyz.shape == (10, 14, 3)
    assert np.allclose(xyz[1:], (stack @ A.matrix.astype(np.float32))[1:], rtol=1e-5)
    assert np.isnan(xyz[0, 0]).all()
    for key, desc in (("srgb", "sRGB"), ("prophoto", "ProPhoto")):
        with tifffile.TiffFile(files[key]) as t:
            page = t.pages[0]
            img = page.asarray()
            assert img.dtype == np.uint16 and img.shape == (10, 14, 3)
            icc = page.tags[34675].value                         # InterColorProfile
            assert bytes(icc)[36:40] == b"acsp"
        from PIL import ImageCms
        assert desc in ImageCms.getProfileDescription(ImageCms.ImageCmsProfile(io.BytesIO(bytes(icc))))
    assert (tifffile.imread(files["srgb"])[0, 0] == 0).all()     # NaN -> black


def test_apply_matrix_bands_equal_whole():
    rng = np.random.default_rng(2)
    stack = rng.uniform(0, 1, (37, 5, 6)).astype(np.float32)
    A = rng.uniform(-1, 1, (6, 3))
    assert np.allclose(apply_matrix(stack, A, band_rows=4), stack @ A.astype(np.float32), rtol=1e-6)
    with pytest.raises(ValueError, match="expects 6"):
        apply_matrix(stack[..., :3], A)


def test_csvs(tmp_path):
    names = ["A1", "A2"]
    values = np.array([[1.0, 2, 3], [4, 5, 6]])
    ref = np.array([[10.0, 11, 12], [20, 21, 22]])
    pred = {"least-squares": ref + 0.5}
    err = {"least-squares": np.array([0.7, 1.2])}
    p = write_patch_csv(tmp_path / "patches.csv", names, values, ["R", "G", "B"], ref, pred, err, target="train")
    rows = list(csv.DictReader(open(p)))
    assert rows[1]["patch"] == "A2" and float(rows[1]["dE00_least-squares"]) == 1.2 and rows[0]["target"] == "train"
    m = CharacterisationMatrix(np.arange(9.0).reshape(3, 3), ["R", "G", "B"])
    rows = list(csv.DictReader(open(write_matrices_csv(tmp_path / "m.csv", {"ls": m}))))
    assert [r["channel"] for r in rows] == ["R", "G", "B"] and float(rows[2]["Z"]) == 8.0
