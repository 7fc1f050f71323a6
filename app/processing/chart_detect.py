"""Finding a chart's patches in a frame as a physical stand must: from the chart's layout and the image alone.

detect_chart(image, geometry, reference=..., cells=...) -> PatchGrid
    ``image``: a target's stack (H, W, C) in superpixel coordinates (app.processing.pipeline), or any image;
    ``geometry``: where the chart's patches lie on it (simulation.chart_geometry: ColorChecker Classic, Digital SG,
    IT8.7/1 and /2, or a generic grid of patches with gaps); ``reference``: the chart's reference XYZ of the
    patches in ``cells`` (they decide which way up the chart lies). Raises :class:`ChartNotFound` (one line) when
    the chart is not there.

How (the same idea as ArgyllCMS ``scanin``'s recognition, written for numpy):

1. the luminance (channels normalised, log-compressed so a film's dense patches still show edges), smoothed, and
   its gradient (Sobel); a small image is searched enlarged, so its one-pixel gaps survive the smoothing;
2. the chart's rotation modulo 90 degrees: the angle whose gradient projections (step 3) peak most sharply, searched
   around the peak of the gradient directions;
3. the gradient projected onto the two turned axes: two edge profiles, peaked where patch edges run;
4. each profile matched against the chart's list of patch edges (ChartGeometry.edges) over every scale and offset
   (and both directions), scored by how far the profile at those edges stands above the profile around them: the
   patch area's extent along that axis; both axis assignments are tried (a chart lying at 90 degrees);
5. the placements the edges allow (a ColorChecker looks the same turned by 180 degrees; with a reference also each
   moved by up to three patch pitches: an IT8's contiguous patches match nearly as well a pitch off) ranked by how
   well their values fit the reference XYZ (a linear fit, app.processing.placement); a mirrored best is refused;
   without a reference the best edge match, the most upright of equals;
6. the chosen one's corners refined by maximising the gradient along every patch edge (Powell, 8 parameters: any
   perspective); a match whose patch edges are not clearly sharper than its patches' insides (:data:`MIN_CONTRAST`)
   is no chart.

Where this finds nothing ArgyllCMS scanin is asked (app.processing.scanin, when installed and it has a template
for the chart), its find turned the way the reference fits best.

Why a detector of our own: ``scanin`` (app.processing.scanin) is an external program (Debian ``argyll``), works on
TIFF files, returns patch values rather than positions and knows only the charts it has templates for (not a
generic grid); colour-checker-detection (patches.detect_cc24) finds only the 24-patch Classic and pulls OpenCV.
This one needs numpy and scipy; tests/app/test_chart_detect.py checks it against the virtual lab's known corners
and against ``scanin``'s own recognition of the same frames.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, optimize

from dualrgb.app.processing.patches import ChartNotFound, PatchGrid, grid_on, homography
from dualrgb.simulation.chart_geometry import ChartGeometry

log = logging.getLogger(__name__)

COARSE_SIZE = 640            # the search runs on the image block-averaged to at most this many pixels across
MIN_EXTENT = 0.12            # the chart's patch area spans at least this fraction of the frame along each axis
MIN_PATCH_PX = 3.0           # below this many pixels a patch cannot be sampled
EDGE_POINTS = (0.25, 0.5, 0.75)      # where along each patch edge the refinement looks
SEARCH_BINS = 200            # the 1-D search runs on edge profiles summed into at most this many bins
SHIFTS = (0, -1, 1, -2, 2, -3, 3)   # patch pitches a coarse match may be off (periodic rows of patches)
MIN_CONTRAST = 1.5           # patch edges at least this much sharper than patch centres (a chart: 2 to hundreds)
MIN_EDGE_SCORE = 0.6         # the matched edges must stand this many sd above the profile around them


@dataclass
class AxisFit:
    """A 1-D match of the chart's edges: chart coordinate ``x`` (from the patch area's start, 0..extent) lies at
    profile position ``offset + scale * (extent - x if flip else x)``."""

    scale: float
    offset: float
    flip: bool
    score: float


def luminance(image: np.ndarray) -> np.ndarray:
    """(H, W) log luminance for edge finding: each channel over its 99th percentile, averaged, log (floor 1e-3);
    pixels without data (NaN) take the median."""
    img = np.asarray(image, dtype=float)
    img = img if img.ndim == 3 else img[..., None]
    chans = []
    for c in range(img.shape[2]):
        ch = img[..., c]
        finite = ch[np.isfinite(ch)]
        top = float(np.percentile(finite, 99)) if finite.size else 0.0
        chans.append(ch / top if top > 0 else np.zeros_like(ch))
    with np.errstate(invalid="ignore"):
        lum = np.log(np.clip(np.mean(chans, axis=0), 1e-3, None))
    bad = ~np.isfinite(lum)
    if bad.any():
        lum[bad] = float(np.median(lum[~bad])) if (~bad).any() else 0.0
    return lum


def block_mean(img: np.ndarray, factor: int) -> np.ndarray:
    """Mean over ``factor`` x ``factor`` blocks (the edge rows and columns that do not fill a block dropped)."""
    if factor <= 1:
        return img
    h, w = img.shape[0] // factor * factor, img.shape[1] // factor * factor
    return img[:h, :w].reshape(h // factor, factor, w // factor, factor).mean(axis=(1, 3))


def gradients(lum: np.ndarray, sigma: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Sobel x and y derivatives of the Gaussian-smoothed luminance."""
    g = ndimage.gaussian_filter(lum, sigma)
    return ndimage.sobel(g, axis=1), ndimage.sobel(g, axis=0)


def dominant_angle(gx: np.ndarray, gy: np.ndarray) -> float:
    """The edges' direction modulo 90 degrees, in [-45, 45): the peak of the strongest 10 % of gradient directions
    (weighted by magnitude), refined by their circular mean (angles x 4 on the unit circle) near the peak."""
    mag = np.hypot(gx, gy)
    strong = mag > np.percentile(mag, 90)
    ang = np.degrees(np.arctan2(gy[strong], gx[strong])) % 90.0
    w = mag[strong]
    hist, _ = np.histogram(ang, bins=360, range=(0.0, 90.0), weights=w)
    hist = ndimage.gaussian_filter1d(hist, 2.0, mode="wrap")
    peak = (np.argmax(hist) + 0.5) * 0.25
    near = np.abs((ang - peak + 45.0) % 90.0 - 45.0) < 4.0
    z = np.sum(w[near] * np.exp(4j * np.radians(ang[near])))
    a = math.degrees(np.angle(z)) / 4.0 if abs(z) > 0 else peak
    return (a + 45.0) % 90.0 - 45.0


def _sharpness(x: np.ndarray, y: np.ndarray, gx: np.ndarray, gy: np.ndarray, angle_deg: float) -> float:
    """How sharply the gradient (gx, gy at points x, y) projected onto the axes turned by ``angle_deg`` peaks:
    sum(P^2) / sum(P)^2 of both one-pixel-bin profiles (a chart's edges pile up in few bins at its true angle)."""
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    out = 0.0
    for coord, weight in ((x * c + y * s, np.abs(gx * c + gy * s)), (y * c - x * s, np.abs(gy * c - gx * s))):
        p = np.bincount((coord - coord.min()).astype(int), weight)
        out += float(np.sum(p ** 2) / np.sum(p) ** 2)
    return out


def chart_angle(gx: np.ndarray, gy: np.ndarray) -> float:
    """The chart's rotation modulo 90 degrees, in [-45, 45): around the peak of the gradient directions
    (:func:`dominant_angle`; a pixel staircase biases it towards the pixel grid) the angle whose edge profiles are
    sharpest (over the strongest fifth of the gradients), searched in 0.25 then 0.02 degree steps."""
    mag = np.hypot(gx, gy)
    y, x = np.nonzero(mag > np.percentile(mag, 80))
    sx, sy = gx[y, x], gy[y, x]
    xf, yf = x.astype(float), y.astype(float)
    best = dominant_angle(gx, gy)
    for half, step in ((6.0, 0.25), (0.3, 0.02)):
        angles = best + np.arange(-half, half + step / 2, step)
        best = float(angles[int(np.argmax([_sharpness(xf, yf, sx, sy, a) for a in angles]))])
    return (best + 45.0) % 90.0 - 45.0


def edge_profiles(gx: np.ndarray, gy: np.ndarray, angle_deg: float) -> tuple[np.ndarray, float, np.ndarray, float]:
    """The gradient projected on the axes turned by ``angle_deg``: (profile along u, u of its bin 0, profile along
    v, v of its bin 0); u = x cos a + y sin a, v = -x sin a + y cos a, bins of one pixel, linear interpolation."""
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    yy, xx = np.indices(gx.shape, dtype=float)
    out: list[tuple[np.ndarray, float]] = []
    for coord, weight in ((xx * c + yy * s, np.abs(gx * c + gy * s)), (-xx * s + yy * c, np.abs(-gx * s + gy * c))):
        lo = float(coord.min())
        pos = (coord - lo).ravel()
        i = np.floor(pos).astype(int)
        f = pos - i
        wv = weight.ravel()
        n = int(i.max()) + 2
        out.append((np.bincount(i, wv * (1 - f), n) + np.bincount(i + 1, wv * f, n), lo))
    (pu, u0), (pv, v0) = out
    return pu, u0, pv, v0


def _interp(profile: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Linear interpolation of ``profile`` at ``pos`` (0 outside)."""
    return np.interp(pos, np.arange(len(profile)), profile, left=0.0, right=0.0)


def _search(prof: np.ndarray, e: np.ndarray, w: np.ndarray, scales: np.ndarray, margin: float
            ) -> tuple[float, float, float]:
    """The grid search of :func:`fit_axis` in one direction: (z score, scale, offset) of the best match."""
    n = len(prof)
    extent = float(e.max())
    c1, c2 = np.r_[0.0, np.cumsum(prof)], np.r_[0.0, np.cumsum(prof ** 2)]
    best = (-np.inf, 0.0, 0.0)
    for s in scales:
        span = int(math.floor(n - 1 - s * extent))
        if span < 1:
            continue
        o = np.arange(span)
        pos = o[:, None] + s * e[None, :]
        i = pos.astype(int)
        f = pos - i
        at_edges = (prof[i] * (1 - f) + prof[np.minimum(i + 1, n - 1)] * f) @ w
        a = np.clip(np.floor(o - s * margin), 0, n).astype(int)
        b = np.clip(np.ceil(o + s * (extent + margin)) + 1, 0, n).astype(int)
        mean = (c1[b] - c1[a]) / (b - a)
        sd = np.sqrt(np.maximum((c2[b] - c2[a]) / (b - a) - mean ** 2, 1e-12))
        z = (at_edges - mean) / sd
        k = int(np.argmax(z))
        if z[k] > best[0]:
            best = (float(z[k]), float(s), float(k))
    return best


def fit_axis(profile: np.ndarray, edges: np.ndarray, weights: np.ndarray, scale_range: tuple[float, float],
             margin: float) -> list[AxisFit]:
    """Every scale (steps moving the far edge half a bin) and offset (one bin) in ``scale_range``, both directions,
    scored by how far the profile at the chart's edges stands above the profile around them: (mean at the edges -
    mean in the window) / sd in the window, the window reaching ``margin`` (chart units, one patch pitch) past the
    outermost edges, so a match a pitch off, which leaves a real edge unexplained beside it, scores lower. The
    search runs on the profile summed into at most :data:`SEARCH_BINS` bins; the best fit per direction is then
    refined on the whole profile to a tenth of a bin (Nelder-Mead on the mean at the edges)."""
    prof = ndimage.gaussian_filter1d(np.asarray(profile, dtype=float), 1.0)
    e = np.asarray(edges, dtype=float) - float(np.min(edges))
    extent = float(e.max())
    w = np.asarray(weights, dtype=float) / float(np.sum(weights))
    d = max(1, int(math.ceil(len(prof) / SEARCH_BINS)))
    small = prof[:len(prof) // d * d].reshape(-1, d).sum(axis=1)
    lo, hi = scale_range[0] / d, scale_range[1] / d
    steps = max(int(math.ceil(math.log(hi / lo) / math.log1p(0.5 / max(hi * extent, 1.0)))), 2)
    scales = lo * (hi / lo) ** (np.arange(steps + 1) / steps)
    fits = []
    for flip in (False, True):
        ef = extent - e if flip else e
        z, sc, off = _search(small, ef, w, scales, margin)
        if not np.isfinite(z):
            continue
        s0, o0 = sc * d, off * d + (d - 1) / 2

        def score(p: np.ndarray, ef: np.ndarray = ef) -> float:
            return -float(_interp(prof, p[1] + p[0] * ef) @ w)
        res = optimize.minimize(score, np.array([s0, o0]), method="Nelder-Mead",
                                bounds=[(0.97 * s0, 1.03 * s0), (o0 - 2 * d, o0 + 2 * d)],
                                options={"xatol": 0.02, "fatol": 1e-9, "initial_simplex":
                                         np.array([[s0, o0], [s0 * 1.004, o0], [s0, o0 + 0.7]])})
        fits.append(AxisFit(float(res.x[0]), float(res.x[1]), flip, z))
    return fits


@dataclass
class Candidate:
    """One way the chart may lie: its patch grid, how well its edges matched, whether it is seen mirrored."""

    grid: PatchGrid
    edge_score: float
    mirrored: bool


def _normalised(profile: np.ndarray) -> np.ndarray:
    inside = profile[profile > 0]
    return profile / float(np.mean(inside)) if inside.size else profile


def _axis_pairs(pu: np.ndarray, pv: np.ndarray, geometry: ChartGeometry) -> list[tuple[bool, list[AxisFit],
                                                                                        list[AxisFit]]]:
    """For both assignments (chart x along u, or along v): the fits of the x and the y edges, the first axis
    searched freely and the other at a scale within 15 % of it (square pixels, a little tilt), whichever of the
    two orders matches better."""
    ex, wx = geometry.edges(0)
    ey, wy = geometry.edges(1)
    mx, my = geometry.blocks[0].step
    out = []
    for swap in (False, True):
        px, py = (pv, pu) if swap else (pu, pv)
        best: tuple[float, list[AxisFit], list[AxisFit]] | None = None
        for first in ("x", "y"):
            (pa, ea, wa, ma), (pb, eb, wb, mb) = (((px, ex, wx, mx), (py, ey, wy, my)) if first == "x"
                                                  else ((py, ey, wy, my), (px, ex, wx, mx)))
            span = float(np.ptp(ea))
            fa = fit_axis(pa, ea, wa, (MIN_EXTENT * len(pa) / span, len(pa) / span), ma)
            if not fa:
                continue
            s = max(fa, key=lambda f: f.score).scale
            fb = fit_axis(pb, eb, wb, (0.85 * s, 1.15 * s), mb)
            if not fb:
                continue
            total = max(f.score for f in fa) + max(f.score for f in fb)
            fits_x, fits_y = (fa, fb) if first == "x" else (fb, fa)
            if best is None or total > best[0]:
                best = (total, fits_x, fits_y)
        if best is not None:
            out.append((swap, best[1], best[2]))
    return out


def _corners(geometry: ChartGeometry, fx: AxisFit, fy: AxisFit, swap: bool, angle: float,
             origins: tuple[float, float], factor: int) -> np.ndarray:
    """The patch area's corners (TL, TR, BR, BL of the chart) in the searched image's x, y from two axis fits
    made on it block-averaged by ``factor``."""
    x0, y0, x1, y1 = geometry.patch_area
    ex, ey = x1 - x0, y1 - y0
    pts = []
    r = math.radians(angle)
    for cx, cy in ((0.0, 0.0), (ex, 0.0), (ex, ey), (0.0, ey)):
        a = fx.offset + fx.scale * (ex - cx if fx.flip else cx)
        b = fy.offset + fy.scale * (ey - cy if fy.flip else cy)
        u, v = (b, a) if swap else (a, b)
        u, v = u + origins[0], v + origins[1]
        pts.append((u * math.cos(r) - v * math.sin(r), u * math.sin(r) + v * math.cos(r)))
    return (np.asarray(pts) + 0.5) * factor - 0.5


def _shifted(fit: AxisFit, pitch: float, k: int) -> AxisFit:
    return AxisFit(fit.scale, fit.offset + k * pitch * fit.scale, fit.flip, fit.score)


def coarse_candidates(lum: np.ndarray, geometry: ChartGeometry, shifts: bool = False) -> list[Candidate]:
    """The search of steps 1-4 (module docstring) on the luminance block-averaged to at most :data:`COARSE_SIZE`
    pixels: every orientation the edges allow (within 10 % of the best match), its corners in ``lum``'s x, y; with
    ``shifts`` also each moved by up to :data:`SHIFTS` patch pitches along either axis (a row of patches much like
    the chart's border, or an IT8's contiguous patches, match the edges nearly as well a pitch or two off: the
    reference decides)."""
    factor = max(1, int(math.ceil(max(lum.shape) / COARSE_SIZE)))
    gx, gy = gradients(block_mean(lum, factor))
    angle = chart_angle(gx, gy)
    pu, u0, pv, v0 = edge_profiles(gx, gy, angle)
    pairs = _axis_pairs(_normalised(pu), _normalised(pv), geometry)
    if not pairs:
        return []
    best_total = max(max(f.score for f in fx) + max(f.score for f in fy) for _, fx, fy in pairs)
    out = []
    step = geometry.blocks[0].step
    moves = [(i, j) for i in SHIFTS for j in SHIFTS] if shifts else [(0, 0)]
    for swap, fits_x, fits_y in pairs:
        for fx in fits_x:
            for fy in fits_y:
                total = fx.score + fy.score
                if total < 0.9 * best_total or min(fx.score, fy.score) < MIN_EDGE_SCORE:
                    continue
                mirrored = (fx.flip != fy.flip) != swap
                for i, j in moves:
                    corners = _corners(geometry, _shifted(fx, step[0], i), _shifted(fy, step[1], j), swap, angle,
                                       (u0, v0), factor)
                    try:
                        out.append(Candidate(grid_on(corners, geometry), total * (1 - 0.01 * (abs(i) + abs(j))),
                                             mirrored))
                    except ValueError:
                        continue
    log.debug("chart search: angle %.2f deg, %d candidate placements", angle, len(out))
    return out


def _edge_points(geometry: ChartGeometry) -> np.ndarray:
    """(m, 2) points along every patch edge, in the patch area's unit square."""
    x0, y0, x1, y1 = geometry.patch_area
    b = geometry.boxes
    u0, u1 = (b[:, 0] - x0) / (x1 - x0), (b[:, 2] - x0) / (x1 - x0)
    v0, v1 = (b[:, 1] - y0) / (y1 - y0), (b[:, 3] - y0) / (y1 - y0)
    pts = []
    for t in EDGE_POINTS:
        along_u, along_v = u0 + t * (u1 - u0), v0 + t * (v1 - v0)
        pts += [np.c_[u0, along_v], np.c_[u1, along_v], np.c_[along_u, v0], np.c_[along_u, v1]]
    return np.vstack(pts)


def refine(grid: PatchGrid, geometry: ChartGeometry, lum: np.ndarray, sigma: float = 1.0
           ) -> tuple[PatchGrid, float]:
    """Step 5: the corners moved (Powell, 8 parameters) to maximise the smoothed gradient's magnitude along every
    patch edge; with the edge contrast there: the mean magnitude on the patch edges over the mean at the patch
    centres (hundreds on a chart, about 1 where there is none)."""
    gx, gy = gradients(lum, sigma)
    mag = np.hypot(gx, gy)
    uv1 = np.c_[_edge_points(geometry), np.ones(len(_edge_points(geometry)))]
    unit = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    start = grid.corners.copy()

    def at(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
        q = pts @ h.T
        xy = q[:, :2] / q[:, 2:3]
        return ndimage.map_coordinates(mag, [xy[:, 1], xy[:, 0]], order=1, mode="constant")

    def cost(p: np.ndarray) -> float:
        return -float(at(homography(unit, start + p.reshape(4, 2)), uv1).mean())
    res = optimize.minimize(cost, np.zeros(8), method="Powell", options={"xtol": 0.05, "ftol": 1e-5})
    try:
        out = PatchGrid(start + res.x.reshape(4, 2), grid.rows, grid.cols, grid.fraction,
                        cell_boxes=grid.cell_boxes)
    except ValueError:
        out = grid
    x0, y0, x1, y1 = geometry.patch_area
    c = geometry.centres()
    inner = np.c_[(c[:, 0] - x0) / (x1 - x0), (c[:, 1] - y0) / (y1 - y0), np.ones(len(c))]
    h = homography(unit, out.corners)
    contrast = float(at(h, uv1).mean()) / max(float(at(h, inner).mean()), 1e-12)
    return out, contrast


def quick_values(grid: PatchGrid, image: np.ndarray, cells: Sequence[int]) -> np.ndarray:
    """(len(cells), C) each cell's value from five points (its centre and four at a fifth of its size around it,
    bilinear): enough to rank candidate placements, far faster than PatchGrid.sample."""
    img = image if image.ndim == 3 else image[..., None]
    b = grid.boxes()[list(cells)]
    cu, cv = (b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2
    du, dv = (b[:, 2] - b[:, 0]) / 5, (b[:, 3] - b[:, 1]) / 5
    uv = np.vstack([np.c_[cu + a * du, cv + c * dv] for a, c in ((0, 0), (-1, -1), (1, -1), (1, 1), (-1, 1))])
    xy = grid.to_image(uv)
    out = np.stack([ndimage.map_coordinates(np.nan_to_num(img[..., k]), [xy[:, 1], xy[:, 0]], order=1,
                                            mode="constant", cval=np.nan) for k in range(img.shape[2])], axis=1)
    return out.reshape(5, len(cells), img.shape[2]).mean(axis=0)


def _ranked_residual(grid: PatchGrid, image: np.ndarray, reference: np.ndarray, cells: Sequence[int]) -> float:
    """The reference fit's residual (app.processing.placement.fit_residual) of a candidate placement from
    :func:`quick_values`; infinite when a tenth of its patches fall outside the image (a fit on the few left
    would look good by chance)."""
    from dualrgb.app.processing.placement import fit_residual

    values = quick_values(grid, image, cells)
    if np.isfinite(values).all(axis=1).mean() < 0.9:
        return float("inf")
    r = fit_residual(values, reference)
    return r if np.isfinite(r) else float("inf")


def _upright(grid: PatchGrid) -> float:
    """How square to the frame a grid lies: the cosine between its top edge and the image's x axis."""
    d = grid.corners[1] - grid.corners[0]
    return float(d[0] / (np.hypot(*d) or 1.0))


def _choose(cands: list[Candidate], image: np.ndarray, reference: np.ndarray | None, cells: Sequence[int] | None,
            what: str) -> Candidate:
    """Step 6: the placement whose values fit the reference best (a mirrored best refused); without a reference
    the best edge match among the unmirrored, the most upright of equals."""
    if reference is not None and cells is not None:
        res = np.array([_ranked_residual(c.grid, image, reference, cells) for c in cands])
        best = cands[int(np.argmin(res))]
        if best.mirrored:
            raise ChartNotFound(f"{what} is seen mirrored (its patches match the reference only read from the other "
                                "side): turn it over on the stand")
        return best
    plain = [c for c in cands if not c.mirrored] or cands
    top = max(c.edge_score for c in plain)
    return max((c for c in plain if c.edge_score >= 0.98 * top), key=lambda c: _upright(c.grid))


def _rescaled(grid: PatchGrid, factor: float) -> PatchGrid:
    """The grid with its corners in an image ``factor`` times the size (pixel centres at integer coordinates)."""
    return PatchGrid((grid.corners + 0.5) * factor - 0.5, grid.rows, grid.cols, grid.fraction,
                     cell_boxes=grid.cell_boxes)


def _own_search(img: np.ndarray, geometry: ChartGeometry, reference: np.ndarray | None,
                cells: Sequence[int] | None, what: str) -> PatchGrid:
    """Steps 1-6 (module docstring) on ``img``; a small image is searched repeated ``up`` times in each direction
    (as many as fit :data:`COARSE_SIZE`), so its one-pixel gaps survive the smoothing."""
    lum = luminance(img)
    up = max(1, COARSE_SIZE // max(lum.shape))
    fine = np.repeat(np.repeat(lum, up, axis=0), up, axis=1) if up > 1 else lum
    cands = [Candidate(_rescaled(c.grid, 1 / up), c.edge_score, c.mirrored)
             for c in coarse_candidates(fine, geometry, shifts=reference is not None and cells is not None)]
    if not cands:
        raise ChartNotFound(f"{what} is not in the frame (no match of its patch edges stands out); check the "
                            "frame and the chart's layout, or place its corners by hand (--train-corners / "
                            "--test-corners)")
    grid = _rescaled(_choose(cands, img, reference, cells, what).grid, up)
    down = max(1, int(math.ceil(max(fine.shape) / COARSE_SIZE)))
    if down > 1:
        grid, _ = refine(grid, geometry, fine, sigma=0.8 * down)
    grid, contrast = refine(grid, geometry, fine)
    if contrast < MIN_CONTRAST:
        raise ChartNotFound(f"{what} is not in the frame (the best match's patch edges are only {contrast:.1f} times "
                            f"as sharp as its patches' insides; a chart's are over {MIN_CONTRAST:g}); check the frame "
                            "and the chart's layout, or place its corners by hand (--train-corners / --test-corners)")
    return _rescaled(grid, 1 / up)


def _by_scanin(img: np.ndarray, geometry: ChartGeometry, reference: np.ndarray | None,
               cells: Sequence[int] | None, what: str) -> PatchGrid | None:
    """ArgyllCMS scanin's find (app.processing.scanin), turned the way the reference fits best; None when scanin
    is not installed, has no template for the chart or finds nothing."""
    from dualrgb.app.processing.scanin import ScaninUnavailable, scanin_grid

    try:
        g = scanin_grid(img, geometry)
    except (ScaninUnavailable, ChartNotFound) as exc:
        log.info("%s: no second opinion from scanin (%s)", what, exc)
        return None
    orders = {(0, 1, 2, 3): False, (2, 3, 0, 1): False, (1, 0, 3, 2): True, (3, 2, 1, 0): True}
    cands = [Candidate(PatchGrid(g.corners[list(o)], g.rows, g.cols, g.fraction, cell_boxes=g.cell_boxes), 1.0, m)
             for o, m in orders.items()]
    return _choose(cands if reference is not None else cands[:1], img, reference, cells, what).grid


def detect_chart(image: np.ndarray, geometry: ChartGeometry, *, reference: np.ndarray | None = None,
                 cells: Sequence[int] | None = None, fraction: float = 0.5, label: str = "") -> PatchGrid:
    """The patch grid of the chart ``geometry`` describes, found in ``image`` (module docstring); ``reference``
    (len(cells), 3) the XYZ of the chart's patches in grid cells ``cells`` (decides which way up); raises
    :class:`ChartNotFound` (one line) when it is not there. Where the own search finds nothing ArgyllCMS scanin
    is asked (when installed and it has a template for the chart)."""
    rows, cols = geometry.layout
    what = f"{label + ': ' if label else ''}the {geometry.name} chart ({rows}x{cols}, {geometry.count} patches)"
    img = np.asarray(image, dtype=float)
    if img.ndim not in (2, 3) or min(img.shape[:2]) < 16:
        raise ChartNotFound(f"{what}: an image of shape {img.shape} is too small to search")
    try:
        grid = _own_search(img, geometry, reference, cells, what)
    except ChartNotFound as own:
        found = None if "mirrored" in str(own) else _by_scanin(img, geometry, reference, cells, what)
        if found is None:
            raise
        log.info("%s: found by ArgyllCMS scanin (the own search: %s)", what, own)
        grid = found
    x0, y0, x1, y1 = geometry.patch_area
    side = min(np.linalg.norm(grid.corners[1] - grid.corners[0]) / (x1 - x0),
               np.linalg.norm(grid.corners[3] - grid.corners[0]) / (y1 - y0))
    smallest = side * min(min(b.size) for b in geometry.blocks)
    if smallest < MIN_PATCH_PX:
        raise ChartNotFound(f"{what}: found, but its patches are {smallest:.1f} px across (at least {MIN_PATCH_PX:g} "
                            "needed): frame the chart larger")
    log.info("%s found: corners %s", what, np.round(grid.corners, 1).tolist())
    return PatchGrid(grid.corners, rows, cols, fraction, cell_boxes=grid.cell_boxes)
