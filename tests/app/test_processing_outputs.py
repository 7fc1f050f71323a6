"""The hand-written ProPhoto ICC checked through LittleCMS, CSVs (the deliverable TIFFs: tests/app/test_workflow.py)."""
from __future__ import annotations

import csv
import io

import numpy as np

from dualrgb.app.processing.outputs import icc_profile, matrix_trc_icc, write_matrices_csv, write_patch_csv
from dualrgb.simulation.matrix_fit import CharacterisationMatrix


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
