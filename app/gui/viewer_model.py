"""What the image viewer shows (issue 42), Qt-free: a delivered master or a captured raw frame as a picture for
the screen, the values under a pixel, and where it is clipped or under-exposed. Loaded in a worker; the viewer
(app.gui.image_viewer) only draws it.

* **A delivered master** (its sidecar): the sRGB master for the screen (16 -> 8 bit), the six camera-RGB channels
  (``<id>_light<n>_cameraRGB_16bit.tif``: 1.0 = the white), CIE XYZ (``<id>_XYZ_16bit.tif``, decoded by the
  sidecar's ``encoding``: XYZ = code / xyz_one * white_xyz) and CIE L*a*b* of it relative to the calibration's
  white, all at the delivered resolution. *Clipped*: a camera channel at the encoding's ceiling (65535, twice the
  white: nothing brighter can be told apart); *near black*: L* below :data:`UNDER_L` (a master's exposures were
  planned by metering, with an HDR bracket where the shadows needed one: the raw frames' under-exposure is in the
  QA line; here the overlay shows where the tones are too deep to hold detail).
* **A raw frame** (DNG / NEF): one pixel per 2x2 Bayer cell (R, the greens' mean, B in raw DN; no interpolation,
  so nothing shown is invented), the camera RGB only (XYZ needs both lights' frames and a calibration).
  *Clipped*: a channel at or above the linear limit (app.processing.hdr.LINEAR_LIMIT_DN, raw DN as the sensor
  writes them); *under-exposed*: every channel below :data:`UNDER_FRACTION` of the linear range above black.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dualrgb.app.processing.hdr import LINEAR_LIMIT_DN

log = logging.getLogger(__name__)

UNDER_L = 3.0                    # L* below which a master's pixel is marked under-exposed
UNDER_FRACTION = 0.01            # a frame's pixel: every channel below 1 % of (linear limit - black)
CLIP_RGBA = (255, 0, 0, 220)     # the overlay's colours: clipped red, under-exposed / near black blue (the
UNDER_RGBA = (40, 110, 255, 120)  # picture stays readable under it)
ZOOMS = (1.0, 2.0, 4.0)          # the viewer's fixed zooms besides Fit: 100, 200, 400 %


@dataclass
class ViewImage:
    """A picture with its measurable values, row-major (H, W, ...)."""

    title: str
    display: np.ndarray                         # (H, W, 3) uint8 for the screen
    camera: np.ndarray                          # (H, W, C) the camera channels (float32 scaled: see camera_unit)
    camera_names: list[str]
    camera_unit: str                            # 'DN' (a frame) or '' (a master: 1.0 = the white)
    clipped: np.ndarray                         # (H, W) bool
    under: np.ndarray                           # (H, W) bool
    under_name: str = "under-exposed"           # a master: 'near black (L* < 3)' (its exposure was HDR-planned)
    xyz: np.ndarray | None = None               # (H, W, 3) float32, Y = Yn for the white (a master)
    white_xyz: tuple[float, float, float] = (0.9642, 1.0, 0.8251)
    notes: list[str] = field(default_factory=list)

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.display.shape[0]), int(self.display.shape[1])

    def overlay(self) -> np.ndarray:
        """(H, W, 4) uint8: clipped pixels red, under-exposed blue, the rest transparent."""
        out = np.zeros((*self.shape, 4), np.uint8)
        out[self.under] = UNDER_RGBA
        out[self.clipped] = CLIP_RGBA
        return out

    def fractions(self) -> tuple[float, float]:
        """The clipped and under-exposed shares of the pixels (0-1)."""
        n = max(self.clipped.size, 1)
        return float(self.clipped.sum()) / n, float(self.under.sum()) / n

    def values(self, x: int, y: int) -> str:
        """One line: the pixel's position and values (camera RGB, XYZ, L*a*b* where known)."""
        h, w = self.shape
        if not (0 <= x < w and 0 <= y < h):
            return ""
        cam = " ".join(f"{n} {v:.4g}" for n, v in zip(self.camera_names, self.camera[y, x], strict=False))
        parts = [f"x {x}, y {y}", f"camera RGB{' (' + self.camera_unit + ')' if self.camera_unit else ''}: {cam}"]
        if self.xyz is not None:
            xyz = self.xyz[y, x].astype(np.float64)
            lab = lab_of(xyz, self.white_xyz)
            parts.append("XYZ " + " ".join(f"{v:.4f}" for v in xyz))
            parts.append("L*a*b* " + " ".join(f"{v:.2f}" for v in lab))
        else:
            parts.append("XYZ, L*a*b*: a delivered master has them (a frame is one light)")
        if self.clipped[y, x]:
            parts.append("clipped")
        elif self.under[y, x]:
            parts.append(self.under_name)
        return "; ".join(parts)


def lab_of(xyz: np.ndarray, white_xyz: tuple[float, float, float]) -> np.ndarray:
    """CIE L*a*b* (CIE 15) of XYZ relative to ``white_xyz`` (colour-science's XYZ_to_Lab)."""
    import colour

    white = np.asarray(white_xyz, np.float64)
    return np.asarray(colour.XYZ_to_Lab(np.asarray(xyz, np.float64) / white[1], colour.XYZ_to_xy(white)))


def _tiff(path: Path) -> np.ndarray:
    import tifffile

    return np.asarray(tifffile.imread(path))


def load_master(sidecar: Path) -> ViewImage:
    """A delivered original from its sidecar JSON (the files beside it): see the module docstring."""
    doc = json.loads(Path(sidecar).read_text(encoding="utf-8"))
    folder, files, enc = Path(sidecar).parent, doc.get("files", {}), doc.get("encoding", {})
    display = (_tiff(folder / files["srgb"]) >> 8).astype(np.uint8)[..., :3]
    wx, wy, wz = (float(v) for v in enc.get("white_xyz", (0.9642, 1.0, 0.8251)))
    white = (wx, wy, wz)
    xyz = _tiff(folder / files["xyz"])[..., :3].astype(np.float32) / float(enc.get("xyz_one", 65535.0))
    xyz *= np.asarray(white, np.float32)
    light_keys = sorted((k for k in files if k.startswith("channels_")), key=lambda k: int(k.split("_")[1]))
    planes = [_tiff(folder / files[k])[..., :3] for k in light_keys]
    codes = np.concatenate(planes, axis=2) if planes else np.zeros((*display.shape[:2], 0), np.uint16)
    names = [str(c) for c in enc.get("channels", [])][:codes.shape[2]] or \
        [f"{c}{i // 3 + 1}" for i, c in zip(range(codes.shape[2]), "RGB" * 4, strict=False)]
    camera = codes.astype(np.float32) / float(enc.get("linear_one", 32768.0))
    y_rel = xyz[..., 1] / white[1]                         # L* (CIE 15), vectorised for the whole picture
    lab_l = 116.0 * np.where(y_rel > (6 / 29) ** 3, np.cbrt(y_rel), y_rel / (3 * (6 / 29) ** 2) + 4 / 29) - 16.0
    ident = doc.get("original", {}).get("identifier", folder.name)
    clipped = np.asarray((codes >= 65535).any(axis=2), bool)
    return ViewImage(f"{ident} (delivered, {display.shape[1]} x {display.shape[0]} px)", display, camera, names, "",
                     clipped, np.asarray(lab_l < UNDER_L, bool), f"near black (L* < {UNDER_L:g})", xyz, white)


def load_frame(path: Path) -> ViewImage:
    """A captured raw frame: see the module docstring."""
    from dualrgb.app.gui.viewmodel import display_rgb
    from dualrgb.drivers.raw import load_raw, superpixel

    frame = load_raw(path)
    raw = superpixel(frame, subtract_black=False)
    black = float(np.mean(frame.black_levels))
    display = display_rgb(np.maximum(raw - black, 0.0), full_scale=frame.white_level - black)
    under = np.asarray((raw - black < UNDER_FRACTION * (LINEAR_LIMIT_DN - black)).all(axis=2), bool)
    clipped = np.asarray((raw >= LINEAR_LIMIT_DN).any(axis=2), bool)
    return ViewImage(f"{Path(path).name} (raw frame, one pixel per 2x2 cell: {raw.shape[1]} x {raw.shape[0]})",
                     display, raw.astype(np.float32), ["R", "G", "B"], "DN", clipped, under)
