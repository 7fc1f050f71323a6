"""A folder of raw files "shot by another program" for the import tests: small DNGs written with the app's one DNG
writer (darks, flats under two lights, the training and test targets, one original), named as Capture One names
them, with their ROLES.csv. Pixels are flat levels: enough for every check an import makes before writing."""
from __future__ import annotations

import csv
import hashlib
import os
from datetime import datetime
from pathlib import Path

import numpy as np

from dualrgb.drivers.virtual.dng import DngInfo, save_dng

SHAPE = (32, 48)
T1, T2 = 0.5, 1 / 60
START = datetime(2026, 5, 4, 10, 0, 0).timestamp()
HEADER = ["file", "role", "light", "identifier", "title"]
# (role, light, identifier, exposure, lit level above black)
SHOTS = [("dark", "", "", T1, 0), ("dark", "", "", T1, 0), ("dark", "", "", T2, 0), ("dark", "", "", T2, 0),
         ("flat", "1", "", T1, 8000), ("flat", "1", "", T1, 8000), ("flat", "2", "", T2, 8000),
         ("flat", "2", "", T2, 8000), ("target", "1", "train", T1, 3000), ("target", "2", "train", T2, 3000),
         ("target", "1", "test", T1, 2500), ("target", "2", "test", T2, 2500),
         ("original", "1", "ACC-1", T1, 2000), ("original", "2", "ACC-1", T2, 2000)]


PATCHED = (96, 136)          # a frame size the charts' patches fit (the 12x17 training grid: 4 x 4 px stack cells)
LAYOUTS = {"train": (12, 17), "test": (4, 6)}


def patches(shape: tuple[int, int], name: str) -> np.ndarray:
    """(h/2, w/2, 3) per-cell factors of a chart's patches filling the frame (row by row), as seen on the 2x2-cell
    stack: the packaged reflective chart's reference XYZ scaled into 0.1-0.9 (cells without a patch 0.05), so its
    patches follow their reference as a real chart's do (the calibration's placement check asks that)."""
    from dualrgb.app.workflow.targets import target_spec
    from dualrgb.app.workflow.vocabulary import Subject

    spec = target_spec("reflective", Subject.target(name), None)
    rows, cols = LAYOUTS[name]
    values = np.full((rows * cols, 3), 0.05)
    xyz = np.asarray(spec.xyz, dtype=float)
    values[spec.cell_indices()] = 0.1 + 0.8 * xyz / xyz.max()
    h, w = shape[0] // 2, shape[1] // 2
    r = np.arange(h)[:, None] * rows // h
    c = np.arange(w)[None, :] * cols // w
    return values[(r * cols + c)]


def shoot(path: Path, exposure_s: float, level: int, n: int, *, chart: str = "", shape: tuple[int, int] = SHAPE,
          **info) -> Path:
    """One small DNG: black 600 + ``level`` (times a chart's patches for a target of ``chart``) with a per-file
    pattern (distinct bytes for distinct shots)."""
    from dualrgb.app.processing.mosaic import mosaic_from_rgb

    if chart:
        mosaic = (600 + mosaic_from_rgb(level * patches(shape, chart))).astype(np.uint16)
    else:
        mosaic = np.full(shape, 600 + level, np.uint16)
    mosaic[n % shape[0], :] += 1 + n
    fields = {"exposure_s": exposure_s, "iso": 100, "aperture": 8.0, "serial": "3012345", "model": "Nikon D610",
              "captured_at": START + 2 * n, **info}
    return save_dng(path, mosaic, DngInfo(**fields))


def make_folder(root: Path, shots=SHOTS, *, shape: tuple[int, int] = SHAPE, **info) -> tuple[Path, Path]:
    """(the folder of Capture_0001.dng ..., its ROLES.csv beside it); at :data:`PATCHED` size the targets show
    their charts' patches filling the frame (``corners(shape)``), so the whole import runs on them."""
    folder = root / "raw"
    folder.mkdir(parents=True)
    rows = [HEADER]
    for n, (role, light, ident, t, level) in enumerate(shots, start=1):
        name = f"Capture_{n:04d}.dng"
        chart = ident if role == "target" and shape != SHAPE else ""
        shoot(folder / name, t, level, n, chart=chart, shape=shape, **info)
        rows.append([name, role, light, ident, "A painting" if role == "original" else ""])
    roles = root / "ROLES.csv"
    write_rows(roles, rows)
    return folder, roles


def corners(shape: tuple[int, int]) -> str:
    """The charts' corners in a frame of ``shape`` that :func:`patches` fills: the frame's outer edges."""
    h, w = shape
    return f"-0.5,-0.5,{w - 0.5},-0.5,{w - 0.5},{h - 0.5},-0.5,{h - 0.5}"


def write_rows(path: Path, rows: list[list[str]]) -> Path:
    with open(path, "w", newline="", encoding="utf-8") as fh:
        csv.writer(fh).writerows(rows)
    return path


def tree(root: Path) -> dict[str, str]:
    """Every file under ``root`` -> its sha256 (what 'nothing written' compares)."""
    out = {}
    for dirpath, _dirs, files in os.walk(root):
        for name in files:
            p = Path(dirpath) / name
            out[str(p.relative_to(root))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out
