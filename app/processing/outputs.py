"""Output files: XYZ and 6-channel float32 TIFFs, 16-bit sRGB / ProPhoto RGB TIFFs with embedded ICC profiles,
and CSVs of patch values and matrices.

ICC profiles
    * sRGB: Pillow's ImageCms (LittleCMS' built-in sRGB, ``ImageCms.createProfile("sRGB")``).
    * ProPhoto RGB (ROMM RGB): ImageCms cannot create it (createProfile knows only sRGB, LAB and XYZ), so
      :func:`matrix_trc_icc` writes a minimal ICC v2.4 display profile itself: header, desc, cprt, wtpt,
      r/g/bXYZ colorants (the colour space's RGB->XYZ matrix adapted to the ICC D50 PCS with Bradford) and
      r/g/bTRC as a 4096-entry sampled curve of the space's decoding function (ROMM's linear toe + 1.8 gamma).
      The tests check it through LittleCMS against colour-science's own conversion.

XYZ scale: the characterisation predicts XYZ on the ground-truth scale (eq 4.2: a perfect white has Y = 100
under D65). RGB encodings divide by the white's Y and adapt (Bradford) from that white to the RGB space's
white, so a perfect white becomes RGB (1, 1, 1); values outside [0, 1] are clipped (16-bit, 0..65535).
Conversion and quantisation run in bands of rows, so a 24 MP set stays small in memory.
"""
from __future__ import annotations

import csv
import json
import logging
import struct
from datetime import datetime, timezone
from pathlib import Path
from typing import Mapping, Optional, Sequence

import numpy as np

from app.processing.mosaic import row_bands
from simulation.atomic_io import atomic_output
from simulation.characterisation import CharacterisationMatrix
from simulation.progress import CancelToken, ProgressCallback, check, report

log = logging.getLogger(__name__)

ICC_D50 = np.array([0.9642, 1.0, 0.8249])
SPACES = {"sRGB": "sRGB", "ProPhoto RGB": "ProPhoto RGB"}


# ---------------------------------------------------------------- colour conversion
def _colourspace(name: str):
    import colour

    try:
        return colour.RGB_COLOURSPACES[name]
    except KeyError:
        raise ValueError(f"unknown RGB colour space {name!r}; expected one of {', '.join(SPACES)}") from None


def _bradford(src_xyz: np.ndarray, dst_xyz: np.ndarray) -> np.ndarray:
    from colour.adaptation import matrix_chromatic_adaptation_VonKries

    return matrix_chromatic_adaptation_VonKries(np.asarray(src_xyz, float), np.asarray(dst_xyz, float), "Bradford")


def xyz_to_rgb_matrix(space: str, white_xyz: Sequence[float]) -> np.ndarray:
    """3x3 M with linear RGB = M @ (XYZ / white_Y), adapting ``white_xyz`` to the space's white."""
    import colour

    cs = _colourspace(space)
    white = np.asarray(white_xyz, dtype=float) / float(white_xyz[1])
    dst = colour.xy_to_XYZ(cs.whitepoint)
    M = cs.matrix_XYZ_to_RGB @ _bradford(white, dst)
    # the published matrices (e.g. IEC 61966-2-1's 4-digit sRGB one) map the white to 1 +- 1e-4: normalise so
    # a perfect white is exactly RGB (1, 1, 1)
    return M / (M @ white)[:, None]


def encode_rgb16(xyz: np.ndarray, space: str, white_xyz: Sequence[float], *, band_rows: int = 512,
                 cancel: Optional[CancelToken] = None) -> np.ndarray:
    """(H, W, 3) XYZ (scale of ``white_xyz``) -> (H, W, 3) uint16 display-encoded RGB of ``space``."""
    cs = _colourspace(space)
    M = (xyz_to_rgb_matrix(space, white_xyz) / float(white_xyz[1])).astype(np.float32)
    out = np.empty(xyz.shape[:2] + (3,), dtype=np.uint16)
    for rows in row_bands(xyz.shape[0], band_rows):
        check(cancel)
        lin = np.nan_to_num(xyz[rows].astype(np.float32) @ M.T, nan=0.0)
        np.clip(lin, 0.0, 1.0, out=lin)
        enc = np.asarray(cs.cctf_encoding(lin), dtype=np.float32)
        out[rows] = np.round(np.clip(enc, 0, 1) * 65535.0).astype(np.uint16)
    return out


def apply_matrix(stack: np.ndarray, matrix: CharacterisationMatrix | np.ndarray, *, band_rows: int = 512,
                 progress: Optional[ProgressCallback] = None, cancel: Optional[CancelToken] = None) -> np.ndarray:
    """(H, W, C) camera channels -> (H, W, 3) float32 XYZ, band by band (NaN stays NaN)."""
    A = (matrix.matrix if isinstance(matrix, CharacterisationMatrix) else np.asarray(matrix)).astype(np.float32)
    if stack.shape[-1] != A.shape[0]:
        raise ValueError(f"image has {stack.shape[-1]} channels, the matrix expects {A.shape[0]}")
    out = np.empty(stack.shape[:2] + (3,), dtype=np.float32)
    H = stack.shape[0]
    for rows in row_bands(H, band_rows):
        check(cancel)
        np.matmul(stack[rows], A, out=out[rows])
        report(progress, rows.stop / H, "applying the characterisation matrix")
    return out


# ---------------------------------------------------------------- ICC profiles
def srgb_icc() -> bytes:
    """LittleCMS' built-in sRGB profile via Pillow ImageCms."""
    from PIL import ImageCms

    return ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()


def _s15(v: float) -> bytes:
    return struct.pack(">i", int(round(v * 65536.0)))


def _xyz_tag(xyz: Sequence[float]) -> bytes:
    return b"XYZ " + b"\0" * 4 + b"".join(_s15(v) for v in xyz)


def _desc_tag(text: str) -> bytes:
    a = text.encode("ascii", "replace") + b"\0"
    return b"desc" + b"\0" * 4 + struct.pack(">I", len(a)) + a + struct.pack(">II", 0, 0) + struct.pack(">HB", 0, 0) + b"\0" * 67


def _text_tag(text: str) -> bytes:
    return b"text" + b"\0" * 4 + text.encode("ascii", "replace") + b"\0"


def _curv_tag(samples: np.ndarray) -> bytes:
    v = np.round(np.clip(samples, 0, 1) * 65535).astype(">u2")
    return b"curv" + b"\0" * 4 + struct.pack(">I", len(v)) + v.tobytes()


def matrix_trc_icc(space: str, description: Optional[str] = None, n_curve: int = 4096) -> bytes:
    """A minimal ICC v2.4 matrix/TRC RGB display profile for a colour-science RGB colour space."""
    import colour

    cs = _colourspace(space)
    white = colour.xy_to_XYZ(cs.whitepoint)
    M = _bradford(white, ICC_D50) @ cs.matrix_RGB_to_XYZ       # RGB -> XYZ (D50 PCS)
    x = np.linspace(0.0, 1.0, n_curve)
    trc = _curv_tag(np.asarray(cs.cctf_decoding(x), dtype=float))
    tags = [
        (b"desc", _desc_tag(description or f"{space} (dualrgb matrix/TRC)")),
        (b"cprt", _text_tag("No copyright, use freely")),
        (b"wtpt", _xyz_tag(ICC_D50)),
        (b"rXYZ", _xyz_tag(M[:, 0])),
        (b"gXYZ", _xyz_tag(M[:, 1])),
        (b"bXYZ", _xyz_tag(M[:, 2])),
        (b"rTRC", trc),
        (b"gTRC", trc),
        (b"bTRC", trc),
    ]
    offset = 128 + 4 + 12 * len(tags)
    table = struct.pack(">I", len(tags))
    data = b""
    placed: dict[bytes, int] = {}
    for sig, body in tags:
        if body in placed:                       # the three TRCs share one curve
            table += sig + struct.pack(">II", placed[body], len(body))
            continue
        pad = (-len(data)) % 4
        data += b"\0" * pad
        pos = offset + len(data)
        placed[body] = pos
        table += sig + struct.pack(">II", pos, len(body))
        data += body
    data += b"\0" * ((-len(data)) % 4)
    size = 128 + len(table) + len(data)
    now = datetime.now(timezone.utc)
    header = (struct.pack(">I", size) + b"none" + bytes([2, 0x40, 0, 0]) + b"mntr" + b"RGB " + b"XYZ "
              + struct.pack(">6H", now.year, now.month, now.day, now.hour, now.minute, now.second)
              + b"acsp" + b"APPL" + struct.pack(">I", 0) + b"none" + b"\0" * 4 + b"\0" * 8
              + struct.pack(">I", 1)                     # relative colorimetric
              + b"".join(_s15(v) for v in ICC_D50) + b"dRGB" + b"\0" * 16 + b"\0" * 28)
    assert len(header) == 128
    return header + table + data


def icc_profile(space: str) -> bytes:
    """The ICC profile embedded for ``space``: ImageCms for sRGB, :func:`matrix_trc_icc` otherwise."""
    return srgb_icc() if space == "sRGB" else matrix_trc_icc(space)


# ---------------------------------------------------------------- files
def write_rgb_tiff(path: Path, rgb16: np.ndarray, space: str, *, description: str = "") -> Path:
    import tifffile

    path = Path(path)
    with atomic_output(path, "wb") as fh:
        tifffile.imwrite(fh, rgb16, photometric="rgb", iccprofile=icc_profile(space),
                         description=description or f"dualrgb {space}", metadata=None)
    return path


def write_float_tiff(path: Path, data: np.ndarray, channels: Sequence[str], *, description: Optional[dict] = None
                     ) -> Path:
    """Float32 (H, W, C) TIFF, channels interleaved; ImageDescription holds a JSON with the channel names."""
    import tifffile

    path = Path(path)
    desc = json.dumps({"channels": list(channels), **(description or {})})
    with atomic_output(path, "wb") as fh:
        tifffile.imwrite(fh, np.ascontiguousarray(data, dtype=np.float32), photometric="minisblack",
                         planarconfig="contig", description=desc, metadata=None)
    return path


def write_patch_csv(path: Path, names: Sequence[str], values: np.ndarray, channels: Sequence[str],
                    xyz_ref: np.ndarray, predictions: Mapping[str, np.ndarray], errors: Mapping[str, np.ndarray],
                    *, target: str = "") -> Path:
    """One row per patch: camera values, reference XYZ, predicted XYZ and dE00 per method."""
    path = Path(path)
    with atomic_output(path, "w", newline="") as fh:
        w = csv.writer(fh)
        head = ["target", "patch"] + list(channels) + ["X_ref", "Y_ref", "Z_ref"]
        for m in predictions:
            head += [f"X_{m}", f"Y_{m}", f"Z_{m}", f"dE00_{m}"]
        w.writerow(head)
        for i, name in enumerate(names):
            row = [target, name] + [f"{v:.6g}" for v in values[i]] + [f"{v:.6g}" for v in xyz_ref[i]]
            for m in predictions:
                row += [f"{v:.6g}" for v in predictions[m][i]] + [f"{errors[m][i]:.4f}"]
            w.writerow(row)
    return path


def write_matrices_csv(path: Path, matrices: Mapping[str, CharacterisationMatrix]) -> Path:
    """Rows ``method, channel, X, Y, Z``: XYZ = sum over channels of value * row."""
    path = Path(path)
    with atomic_output(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["method", "channel", "X", "Y", "Z"])
        for name, m in matrices.items():
            chans = m.channels or [f"ch{i + 1}" for i in range(m.matrix.shape[0])]
            for ch, row in zip(chans, m.matrix):
                w.writerow([name, ch] + [f"{v:.10g}" for v in row])
    return path


def write_image_outputs(out_dir: Path, stack: np.ndarray, channels: Sequence[str],
                        matrix: CharacterisationMatrix, white_xyz: Sequence[float], *, prefix: str = "image",
                        progress: Optional[ProgressCallback] = None, cancel: Optional[CancelToken] = None
                        ) -> dict[str, Path]:
    """XYZ float32 TIFF, sRGB and ProPhoto 16-bit TIFFs with ICC, and the N-channel float32 TIFF."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    report(progress, 0.0, "writing the channel stack")
    files["channels"] = write_float_tiff(out_dir / f"{prefix}_{len(channels)}ch_float32.tif", stack, channels,
                                         description={"units": "flat-fielded relative signal"})
    check(cancel)
    xyz = apply_matrix(stack, matrix, cancel=cancel)
    report(progress, 0.35, "writing XYZ")
    files["xyz"] = write_float_tiff(out_dir / f"{prefix}_XYZ_float32.tif", xyz, ["X", "Y", "Z"],
                                    description={"white_xyz": [float(v) for v in white_xyz],
                                                 "matrix": matrix.method})
    for i, space in enumerate(("sRGB", "ProPhoto RGB")):
        check(cancel)
        rgb = encode_rgb16(xyz, space, white_xyz, cancel=cancel)
        key = "srgb" if space == "sRGB" else "prophoto"
        files[key] = write_rgb_tiff(out_dir / f"{prefix}_{key}_16bit.tif", rgb, space)
        del rgb
        report(progress, 0.6 + 0.2 * (i + 1), f"wrote {space}")
    del xyz
    return files
