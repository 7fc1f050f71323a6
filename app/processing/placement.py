"""Does a patch grid fit the chart in the frame? Checked for every grid, found (app.processing.chart_detect) or
given (``--train-corners``, ``--train-grid``, the window's corners), before its values calibrate anything.

check_placement(grid, image, reference, cells, names) -> Placement, or PlacementError (one line) when

* a patch's sampling window spans more than one tone: the spread of its pixels (10th to 90th percentile, what the
  trimmed mean keeps, less what the window's own noise spreads) over :data:`SPREAD_LIMIT` of the chart's range of
  patch values in some channel: the grid is
  off the patches (a corner misplaced, the wrong rows or columns); windows of fewer than :data:`MIN_WINDOW_PX`
  pixels (a tiny frame) are not judged, said in a warning;
* the chart fits its reference clearly better turned by 180 degrees or mirrored: the reference XYZ fitted linearly
  from the sampled values (least squares with an offset) leaves a residual under :data:`ORIENTATION_RATIO` times the
  grid's own when the grid is turned or mirrored (patch 1 is not where the grid says);
* the values do not follow the reference at all (residual over :data:`FIT_LIMIT`): another chart, or another
  layout, than the one named.

The residual is ``|X - V M| / |X - mean X|`` (Frobenius norms): 0 when the sampled values explain the reference
exactly, 1 when they explain nothing. :func:`placement_figure` draws the grid over the frame for the report.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dualrgb.app.processing.patches import PatchGrid

log = logging.getLogger(__name__)

SPREAD_LIMIT = 0.12          # a window's 10-90 % pixel spread, as a fraction of the chart's range of patch values
MIN_WINDOW_PX = 9            # windows of fewer pixels (median) are too small to judge their spread (a 96 x 64 frame)
ORIENTATION_RATIO = 0.6      # another orientation fitting with this fraction of the residual wins
FIT_LIMIT = 0.35             # residual above which the values do not follow the reference at all
NORMAL_10_90 = 2.5631      # the 10-90 % width of a normal distribution, in sigma (scipy.stats.norm.ppf(0.9) * 2)
NORMAL_MAD = 1.4826        # sigma / median absolute deviation of a normal distribution
ALTERNATIVES = {"turned by 180 degrees": (2, 3, 0, 1), "mirrored left to right": (1, 0, 3, 2),
                "mirrored top to bottom": (3, 2, 1, 0)}


class PlacementError(ValueError):
    """A patch grid that does not fit the chart in the frame (one line: which check, which patch, what to do)."""


@dataclass
class Placement:
    """What the checks found, for the report: the grid's corners, how it was placed, the largest spread and its
    patch, the reference fit's residual as placed and as the alternatives would have it."""

    corners: list[list[float]]
    method: str
    spread: float
    spread_patch: str
    residual: float | None
    alternatives: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"corners": self.corners, "method": self.method,
                "max_spread": round(self.spread, 4) if np.isfinite(self.spread) else None,
                "max_spread_patch": self.spread_patch, "spread_limit": SPREAD_LIMIT,
                "fit_residual": None if self.residual is None else round(self.residual, 4),
                "alternatives": {k: round(v, 4) for k, v in self.alternatives.items()}}


def fit_residual(values: np.ndarray, reference: np.ndarray) -> float:
    """``|X - V M| / |X - mean X|`` for the reference ``X`` (n, 3) fitted from the values ``V`` (n, C) plus an
    offset by least squares (only the first three channels when there are fewer than 4 patches per unknown)."""
    v = np.asarray(values, dtype=float)
    x = np.asarray(reference, dtype=float)
    ok = np.isfinite(v).all(axis=1) & np.isfinite(x).all(axis=1)
    v, x = v[ok], x[ok]
    if v.shape[1] > 3 and len(v) < 4 * (v.shape[1] + 1):
        v = v[:, :3]
    if len(v) < v.shape[1] + 2:
        return float("nan")
    a = np.c_[v, np.ones(len(v))]
    m, *_ = np.linalg.lstsq(a, x, rcond=None)
    spread = np.linalg.norm(x - x.mean(axis=0))
    return float(np.linalg.norm(x - a @ m) / spread) if spread > 0 else float("nan")


def window_noise(box: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(C,) the pixel noise (sigma) in a window, from differences of pixels two apart along its rows: a robust
    (median) estimate, so the few pairs across an edge between two tones do not raise it; two apart because a
    demosaic correlates neighbours. NaN where the window has no such pair."""
    pair = mask[:, 2:] & mask[:, :-2]
    d = (box[:, 2:] - box[:, :-2])[pair].astype(float)
    d = d[np.isfinite(d).all(axis=1)]
    if not len(d):
        return np.full(box.shape[2], np.nan)
    return NORMAL_MAD * np.median(np.abs(d), axis=0) / np.sqrt(2.0)


def window_spread(grid: PatchGrid, image: np.ndarray, cells: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """(len(cells), C) the 10th-to-90th percentile spread of every used cell's sampled pixels beyond what the
    window's own noise gives, and (len(cells),) how many pixels each window holds.

    Noise alone spreads a uniform patch's pixels over :data:`NORMAL_10_90` sigma; that much is taken off (in
    quadrature, the window's noise from :func:`window_noise`), so a noisy frame (high ISO, a dark patch) is not
    taken for a grid off the patches, while a window over two tones keeps their difference."""
    img = image if image.ndim == 3 else image[..., None]
    masks = grid.masks(img.shape[:2])
    out = np.full((len(cells), img.shape[2]), np.nan)
    count = np.zeros(len(cells), dtype=int)
    for i, k in enumerate(cells):
        rs, cs, mask = masks[k]
        if mask.size == 0:
            continue
        box = img[rs, cs]
        px = box[mask].astype(float)
        px = px[np.isfinite(px).all(axis=1)]
        count[i] = len(px)
        if len(px):
            lo, hi = np.percentile(px, [10, 90], axis=0)
            noise = np.nan_to_num(NORMAL_10_90 * window_noise(box, mask))
            out[i] = np.sqrt(np.maximum((hi - lo) ** 2 - noise ** 2, 0.0))
    return out, count


def _orientations(grid: PatchGrid, image: np.ndarray, reference: np.ndarray, cells: Sequence[int]
                  ) -> dict[str, float]:
    """The reference fit's residual with the grid turned by 180 degrees and mirrored either way."""
    out = {}
    for label, order in ALTERNATIVES.items():
        try:
            alt = PatchGrid(grid.corners[list(order)], grid.rows, grid.cols, grid.fraction, cell_boxes=grid.cell_boxes)
        except ValueError:
            continue
        out[label] = fit_residual(alt.sample(image).mean[list(cells)], reference)
    return out


def check_placement(grid: PatchGrid, image: np.ndarray, reference: np.ndarray | None, cells: Sequence[int],
                    names: Sequence[str], *, label: str = "target", method: str = "given",
                    means: np.ndarray | None = None) -> Placement:
    """Check ``grid`` on ``image`` (module docstring); ``means`` (n_cells, C): the grid's sampled means when they
    are known already. Raises PlacementError naming ``label`` and what to do."""
    means = grid.sample(image).mean if means is None else means
    used = np.asarray(means, dtype=float)[list(cells)]
    spread, count = window_spread(grid, image, cells)
    span = np.nanmax(used, axis=0) - np.nanmin(used, axis=0)
    rel = np.nanmax(spread / np.where(span > 0, span, np.inf), axis=1)
    worst = int(np.nanargmax(rel)) if np.isfinite(rel).any() else 0
    corners = [[round(float(x), 2), round(float(y), 2)] for x, y in grid.corners]
    place = Placement(corners, method, float(np.nan_to_num(rel[worst])), names[worst] if names else str(worst), None)
    if np.median(count) < MIN_WINDOW_PX:
        place.spread, place.spread_patch = float("nan"), ""
        log.warning("%s: the sampling windows hold %d pixels (median; at least %d to check them): the patches are too "
                    "small on this frame to tell whether a window spans two of them", label, int(np.median(count)),
                    MIN_WINDOW_PX)
    elif place.spread > SPREAD_LIMIT:
        raise PlacementError(f"{label}: patch {place.spread_patch}'s sampling window spans more than one tone (spread "
                             f"{place.spread:.0%} of the chart's range, limit {SPREAD_LIMIT:.0%}): the grid is off "
                             "the patches; place its corners on the outer edges of the corner patches")
    if reference is None:
        return place
    place.residual = fit_residual(used, reference)
    if not np.isfinite(place.residual):             # too few patches, or a reference without spread: unchecked
        place.residual = None
        return place
    place.alternatives = _orientations(grid, image, reference, cells)
    better = {k: v for k, v in place.alternatives.items() if v < ORIENTATION_RATIO * place.residual}
    if better:
        how = min(better, key=lambda k: better[k])
        raise PlacementError(f"{label}: the chart fits its reference better {how} (residual {better[how]:.3f} "
                             f"against {place.residual:.3f}): patch {names[0] if names else 1} is not at the grid's "
                             "first corner; place the corners starting at the chart's top-left patch, or turn the "
                             "chart")
    if not place.residual <= FIT_LIMIT:
        raise PlacementError(f"{label}: the sampled values do not follow the chart's reference (residual "
                             f"{place.residual:.2f}, limit {FIT_LIMIT}): another chart or another layout is on the "
                             "stand than the one named")
    log.info("%s: placement fits (spread %.1f %% at %s, reference residual %.3f)", label, 100 * place.spread,
             place.spread_patch, place.residual)
    return place


def display_rgb(image: np.ndarray) -> np.ndarray:
    """(H, W, 3) in 0..1 for a figure: the first three channels over their common 99.5th percentile, gamma 1/2.2."""
    img = np.asarray(image, dtype=float)
    img = np.repeat(img[..., None], 3, axis=2) if img.ndim == 2 else img
    img = img[..., :3] if img.shape[2] >= 3 else np.repeat(img[..., :1], 3, axis=2)
    finite = img[np.isfinite(img)]
    top = float(np.percentile(finite, 99.5)) if finite.size else 1.0
    return np.clip(np.nan_to_num(img / (top or 1.0)), 0, 1) ** (1 / 2.2)


def placement_figure(path: Path, image: np.ndarray, grid: PatchGrid, title: str, cells: Sequence[int] = ()
                     ) -> Path:
    """The frame with the grid's sampling windows drawn over it (used cells yellow, others grey), the chart's
    top-left corner marked and the first patch numbered, so a reader sees where every value came from."""
    from matplotlib.patches import Polygon

    from dualrgb.app.processing.figure_files import new_figure, save_tight

    rgb = display_rgb(image)
    h, w = rgb.shape[:2]
    fig = new_figure(7.0, max(2.5, 7.0 * h / max(w, 1) + 0.6))
    ax = fig.add_subplot(111)
    ax.imshow(rgb, interpolation="nearest")
    used = set(cells) if cells else set(range(grid.n_patches))
    for k, poly in enumerate(grid.sample_polygons()):
        if np.isfinite(poly).all():
            ax.add_patch(Polygon(poly, closed=True, fill=False, lw=0.6,
                                 edgecolor="yellow" if k in used else "0.6"))
    ax.add_patch(Polygon(grid.corners, closed=True, fill=False, lw=0.8, edgecolor="cyan"))
    ax.plot(*grid.corners[0], "o", color="red", ms=5)
    first = grid.centres()[min(used) if used else 0]
    ax.text(first[0], first[1], "1", color="red", ha="center", va="center", fontsize=8, weight="bold")
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(f"{title}\npatch placement (red dot: the chart's top-left corner)", fontsize=8)
    return save_tight(fig, path)
