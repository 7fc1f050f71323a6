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


def shoot(path: Path, exposure_s: float, level: int, n: int, **info) -> Path:
    """One small DNG: black 600 + ``level`` with a per-file pattern (distinct bytes for distinct shots)."""
    mosaic = np.full(SHAPE, 600 + level, np.uint16)
    mosaic[n % SHAPE[0], :] += 1 + n
    fields = {"exposure_s": exposure_s, "iso": 100, "aperture": 8.0, "serial": "3012345", "model": "Nikon D610",
              "captured_at": START + 2 * n, **info}
    return save_dng(path, mosaic, DngInfo(**fields))


def make_folder(root: Path, shots=SHOTS, **info) -> tuple[Path, Path]:
    """(the folder of Capture_0001.dng ..., its ROLES.csv beside it)."""
    folder = root / "raw"
    folder.mkdir(parents=True)
    rows = [HEADER]
    for n, (role, light, ident, t, level) in enumerate(shots, start=1):
        name = f"Capture_{n:04d}.dng"
        shoot(folder / name, t, level, n, **info)
        rows.append([name, role, light, ident, "A painting" if role == "original" else ""])
    roles = root / "ROLES.csv"
    write_rows(roles, rows)
    return folder, roles


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
