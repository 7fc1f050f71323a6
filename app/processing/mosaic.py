"""Bayer-mosaic helpers shared by the processing steps (numpy only, no demosaicing).

Every calibration step (dark subtraction, eq 7.1 flat field, eq 8.9 HDR merge) is a per-pixel operation, so
it runs on the raw mosaic itself: each pixel is processed with the dark/white values of the same pixel, i.e.
of its own CFA channel. Only at the end is the mosaic reduced to a half-size "superpixel" image, one RGB value
per 2x2 cell (R, mean(G1, G2), B), which needs no interpolation and is what patch statistics and the 6-channel
(dual-RGB) stack use.

Inputs may be a ``drivers.raw.RawFrame`` (as ``drivers.raw.load_raw`` returns), a path to a raw file, or a
bare 2-D numpy mosaic (tests, virtual camera). Paths are opened with ``open_raw`` / ``iter_open_raw`` (no
copy, next file decoded in the background). numpy steps on large frames go in horizontal bands of an even
number of rows (``row_bands``) so temporaries stay small and the CFA phase is the same in every band.
"""
from __future__ import annotations

import logging
import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Union

import numpy as np

log = logging.getLogger(__name__)

DEFAULT_BAND_ROWS = 256
CFA_LETTERS = "RGB"

FrameLike = Union[np.ndarray, "os.PathLike[str]", str, Any]   # ndarray, path or drivers.raw.RawFrame


def mosaic_of(frame: FrameLike) -> np.ndarray:
    """The 2-D raw mosaic of ``frame`` (a RawFrame, a path read with drivers.raw.load_raw, or an array)."""
    if isinstance(frame, np.ndarray):
        m = frame
    elif isinstance(frame, (str, Path, os.PathLike)):   # (copies; the pipeline uses open_raw instead)
        from dualrgb.drivers.raw import load_raw

        m = load_raw(frame).mosaic
    elif hasattr(frame, "mosaic"):
        m = frame.mosaic
    else:
        raise TypeError(f"expected a raw mosaic array, a RawFrame or a path, got {type(frame).__name__}")
    if m.ndim != 2:
        raise ValueError(f"raw mosaic must be 2-D, got shape {m.shape}")
    return m


@dataclass
class RawView:
    """A raw file's mosaic as a read-only view into LibRaw's buffer: valid only inside ``open_raw``."""

    path: Path
    mosaic: np.ndarray
    white_level: int
    black_levels: tuple[int, ...]
    cfa_pattern: str


@contextmanager
def open_raw(source: FrameLike) -> Iterator[Any]:
    """Yield something with ``.mosaic`` (and, for files, white/black levels and CFA) for one use.

    For a path the mosaic is LibRaw's own buffer (no copy: a 24 MP copy costs 20-50 ms, about a third of the
    decode itself). Anything LibRaw refuses, or that is not a 2x2 RGB Bayer mosaic, is handed to
    ``drivers.raw.load_raw`` so the user gets its one-line RawFileError naming the file and the problem.
    Arrays and RawFrames are yielded as they are.
    """
    if not isinstance(source, (str, Path, os.PathLike)):
        yield source
        return
    import rawpy

    from dualrgb.drivers.raw import libraw_source, load_raw

    path = Path(source)
    try:
        raw = rawpy.imread(libraw_source(path))
    except (rawpy.LibRawError, OSError):
        load_raw(path)              # raises the descriptive RawFileError
        raise
    with raw:
        try:
            ok = raw.raw_type == rawpy.RawType.Flat and np.asarray(raw.raw_pattern).shape == (2, 2)
            desc = raw.color_desc.decode("ascii", errors="replace")
            cfa = "".join(desc[int(i)] if 0 <= int(i) < len(desc) else "?" for i in np.asarray(raw.raw_pattern).ravel())
            ok = ok and sorted(cfa) == ["B", "G", "G", "R"]
            view = RawView(path, raw.raw_image_visible, int(raw.white_level),
                           tuple(int(b) for b in raw.black_level_per_channel), cfa) if ok else None
        except rawpy.LibRawError:
            view = None
        if view is None:
            load_raw(path)          # raises the descriptive RawFileError
            raise ValueError(f"{path}: not a 2x2 RGB Bayer raw file")
        yield view


def iter_open_raw(sources: Sequence[FrameLike], *, prefetch: bool = True) -> Iterator[Any]:
    """Yield each source opened with :func:`open_raw`, in order, closing it when the caller moves on.

    With ``prefetch`` the next file is decoded in a background thread while the caller processes the current
    one (the processing kernels release the GIL), so decoding and processing overlap; at most two raw
    buffers are alive at a time.
    """
    sources = list(sources)
    if not sources:
        return
    if not prefetch or len(sources) == 1:
        for src in sources:
            with open_raw(src) as frame:
                yield frame
        return
    from concurrent.futures import Future, ThreadPoolExecutor

    def enter(src):
        cm = open_raw(src)
        return cm, cm.__enter__()

    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="raw-prefetch")
    pending: Future[tuple[Any, Any]] | None = pool.submit(enter, sources[0])
    try:
        for i in range(len(sources)):
            assert pending is not None                  # submitted for every source but the last's successor
            cm, frame = pending.result()
            pending = pool.submit(enter, sources[i + 1]) if i + 1 < len(sources) else None
            try:
                yield frame
            finally:
                cm.__exit__(None, None, None)
    finally:
        if pending is not None:           # stopped early (error, cancel): close what was prefetched
            try:
                cm, _ = pending.result()
                cm.__exit__(None, None, None)
            except Exception:  # noqa: BLE001 - the prefetched file's own error is irrelevant now
                pass
        pool.shutdown(wait=True)


def cfa_of(frame: Any, default: str = "RGGB") -> str:
    """The 2x2 CFA in raster order ('RGGB', 'BGGR', ...) of a RawFrame, else ``default``."""
    pattern = getattr(frame, "cfa_pattern", None)
    return str(pattern) if pattern else default


def white_level_of(frame: Any, default: float = 16383.0) -> float:
    w = getattr(frame, "white_level", None)
    return float(w) if w else float(default)


def check_cfa(cfa: str) -> str:
    cfa = cfa.upper()
    if len(cfa) != 4 or sorted(cfa) != ["B", "G", "G", "R"]:
        raise ValueError(f"CFA pattern {cfa!r} is not a 2x2 RGB Bayer pattern like 'RGGB'")
    return cfa


def row_bands(height: int, band_rows: int = DEFAULT_BAND_ROWS) -> Iterator[slice]:
    """Row slices covering ``height`` in bands of an even number of rows (keeps the CFA phase)."""
    band = max(2, int(band_rows) // 2 * 2)
    for start in range(0, height, band):
        yield slice(start, min(start + band, height))


def superpixel(mosaic: np.ndarray, cfa: str = "RGGB", out: np.ndarray | None = None) -> np.ndarray:
    """(H/2, W/2, 3) float32 R, (G1 + G2) / 2, B of each 2x2 cell of a processed mosaic (odd edges dropped).

    NaN in a green pixel makes that cell's G NaN (not silently the other green): invalid stays visible.
    """
    from dualrgb.drivers.raw import bayer_superpixel

    return bayer_superpixel(mosaic, check_cfa(cfa), out=out)


def cfa_channel_index(cfa: str) -> np.ndarray:
    """(2, 2) array of channel indices 0 = R, 1 = G, 2 = B for the cell."""
    cfa = check_cfa(cfa)
    return np.array([CFA_LETTERS.index(ch) for ch in cfa], dtype=np.int8).reshape(2, 2)


def mosaic_from_rgb(rgb: np.ndarray, cfa: str = "RGGB") -> np.ndarray:
    """Build a (2h, 2w) mosaic from an (h, w, 3) image (each cell gets the pixel's R, G, G, B): the inverse of
    ``superpixel`` for synthetic frames (tests, virtual camera)."""
    idx = cfa_channel_index(cfa)
    h, w, _ = rgb.shape
    out = np.empty((2 * h, 2 * w), dtype=rgb.dtype)
    for r in range(2):
        for c in range(2):
            out[r::2, c::2] = rgb[..., idx[r, c]]
    return out
