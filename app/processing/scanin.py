"""ArgyllCMS ``scanin`` as a second chart finder: the real tool colour people use to read charts from images, run as
an external program (Debian package ``argyll``; its recognition templates, ``*.cht``, come with ``argyll-ref``).

scanin_grid(image, geometry) -> PatchGrid
    Writes the image as an 8-bit TIFF, runs ``scanin -o -dp FRAME.tif TEMPLATE.cht DIAG.tif`` (every orientation),
    and turns what scanin reports into a patch grid: its ``.val`` file gives every patch's mean colour by name, its
    diagnostic image (``-dp``: the sampled pixels in their own colour, black elsewhere) where each patch was sampled;
    each sampled area is matched to its patch by colour (only unambiguous matches), and the homography from the
    chart's patch centres (simulation.chart_geometry) to those areas' centroids gives the grid's corners.

scanin reports values, not positions, so the positions are read back this way; it knows only the charts it has
templates for (the ColorChecker Classic, Digital SG, IT8.7; not the virtual lab's generic grid). Where it is not
installed :class:`ScaninUnavailable` says which Debian package to install. app.processing.chart_detect uses it when
its own search finds nothing; the tests use it as an independent check of that search.
"""
from __future__ import annotations

import logging
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
from scipy import ndimage

from dualrgb.app.processing.patches import ChartNotFound, PatchGrid, grid_on, homography
from dualrgb.simulation.chart_geometry import ARGYLL_REF, ChartGeometry

log = logging.getLogger(__name__)

SCANIN = "scanin"
TIMEOUT_S = 120.0                    # a hang guard: scanin takes seconds
MATCH_DN = 2.0                       # a sampled area's colour within this (8-bit levels) of its patch's value
UNIQUE_DN = 4.0                      # ... and every other patch's further than this
MIN_MATCHES = 8
_NAME = re.compile(r"^([A-Z]{1,2})(\d{1,2})$")


class ScaninUnavailable(RuntimeError):
    """scanin or its chart template is not installed (one line saying which Debian package to install)."""


def template_for(geometry: ChartGeometry) -> Path:
    """The ArgyllCMS recognition template of ``geometry``'s chart; ScaninUnavailable when it has none or it is not
    installed."""
    if shutil.which(SCANIN) is None:
        raise ScaninUnavailable("ArgyllCMS scanin is not installed: install the Debian package 'argyll' (and "
                                "'argyll-ref' for its chart templates)")
    if not geometry.template:
        raise ScaninUnavailable(f"ArgyllCMS has no recognition template for a {geometry.name} chart "
                                f"({geometry.layout[0]}x{geometry.layout[1]})")
    path = Path(ARGYLL_REF) / geometry.template
    if not path.is_file():
        raise ScaninUnavailable(f"{path}: ArgyllCMS's chart template is missing: install the Debian package "
                                "'argyll-ref'")
    return path


def patch_index(geometry: ChartGeometry, name: str) -> int | None:
    """The geometry's patch index of a patch as ArgyllCMS's template names it (CC24: A1 .. D6, rows A-D; SG: A1 ..
    N10, columns A-N; IT8: A01 .. L22, rows A-L, then GS00 .. GS23); None for a name it does not place."""
    if geometry.name == "IT8.7" and name.startswith("GS") and name[2:].isdigit():
        k = int(name[2:])
        return 264 + k if 0 <= k < 24 else None
    m = _NAME.match(name.strip().upper())
    if m is None or len(m.group(1)) != 1:
        return None
    letter, number = ord(m.group(1)) - ord("A"), int(m.group(2)) - 1
    rows, cols = geometry.blocks[0].rows, geometry.blocks[0].cols
    if geometry.name == "ColorChecker Digital SG":
        r, c = number, letter
    else:
        r, c = letter, number
    return r * cols + c if 0 <= r < rows and 0 <= c < cols else None


def read_val(path: Path) -> dict[str, np.ndarray]:
    """scanin's ``.val`` file: SAMPLE_ID -> (R, G, B) on the 0-255 scale of the image it read."""
    lines = path.read_text(errors="replace").splitlines()
    out = {}
    inside = False
    for line in lines:
        if line.strip() == "BEGIN_DATA":
            inside = True
        elif line.strip() == "END_DATA":
            break
        elif inside and line.strip():
            cells = line.split()
            out[cells[0].strip('"')] = np.asarray([float(v) for v in cells[1:4]])
    return out


def _areas(diag: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(centroids (n, 2) x, y, mean colours (n, 3)) of the sampled areas of scanin's ``-dp`` diagnostic image."""
    lit = np.any(diag > 0, axis=2)
    labels, n = ndimage.label(lit)
    idx = np.arange(1, n + 1)
    cy, cx = (np.asarray(v) for v in zip(*ndimage.center_of_mass(lit, labels, idx), strict=True)) if n else ([], [])
    colours = np.stack([ndimage.mean(diag[..., k].astype(float), labels, idx) for k in range(3)], axis=1) if n \
        else np.zeros((0, 3))
    return np.c_[cx, cy], colours


def _matches(geometry: ChartGeometry, values: dict[str, np.ndarray], centroids: np.ndarray, colours: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (patch index, centroid) where one sampled area's colour matches one patch's value unambiguously."""
    named = [(patch_index(geometry, n), v) for n, v in values.items()]
    named = [(k, v) for k, v in named if k is not None]
    if not named or not len(colours):
        return np.zeros(0, int), np.zeros((0, 2))
    ref = np.asarray([v for _, v in named])
    d = np.linalg.norm(colours[:, None, :] - ref[None, :, :], axis=2)           # (areas, patches)
    order = np.sort(d, axis=1)
    best = np.argmin(d, axis=1)
    ok = (order[:, 0] < MATCH_DN) & ((order[:, 1] if d.shape[1] > 1 else np.inf) > UNIQUE_DN)
    return np.asarray([named[b][0] for b in best[ok]], int), centroids[ok]


def _fit(geometry: ChartGeometry, index: np.ndarray, centroids: np.ndarray) -> np.ndarray:
    """Corners of the patch area from the homography of the patch centres (unit square) onto the centroids
    (least squares, areas more than 2 px off the first fit dropped)."""
    x0, y0, x1, y1 = geometry.patch_area
    c = geometry.centres()[index]
    uv = np.c_[(c[:, 0] - x0) / (x1 - x0), (c[:, 1] - y0) / (y1 - y0)]
    keep = np.ones(len(uv), bool)
    for _ in range(2):
        h = homography(uv[keep], centroids[keep])
        q = np.c_[uv, np.ones(len(uv))] @ h.T
        err = np.linalg.norm(q[:, :2] / q[:, 2:3] - centroids, axis=1)
        keep = err < max(2.0, 3 * float(np.median(err)))
    unit = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float) @ h.T
    return unit[:, :2] / unit[:, 2:3]


def scanin_grid(image: np.ndarray, geometry: ChartGeometry, *, fraction: float = 0.5) -> PatchGrid:
    """The chart found by ArgyllCMS scanin (module docstring), as a patch grid on ``image``'s pixels; raises
    ScaninUnavailable when scanin or the template is missing, ValueError (one line) when scanin finds no chart."""
    from dualrgb.app.processing.placement import display_rgb

    template = template_for(geometry)
    import tifffile

    rgb = (16 + np.round(display_rgb(image) * 239)).astype(np.uint8)      # no black: -dp draws black as "unsampled"
    with tempfile.TemporaryDirectory(prefix="dualrgb-scanin-") as tmp:
        frame, diag = Path(tmp) / "frame.tif", Path(tmp) / "diag.tif"
        tifffile.imwrite(frame, rgb, photometric="rgb")
        try:
            r = subprocess.run([SCANIN, "-o", "-dp", str(frame), str(template), str(diag)], capture_output=True,
                               text=True, timeout=TIMEOUT_S, cwd=tmp)
        except subprocess.TimeoutExpired:
            raise ChartNotFound(f"scanin found no {geometry.name} chart within {TIMEOUT_S:g} s") from None
        if r.returncode != 0 or not frame.with_suffix(".val").is_file():
            said = (r.stderr or r.stdout).strip().splitlines()
            why = said[-1] if said else f"exit {r.returncode}"
            raise ChartNotFound(f"scanin found no {geometry.name} chart ({why})")
        values = read_val(frame.with_suffix(".val"))
        centroids, colours = _areas(tifffile.imread(diag))
    index, where = _matches(geometry, values, centroids, colours)
    if len(index) < MIN_MATCHES:
        raise ChartNotFound(f"scanin read the {geometry.name} chart, but only {len(index)} of its sampled patches "
                            f"could be told apart by colour (at least {MIN_MATCHES} needed)")
    log.info("scanin: %s found (%d patches located)", geometry.name, len(index))
    return grid_on(_fit(geometry, index, where), geometry, fraction)
