"""Access copies of a delivery, made from its sRGB master when the delivery settings ask for them
(app.workflow.delivery.delivery_settings):

* ``<id>_access.jp2``: JPEG 2000 (JP2 file format), lossless (reversible 5/3 wavelet), 16-bit sRGB, with
  resolution levels down to about 256 pixels and 512 x 512 tiles (so a viewer reads any region and level without
  decoding the whole image), through OpenJPEG (the reference codec) as imagecodecs binds it. The colour space is the
  enumerated sRGB of the JP2 ``colr`` box.
* ``<id>_access_pyramid.tif``: a tiled (256 x 256), multi-resolution TIFF of the sRGB master at 8 bits, each level
  half the one before down to a tile, JPEG-compressed tiles (quality 90), the sRGB ICC profile and the master's
  XMP in the full-resolution page. The levels are successive IFDs (NewSubfileType 1 after the first): the layout
  IIPImage and Cantaloupe serve as a pyramid (and GDAL reads as overviews). Being tiled and compressed it is not a
  baseline TIFF (SLUB's checkit_tiff baseline refuses tiles and compression): it is an access copy, not a master.

Both are read from the finished sRGB master (memory-mapped: the whole image is in memory once for the JPEG 2000
encoder, 8 bits for the pyramid) and get their fixity like every other file.
"""
from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from dualrgb.app.processing.outputs import RESOLUTION_UNIT_INCH, icc_profile
from dualrgb.app.workflow.delivery.deliverables import Deliverable
from dualrgb.app.workflow.delivery.master_metadata import MasterContext
from dualrgb.common.atomic_files import atomic_output

log = logging.getLogger(__name__)

TILE = 256
JPEG_QUALITY = 90


def make_access_copy(im: Deliverable, srgb: Path, ctx: MasterContext) -> Path:
    """Write access copy ``im`` (its ``space``: 'jp2' or 'pyramid') from the sRGB master ``srgb``."""
    import tifffile

    image = tifffile.memmap(srgb, mode="r")
    try:
        if im.space == "jp2":
            return _jp2(im.path, np.asarray(image))
        if im.space == "pyramid":
            return _pyramid(im, image, ctx)
    finally:
        del image
    raise ValueError(f"{im.path.name}: unknown access copy {im.space!r}")


def levels_below(height: int, width: int, smallest: int) -> int:
    """How many halvings bring the larger side of ``height`` x ``width`` to ``smallest`` or less."""
    n = 0
    side = max(height, width)
    while side > smallest:
        side = -(-side // 2)
        n += 1
    return n


def _jp2(path: Path, image: np.ndarray) -> Path:
    import imagecodecs

    h, w = image.shape[:2]
    resolutions = min(levels_below(h, w, TILE) + 1, 8)
    data = imagecodecs.jpeg2k_encode(np.ascontiguousarray(image), level=0, codecformat="jp2",
                                     colorspace=imagecodecs.JPEG2K.CLRSPC.SRGB, reversible=True,
                                     resolutions=resolutions, numthreads=min(os.cpu_count() or 1, 8))
    with atomic_output(path, "wb") as fh:
        fh.write(data)
    return path


def halve(image: np.ndarray) -> np.ndarray:
    """A 2x2 box average (an odd last row or column is averaged with itself), uint8 rounded."""
    a = image.astype(np.uint16)
    if a.shape[0] % 2:
        a = np.concatenate([a, a[-1:]], axis=0)
    if a.shape[1] % 2:
        a = np.concatenate([a, a[:, -1:]], axis=1)
    s = a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]
    return ((s + 2) // 4).astype(np.uint8)


def _pyramid(im: Deliverable, image: np.ndarray, ctx: MasterContext) -> Path:
    import tifffile

    level = np.empty(image.shape, np.uint8)
    for r0 in range(0, image.shape[0], 256):                         # 16 -> 8 bits, a band at a time
        band = image[r0: r0 + 256].astype(np.uint32)
        level[r0: r0 + 256] = ((band + 128) // 257).astype(np.uint8)
    meta = ctx.meta(im)
    ppi = float(ctx.ppi or 1.0)                  # no sampling known: 1 pixel per inch, as TIFF's default says
    height, width = int(image.shape[0]), int(image.shape[1])
    with atomic_output(im.path, "wb") as fh, tifffile.TiffWriter(fh) as tif:
        n = levels_below(height, width, TILE)
        for i in range(n + 1):
            first = i == 0
            tif.write(level, photometric="rgb", tile=(TILE, TILE), compression="jpeg",
                      compressionargs={"level": JPEG_QUALITY, "outcolorspace": "rgb"},
                      subfiletype=0 if first else 1, metadata=None, software=meta.software,
                      description=meta.description if first else None,
                      iccprofile=icc_profile("sRGB") if first else None,
                      extratags=[(700, "B", len(meta.xmp), meta.xmp, True)] if first else None,
                      resolution=(ppi / 2 ** i, ppi / 2 ** i), resolutionunit=RESOLUTION_UNIT_INCH)
            if i < n:
                level = halve(level)
    return im.path
