"""Delivered XYZ against a per-pixel ground truth: CIEDE2000 statistics, the dE00 map and its figure.

Ground truth comes from the virtual lab's originals (``VirtualLab.ground_truth_xyz``; drivers/virtual/
originals.py): per sensor pixel, on the eq 4.2 scale (D65, CIE 1931 2 degree, Y of a perfect white = 100),
rows down and columns right as the raw mosaic. The processing delivers one value per 2x2 Bayer cell
(app/processing/mosaic.py ``superpixel``); :func:`bin_to_superpixels` brings the truth to that grid (the mean
XYZ of each cell; exact for the virtual originals, whose 2x2 cells are each one material).

dE00 is simulation.colorimetry's float64 CIEDE2000 (kL = kC = kH = 1, thesis 6.2.3), computed in bands of
rows so a 24 MP delivery needs no more than a few bands' worth of temporaries.

Two figures answer two questions. The per-pixel statistics (mean, p90, max, the map) are what a user of the
delivered file sees: colour error *plus* sensor noise, which the 3L x 3 characterisation matrix amplifies (a
single 14-bit frame per light gives ~0.7 dE00 of noise on the virtual painting under the dual-RGB-PSO preset).
The *material* statistics average the delivered XYZ over every pixel that shares one ground-truth value (one
paint, one gradient step) before the dE00, as a chart's error is taken on patch means: the colour error with
the noise averaged out, comparable with the calibration's test-target error.

    truth = lab.ground_truth_xyz("painting", lab.height, lab.width)
    result = compare_to_ground_truth(delivered_xyz, truth, white)      # truth binned automatically
    write_de_map_png(out / "painting_de00.png", result.de_map, title="painting")
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dualrgb.app.processing.mosaic import row_bands
from dualrgb.simulation.colorimetry import delta_e_2000, xyz_to_lab

log = logging.getLogger(__name__)

DE_MAP_MAX = 5.0          # fixed colour scale of the dE00 map figure, so figures compare at a glance


@dataclass
class GroundTruthComparison:
    """dE00 of a delivered XYZ image against its ground truth.

    ``de_map`` (H, W) float32 is NaN where the delivered value is not finite (clipped or invalid pixels);
    the statistics are over the ``n_pixels`` finite ones, ``n_invalid`` counts the rest.
    """

    mean: float
    median: float
    p90: float
    p99: float
    max: float
    n_pixels: int
    n_invalid: int
    de_map: np.ndarray
    material_mean: float = float("nan")     # area-weighted dE00 of material means (noise averaged out)
    material_max: float = float("nan")
    n_materials: int = 0

    def to_dict(self) -> dict:
        return {"mean": round(self.mean, 4), "median": round(self.median, 4), "p90": round(self.p90, 4),
                "p99": round(self.p99, 4), "max": round(self.max, 4), "n_pixels": self.n_pixels,
                "n_invalid": self.n_invalid, "material_mean": round(self.material_mean, 4),
                "material_max": round(self.material_max, 4), "n_materials": self.n_materials}


def bin_to_superpixels(image: np.ndarray) -> np.ndarray:
    """(H, W, C) per sensor pixel -> (H // 2, W // 2, C) float32 mean of each 2x2 Bayer cell.

    Cell (i, j) covers sensor rows 2i, 2i + 1 and columns 2j, 2j + 1, the cell ``mosaic.superpixel`` turns
    into one pixel; an odd last row or column is dropped as there.
    """
    image = np.asarray(image)
    if image.ndim != 3:
        raise ValueError(f"expected an (H, W, C) image, got shape {image.shape}")
    h2, w2 = image.shape[0] // 2, image.shape[1] // 2
    out = np.zeros((h2, w2, image.shape[2]), dtype=np.float32)
    for dy in (0, 1):
        for dx in (0, 1):
            out += image[dy: 2 * h2: 2, dx: 2 * w2: 2]
    out *= 0.25
    return out


def _matching_truth(xyz_image: np.ndarray, truth_xyz: np.ndarray) -> np.ndarray:
    """The truth on the image's grid: as given, or binned when it is at sensor resolution (2x per axis)."""
    if xyz_image.ndim != 3 or xyz_image.shape[2] != 3:
        raise ValueError(f"delivered XYZ image has shape {xyz_image.shape}; expected (H, W, 3)")
    if truth_xyz.ndim != 3 or truth_xyz.shape[2] != 3:
        raise ValueError(f"ground truth has shape {truth_xyz.shape}; expected (H, W, 3)")
    if truth_xyz.shape == xyz_image.shape:
        return truth_xyz
    if truth_xyz.shape[0] // 2 == xyz_image.shape[0] and truth_xyz.shape[1] // 2 == xyz_image.shape[1]:
        return bin_to_superpixels(truth_xyz)
    raise ValueError(f"ground truth {truth_xyz.shape[1]}x{truth_xyz.shape[0]} does not match the delivered image "
                     f"{xyz_image.shape[1]}x{xyz_image.shape[0]} (expected the same size or the sensor size, "
                     f"twice the superpixel image)")


def compare_to_ground_truth(xyz_image: np.ndarray, truth_xyz: np.ndarray, white: np.ndarray, *,
                            band_rows: int = 256, mask: np.ndarray | None = None) -> GroundTruthComparison:
    """Per-pixel CIEDE2000 of ``xyz_image`` against ``truth_xyz`` (both on ``white``'s scale, Y_white = 100).

    Parameters
    ----------
    xyz_image : (H, W, 3) delivered XYZ (e.g. the XYZ TIFF of a processed capture, superpixel grid).
    truth_xyz : (H, W, 3) ground truth, or (2H, 2W, 3) at sensor resolution (binned to superpixels here).
    white : (3,) XYZ of the Lab reference white (simulation.colorimetry.white_point of D65).
    mask : optional (H, W) bool, True where pixels count (e.g. to leave out an area); all by default.

    References
    ----------
    CIEDE2000: Sharma, Wu, Dalal (2005); thesis chapter 6.2.3 (kL = kC = kH = 1).
    """
    xyz_image = np.asarray(xyz_image)
    truth = _matching_truth(xyz_image, np.asarray(truth_xyz))
    white = np.asarray(white, dtype=float)
    de = np.empty(xyz_image.shape[:2], dtype=np.float32)
    for rows in row_bands(xyz_image.shape[0], band_rows):
        est = xyz_image[rows].astype(np.float64)
        ref = truth[rows].astype(np.float64)
        with np.errstate(invalid="ignore"):
            de[rows] = delta_e_2000(xyz_to_lab(ref, white), xyz_to_lab(est, white))
    valid = np.isfinite(de)
    if mask is not None:
        if np.shape(mask) != de.shape:
            raise ValueError(f"mask has shape {np.shape(mask)}; expected {de.shape}")
        valid &= np.asarray(mask, dtype=bool)
    n_invalid = int((~np.isfinite(de)).sum())
    values = de[valid].astype(np.float64)
    if values.size == 0:
        raise ValueError("no valid pixel to compare: every delivered value is NaN/inf or masked out")
    p50, p90, p99 = np.percentile(values, [50, 90, 99])
    m_mean, m_max, n_mat = _material_errors(xyz_image, truth, white, valid)
    result = GroundTruthComparison(float(values.mean()), float(p50), float(p90), float(p99), float(values.max()),
                                   int(values.size), n_invalid, de, m_mean, m_max, n_mat)
    log.info("dE00 against ground truth: mean %.3f, p90 %.3f, max %.3f over %d pixels (%d invalid); "
             "materials %.3f (%d)", result.mean, result.p90, result.max, result.n_pixels, n_invalid, m_mean, n_mat)
    return result


def _material_errors(xyz_image: np.ndarray, truth: np.ndarray, white: np.ndarray,
                     valid: np.ndarray) -> tuple[float, float, int]:
    """Area-weighted mean and max dE00 of the mean delivered XYZ of each material (pixels sharing one truth)."""
    ref = np.ascontiguousarray(truth[valid], dtype=np.float32)
    # one 12-byte key per pixel: np.unique on it is ~7x faster than np.unique(axis=0) at 24 MP
    keys = ref.view(np.dtype((np.void, 12))).ravel()
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    counts = np.bincount(inverse).astype(np.float64)
    est = xyz_image[valid].astype(np.float64)
    means = np.stack([np.bincount(inverse, weights=est[:, c]) for c in range(3)], axis=1) / counts[:, None]
    de = delta_e_2000(xyz_to_lab(ref[first].astype(np.float64), white), xyz_to_lab(means, white))
    return float(np.sum(de * counts) / counts.sum()), float(de.max()), int(len(counts))


def block_max(de_map: np.ndarray, max_pixels: int) -> np.ndarray:
    """``de_map`` reduced by an integer factor until it fits ``max_pixels``: each block's worst (NaN-ignoring)
    value, so one bad pixel in a 24 MP map still shows; a block of NaN stays NaN."""
    step = max(1, int(np.ceil(max(de_map.shape) / max_pixels)))
    if step == 1:
        return de_map
    h, w = de_map.shape[0] // step * step, de_map.shape[1] // step * step
    blocks = de_map[:h, :w].reshape(h // step, step, w // step, step)
    return np.fmax.reduce(np.fmax.reduce(blocks, axis=3), axis=1)


def write_de_map_png(path: Path, de_map: np.ndarray, *, title: str = "", vmax: float = DE_MAP_MAX,
                     max_pixels: int = 1600, label: str = "ΔE00") -> Path:
    """A PNG of the dE00 map (or another per-pixel error, named by ``label``) with a colour bar on a fixed
    0..``vmax`` scale (larger errors show as ``vmax``).

    Maps wider or taller than ``max_pixels`` are shown block-max-reduced (the worst pixel of each block), so
    an isolated large error stays visible; NaN (invalid) pixels are grey.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = Path(path)
    de = block_max(np.asarray(de_map, dtype=np.float32), max_pixels)
    aspect = de.shape[1] / max(de.shape[0], 1)
    fig = Figure(figsize=(min(12.0, 2.0 + 5.0 * aspect), 5.6), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    import matplotlib

    cmap = matplotlib.colormaps["magma"].with_extremes(bad="0.6")
    im = ax.imshow(np.ma.masked_invalid(de), cmap=cmap, vmin=0.0, vmax=vmax, interpolation="nearest")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title or "CIEDE2000 against ground truth")
    bar = fig.colorbar(im, ax=ax, extend="max", fraction=0.046, pad=0.04)
    bar.set_label(label)
    fig.tight_layout()
    from dualrgb.app.processing.figure_files import save_figure  # the atomic write: a full disk leaves no half PNG

    return save_figure(fig, path)
