"""Dark frames and flat fielding: thesis 7 (eq 7.1) and 8.2.1 (a master dark per exposure time).

MasterDark
    One master dark per exposure time, the per-pixel mean of N lens-cap frames (thesis: 10) with outlier
    rejection. Outliers in a dark stack are *transient*: cosmic-ray hits, random-telegraph pixels that jump for
    one frame. *Persistent* hot pixels (high dark current) are real signal and are kept, so that subtracting
    the master dark removes them from the images. The rejection is a min/max-clipped mean (IRAF imcombine
    ``reject=minmax``): per pixel the ``reject_high`` largest and ``reject_low`` smallest of the N values are
    dropped and the rest averaged. Chosen over a sigma-clipped mean or a median because

      * it is exact for what it targets: a single spike per pixel per stack is removed however large it is, with
        no threshold to tune (a sigma clip needs a noise estimate per pixel, and with N = 10 the spike itself
        inflates the sample sigma it is judged against);
      * it streams: only running sums and the k largest/smallest values are kept (compare-exchange per frame),
        so N 24 MP frames need ~4 arrays of memory instead of an (N, H, W) stack, and it costs a few
        passes per frame (a per-pixel median over the stack costs more than the raw decoding itself);
      * with N = 10 and symmetric (read) noise it is unbiased, and its efficiency is ~90 % of the plain mean
        (the median's is ~72 %).

    With fewer than ``reject_low + reject_high + 2`` frames it falls back to the plain mean (logged).

FlatField (eq 7.1)
    ``img_f = (img_r - img_d) / (img_w - img_d)``. Images taken at different exposure times are first put on a
    common scale (divided by their exposure time), which reduces to eq 7.1 exactly when the times are equal.
    Pixels whose white denominator is not clearly positive (below ``min_fraction`` of the white's 99th
    percentile: dead pixels, the edge of the illuminated field) become NaN instead of dividing by ~0.
"""
from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from dualrgb.app.processing.mosaic import FrameLike, mosaic_of, row_bands
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report

log = logging.getLogger(__name__)

EXPOSURE_RTOL = 0.02   # exposure times closer than 2 % are the same setting (1/60 vs 0.0167)


@dataclass
class DarkFrame:
    """A master dark for one exposure time: ``mean`` is float32 (H, W) in raw DN (black level included)."""

    exposure_s: float
    mean: np.ndarray
    n_frames: int
    rejected_high: int = 0
    rejected_low: int = 0
    noise_dn: float = float("nan")        # robust temporal noise estimate of one frame (DN)
    spikes: int = 0                       # pixels whose largest value was far above the rest (rejected)


def _buffer(work: dict | None, name: str, shape: tuple, dtype) -> np.ndarray:
    """A scratch array from ``work`` (reused when shape and dtype match), else a new one.

    Reusing mosaic-size buffers matters: on the lab PC's VM a fresh 100 MB array costs up to 0.3 s of page
    faults before the first pass over it even starts (bench/processing_bench.py)."""
    if work is not None:
        buf = work.get(name)
        if buf is not None and buf.shape == shape and buf.dtype == np.dtype(dtype):
            return buf
    buf = np.empty(shape, dtype=dtype)
    if work is not None:
        work[name] = buf
    return buf


def combine_darks(frames: Iterable[FrameLike], *, reject_high: int = 1, reject_low: int = 1,
                  cancel: CancelToken | None = None, progress: ProgressCallback | None = None,
                  n_expected: int | None = None, work: dict | None = None
                  ) -> tuple[np.ndarray, int, int, int, float, int]:
    """Streamed min/max-rejected mean of dark mosaics -> (mean float32, n, k_high, k_low, noise, spikes).

    ``work`` is an optional dict of scratch buffers reused between calls (same frame size)."""
    from dualrgb.app.processing.kernels import dark_accumulate, dark_finish

    total: np.ndarray | None = None
    hi: np.ndarray | None = None
    lo: np.ndarray | None = None
    n = 0
    shape: tuple[int, ...] | None = None
    from dualrgb.app.processing.mosaic import iter_open_raw

    for f in iter_open_raw(list(frames)):
        check(cancel)
        m = mosaic_of(f)
        if m.dtype.kind in "ui" and m.dtype != np.uint16:
            m = m.astype(np.uint16)
        if shape is None:
            shape = m.shape
            is_float = m.dtype.kind == "f"
            kind = np.float64 if is_float else np.uint16
            total = _buffer(work, "dark_total", shape, np.float64 if is_float else np.uint32)
            hi = _buffer(work, "dark_hi", (reject_high,) + shape, kind)
            lo = _buffer(work, "dark_lo", (reject_low,) + shape, kind)
        elif m.shape != shape:
            raise ValueError(f"dark frame {n + 1} has shape {m.shape}, the first had {shape}")
        assert total is not None and hi is not None and lo is not None    # made with the first frame's shape
        if m.dtype != hi.dtype:
            m = m.astype(hi.dtype)
        dark_accumulate(np.ascontiguousarray(m), total, hi, lo, n == 0)
        n += 1
        if progress is not None:
            report(progress, n / n_expected if n_expected else 0.0, f"dark frame {n}")
    if n == 0 or total is None or hi is None or lo is None or shape is None:
        raise ValueError("no dark frames given")
    k_hi, k_lo = reject_high, reject_low
    if n < k_hi + k_lo + 2:
        log.warning("only %d dark frames: plain mean without outlier rejection; shoot %d or more dark frames to "
                    "reject hot pixels and cosmic-ray hits", n, k_hi + k_lo + 2)
        k_hi = k_lo = 0
    mean = np.empty(shape, dtype=np.float32)
    dark_finish(total, hi, lo, k_hi, k_lo, float(n - k_hi - k_lo), mean)
    noise, spikes = float("nan"), 0
    if reject_high and reject_low:
        noise, spikes = _noise_and_spikes(hi[0], lo[0], mean, n, spikes_rejected=bool(k_hi))
    return mean, n, k_hi, k_lo, noise, spikes


def _noise_and_spikes(highest: np.ndarray, lowest: np.ndarray, mean: np.ndarray, n: int, *, spikes_rejected: bool
                      ) -> tuple[float, int]:
    """The dark frames' temporal noise (DN) from the spread between each pixel's highest and lowest of ``n``
    frames, and how many pixels had a spike (a highest more than 8 sigma above the mean, when it was rejected)."""
    spread = highest[::7, ::7].astype(np.float32) - lowest[::7, ::7].astype(np.float32)
    # expected range of n Gaussian samples is ~ d_n * sigma (d_10 = 3.08): a robust global sigma
    d_n = {2: 1.13, 3: 1.69, 4: 2.06, 5: 2.33, 6: 2.53, 7: 2.70, 8: 2.85, 9: 2.97, 10: 3.08}.get(n, 3.5)
    noise = float(np.median(spread)) / d_n
    spikes = 0
    if spikes_rejected and noise > 0:
        thr = np.float32(8 * max(noise, 0.5))
        for rows in row_bands(mean.shape[0], 512):
            spikes += int(np.count_nonzero(highest[rows] - mean[rows] > thr))
    return noise, spikes


class MasterDark:
    """Master dark frames keyed by exposure time (thesis 8.2.1).

    ``add(exposure_s, frames)`` builds one from N dark mosaics; ``get(exposure_s)`` returns the float32 mosaic
    for an exposure time (matched within 2 %); ``put(frame)`` adds one made earlier (a calibration profile
    keeps them, app.workflow.calibration.profile, so darks are shot once per setting).
    """

    def __init__(self) -> None:
        self._frames: dict[float, DarkFrame] = {}

    @property
    def exposures(self) -> list[float]:
        return sorted(self._frames)

    def __contains__(self, exposure_s: float) -> bool:
        return self._key(exposure_s) is not None

    def _key(self, exposure_s: float) -> float | None:
        for t in self._frames:
            if abs(t - exposure_s) <= EXPOSURE_RTOL * max(t, exposure_s):
                return t
        return None

    def add(self, exposure_s: float, frames: Iterable[FrameLike], *, reject_high: int = 1, reject_low: int = 1,
            progress: ProgressCallback | None = None, cancel: CancelToken | None = None,
            work: dict | None = None) -> DarkFrame:
        frames = list(frames) if not isinstance(frames, list) else frames
        mean, n, k_hi, k_lo, noise, spikes = combine_darks(
            frames, reject_high=reject_high, reject_low=reject_low, cancel=cancel, progress=progress,
            n_expected=len(frames), work=work)
        frame = DarkFrame(float(exposure_s), mean, n, k_hi, k_lo, noise, spikes)
        key = self._key(exposure_s)
        if key is not None:
            del self._frames[key]
        self._frames[float(exposure_s)] = frame
        log.info("master dark %.6g s: %d frames, mean %.1f DN, noise %.2f DN, %d transient outliers rejected",
                 exposure_s, n, float(mean[::17, ::17].mean()), noise, spikes)
        return frame

    def put(self, frame: DarkFrame) -> None:
        key = self._key(frame.exposure_s)
        if key is not None:
            del self._frames[key]
        self._frames[frame.exposure_s] = frame

    def frame(self, exposure_s: float) -> DarkFrame:
        key = self._key(exposure_s)
        if key is None:
            have = ", ".join(f"{t:.6g} s" for t in self.exposures) or "none"
            raise KeyError(f"no master dark for {exposure_s:.6g} s (have: {have}); shoot darks at that time")
        return self._frames[key]

    def get(self, exposure_s: float) -> np.ndarray:
        return self.frame(exposure_s).mean


def white_threshold(white: np.ndarray, min_fraction: float) -> float:
    """Smallest usable white value: ``min_fraction`` of the white's 99th percentile (subsampled)."""
    sample = white[::5, ::5] if white.ndim >= 2 else white
    finite = sample[np.isfinite(sample)]
    if finite.size == 0:
        raise ValueError("the white (flat) image has no finite values")
    top = float(np.percentile(finite, 99))
    if top <= 0:
        raise ValueError("the white (flat) image is not brighter than the dark: check the light and the darks")
    return max(min_fraction * top, float(np.finfo(np.float32).tiny))


class FlatField:
    """Eq 7.1 with a prepared denominator: ``white`` is the dark-subtracted white per second (DN/s), e.g. an
    HDR white (thesis 8.2.2) or ``(img_w - img_d) / t_w``. ``apply(image)`` divides a dark-subtracted image per
    second by it; unusable white pixels give NaN."""

    def __init__(self, white: np.ndarray, *, min_fraction: float = 0.01):
        self.white = np.asarray(white, dtype=np.float32)
        self.threshold = white_threshold(self.white, min_fraction)
        bad = ~(self.white > self.threshold)
        self.n_invalid = int(np.count_nonzero(bad))
        if self.n_invalid:
            log.warning("flat field: %d pixels (%.3f %%) have no usable white (<= %.4g); they become NaN (invalid, "
                        "counted on the QA line): check that the white card fills the frame and is evenly lit",
                        self.n_invalid, 100.0 * self.n_invalid / self.white.size, self.threshold)

    def apply(self, image: np.ndarray, *, rows: slice | None = None, out: np.ndarray | None = None) -> np.ndarray:
        """``image / white`` (float32); ``rows`` selects the band of the white that ``image`` covers."""
        w = self.white if rows is None else self.white[rows]
        image = np.asarray(image, dtype=np.float32)
        if image.shape != w.shape:
            raise ValueError(f"image {image.shape} and white {w.shape} differ in shape")
        if out is None:
            out = np.empty(w.shape, dtype=np.float32)
        ok = w > self.threshold
        np.divide(image, w, out=out, where=ok)
        out[~ok] = np.nan
        return out
