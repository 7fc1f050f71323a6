"""Demosaicing for the full-resolution masters: Malvar-He-Cutler (2004) linear interpolation of a Bayer mosaic.

Why this method. An archival master must stay linear in scene radiance (the characterisation matrix and the
spectral map are linear maps of the channels): a demosaic that is one fixed linear filter per CFA position keeps
it so, exactly, at every signal level, where edge-directed methods (AHD, PPG, DCB, ...) choose their filter from
the image and are only piecewise linear. Among linear methods Malvar-He-Cutler is the one of least error for its
cost: bilinear interpolation corrected by the Laplacian of the pixel's own channel (gains fitted on the Kodak set),
5x5 support, ~1.5 dB better than bilinear in the paper, and the "LINEAR" of no raw developer (LibRaw's
``demosaic_algorithm=LINEAR`` is plain bilinear). Here it runs on the flat-fielded, HDR-merged mosaic of each light
(app.processing.masters): after eq 7.1 every channel is relative to the white (1.0 = the white / open gate), so
the channels are balanced as the method's cross-channel Laplacian assumes, and the HDR weights and the clipping
act on the photosites they concern (demosaicing each raw exposure first would mix clipped and unclipped
photosites into one estimate). The per-pixel figures against the virtual originals' truth, flat regions and
edges apart, are in docs/notes/issue-31.md.

Borders: the mosaic is mirrored about its first and last row and column without repeating them (numpy's
``reflect``, scipy.ndimage's ``mirror``), which keeps the CFA phase, so every pixel, the border ones included,
gets the same filter as in the interior. NaN (no usable flat field) spreads to the pixels whose 5x5 support
holds it: their channels become NaN (invalid, 0 in the TIFFs, counted on the QA line), never a guess.

Why hand-written: colour-demosaicing (the test reference) convolves the whole frame four times with scipy and
selects with masks: ~30 full-frame float64 temporaries, 3 GB for 24 MP. One numba pass per row computes each
pixel's two missing channels from the band in cache into channel planes (:func:`mhc_planes`): the delivery
encodes them while they are in the cache (app.processing.encode.DeliveryEncoder.encode_mosaic), and
:func:`demosaic_rows` interleaves them into N-channel bands; the tests check both against
``colour_demosaicing.demosaicing_CFA_Bayer_Malvar2004`` over whole frames, borders included.

References
----------
Malvar, He, Cutler (2004), "High-quality linear interpolation for demosaicing of Bayer-patterned color images",
IEEE ICASSP 2004, vol. 3, pp. 485-488.
"""
from __future__ import annotations

import logging

import numpy as np
from numba import njit

from dualrgb.app.processing.mosaic import cfa_channel_index

log = logging.getLogger(__name__)

HALO = 2                      # rows / columns of support on each side of a pixel (5x5 filters)
DEMOSAIC = ("Malvar-He-Cutler (2004) linear demosaic of each light's flat-fielded HDR mosaic, mirrored borders")
GREEN = 1


@njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _stencils(r0, r1, r2, r3, r4, j):  # pragma: no cover - compiled
    """The four Malvar-He-Cutler filters at padded column ``j`` of padded rows r0..r4 (r2 the pixel's row): G at
    an R or B photosite, the horizontal neighbours' colour at a G one, the vertical neighbours' colour at a G one,
    the diagonal neighbours' colour at an R or B one."""
    c = r2[j]
    eighth = np.float32(0.125)
    ax1 = r1[j] + r3[j] + r2[j - 1] + r2[j + 1]
    ax2h = r2[j - 2] + r2[j + 2]
    ax2v = r0[j] + r4[j]
    diag = r1[j - 1] + r1[j + 1] + r3[j - 1] + r3[j + 1]
    g = (np.float32(4.0) * c + np.float32(2.0) * ax1 - ax2h - ax2v) * eighth
    h = (np.float32(5.0) * c + np.float32(4.0) * (r2[j - 1] + r2[j + 1]) - ax2h - diag
         + np.float32(0.5) * ax2v) * eighth
    v = (np.float32(5.0) * c + np.float32(4.0) * (r1[j] + r3[j]) - ax2v - diag + np.float32(0.5) * ax2h) * eighth
    d = (np.float32(6.0) * c + np.float32(2.0) * diag - np.float32(1.5) * (ax2h + ax2v)) * eighth
    return c, g, h, v, d


@njit(nogil=True, cache=True, error_model="numpy")
def mhc_planes(P, p, even_green, here, S):  # pragma: no cover - compiled
    """One row into planes: padded band ``P`` (rows, W + 4), the pixel row at ``P[p]``; ``even_green``: the
    row's even columns are green; ``here``: the row's other colour (0 = R, 2 = B). Writes the row's R, G, B into
    ``S[0]``, ``S[1]``, ``S[2]`` (3, >= W). Planar rows (one contiguous store per channel, the CFA position a
    select) let LLVM vectorise the loop; with the pixel-interleaved N-channel stores of before it stayed scalar
    (both lights of a 24 MP frame: 0.085 CPU-s into planes, 0.23 into the interleaved band)."""
    W = P.shape[1] - 2 * HALO
    r0 = P[p - 2]
    r1 = P[p - 1]
    r2 = P[p]
    r3 = P[p + 1]
    r4 = P[p + 2]
    sg = S[GREEN]
    sh = S[here]
    so = S[2 - here]
    odd = 0 if even_green else 1
    for x in range(W):
        c, g, h, v, d = _stencils(r0, r1, r2, r3, r4, x + HALO)
        green = (x & 1) == odd
        sg[x] = c if green else g
        sh[x] = h if green else c
        so[x] = v if green else d


@njit(nogil=True, cache=True, error_model="numpy")
def row_colours(cfa, y):  # pragma: no cover - compiled
    """(even_green, here) of image row ``y`` for ``cfa`` (2, 2) channel indices of the top-left cell: whether
    the row's even columns are green, and the row's other colour (0 = R, 2 = B)."""
    par = y % 2
    even_green = cfa[par, 0] == GREEN
    return even_green, (cfa[par, 1] if even_green else cfa[par, 0])


@njit(nogil=True, cache=True, error_model="numpy")
def demosaic_rows(P, p0, y0, cfa, out, a, b, base):  # pragma: no cover - compiled
    """Rows ``a`` .. ``b`` of ``out`` (rows, W, C): channels ``base`` .. ``base + 2`` demosaiced from the padded
    band ``P`` whose row ``p0 + r`` holds image row ``y0 + r`` (HALO mirrored rows and columns around);
    ``cfa`` (2, 2) channel indices (0 = R, 1 = G, 2 = B) of the image's top-left cell."""
    W = out.shape[1]
    S = np.empty((3, W), np.float32)
    for r in range(a, b):
        even_green, here = row_colours(cfa, y0 + r)
        mhc_planes(P, p0 + r, even_green, here, S)
        o = out[r]
        for x in range(W):
            for c in range(3):
                o[x, base + c] = S[c, x]


def mirror_pad(mosaic: np.ndarray) -> np.ndarray:
    """``mosaic`` with HALO rows and columns mirrored around it (the CFA phase kept): the padded band of a whole
    frame, for :func:`demosaic` and the tests."""
    return np.pad(np.asarray(mosaic, np.float32), HALO, mode="reflect")


def demosaic(mosaic: np.ndarray, cfa: str = "RGGB") -> np.ndarray:
    """(H, W, 3) float32 R, G, B of a whole (H, W) mosaic (at least 3 x 3): the kernel on one band."""
    mosaic = np.asarray(mosaic, np.float32)
    if mosaic.ndim != 2 or min(mosaic.shape) < HALO + 1:
        raise ValueError(f"mosaic of shape {mosaic.shape}: expected 2-D, at least {HALO + 1} x {HALO + 1}")
    out = np.empty(mosaic.shape + (3,), np.float32)
    demosaic_rows(mirror_pad(mosaic), HALO, 0, cfa_channel_index(cfa), out, 0, mosaic.shape[0], 0)
    return out
