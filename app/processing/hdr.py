"""HDR merging of raw exposures (thesis 8.2.2 white, 8.2.3 image; eq 8.9 or variance-optimal weights).

For each exposure e of one light: dark-subtract with the master dark of its exposure time, divide by the
exposure time t_e (DN/s, a common irradiance scale), and combine with a per-pixel weighted mean::

    E = sum_e w_e (x_e - d_e) / t_e  /  sum_e w_e

``method`` picks the weights (``simulation.hdr_estimators``: the numpy reference, the methods' maths and
references; the default is the parsimony study's choice, ``resources/parsimony.json`` key ``hdr_merge``):

* ``"thesis"``, eq 8.9: the thesis' triangle f(x) = x below 8192 and 16383 - x above, x being the dark-corrected
  value of 14-bit data. Here, scaled to the sensor's usable range::

      u = (x_raw - dark) / (white_level - black_level),   w = u for u < 0.5,  1 - u for u >= 0.5  (>= 0)

  It is biased upwards at low signal (it weights the measured signal, whose noise it then averages).
* ``"variance"``: w_e = t_e^2 / var(x_e) at the pooled estimate (Granados et al. 2010): unbiased.

In both, an exposure whose raw value is above the linear limit (default 11 000 DN, end of the D610's linear
range, thesis Fig 4.2) or at the white level (clipped) is not used.

Choices. The triangle is applied to the dark-subtracted signal, as in the thesis, and scaled to the usable
range (white level - black level: 15 520 - 600 for 14-bit Nikon files, 16 383 in the thesis, 65 535 for 16-bit
files) so the hinge sits at half range for any camera. Applying it to the raw value *before* dark subtraction
was tried and rejected: the black pedestal (600 DN) then gives a barely exposed short frame (5 DN of signal,
read noise 3 DN) nearly the same weight as a well exposed long one (180 DN), and the shadows of the merge
came out with up to 66 % error instead of < 2 % (test_hdr_recovers_radiance_that_one_exposure_clips).
The exclusions, on the other hand, use the raw value: clipping and non-linearity happen to what the ADC
records, pedestal included. The linear limit stays in absolute raw DN because it is a measured property of
the sensor (pass another for another camera, None for no limit below the white level).

Pixels with no usable exposure (above the linear limit even in the shortest) take the shortest exposure's
value and are counted as ``clipped`` (a warning names how many). Dark pixels (eq 8.9 gives every usable
exposure zero weight because the signal is <= 0) take the longest usable exposure's value and are not clipped.
A single exposure gives exactly ``(x - d) / t``: HDR with one frame is plain dark subtraction.

Frames of one exposure time share a slot (float32 sum of the usable frames' dark-subtracted signal + a uint8
count, 5 bytes per pixel): the merge sees their mean, as the thesis merges one image per exposure time. The merge
runs once all frames are in (the variance weights need the pooled estimate first).

The flat-fielded HDR image (8.2.3) is ``FlatField(hdr_white).apply(hdr_scene)``: dividing each exposure by
the white and then averaging with the same weights equals dividing the weighted mean once.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dualrgb.app.processing.mosaic import DEFAULT_BAND_ROWS, FrameLike, mosaic_of
from dualrgb.common.formatting import format_exposure
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.hdr_estimators import (
    HDR_MERGE_METHODS,
    HDR_METHOD_CODES,
    HdrNoise,
    check_method,
    default_method,
    triangle_weight,
)

log = logging.getLogger(__name__)
_CLIPPED_SAID: set[float] = set()                 # shortest exposures whose clipping was said (once each)
CLIPPED_WARN_FRACTION = 1e-4                       # 0.01 % of the frame clipped in every exposure: worth a warning

LINEAR_LIMIT_DN = 11000.0   # thesis 4.1.2 / Fig 4.2: the D610 is linear up to ~11 000 DN
MAX_EXPOSURE_TIMES = 16     # distinct exposure times per merge (one slot of float32 + uint8 per pixel each)
MAX_FRAMES_PER_TIME = 15    # frames of one exposure time (a 4-bit count per pixel)
# the merge kernels' leading arguments (kernels.hdr_merge): sums, counts, order, times, 1/times, method code,
# 1/(white - black), 1/gain, read variance
KernelArgs = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, np.float32, np.float32,
                   np.float32]
__all__ = ["HDR_MERGE_METHODS", "HdrMerge", "HdrNoise", "HdrResult", "LINEAR_LIMIT_DN", "exposure_weight",
           "triangle_weight"]


def exposure_weight(raw: np.ndarray, signal: np.ndarray, white_level: float, black_level: float = 0.0,
                    linear_limit: float | None = LINEAR_LIMIT_DN, out: np.ndarray | None = None) -> np.ndarray:
    """Weight of each pixel of one exposure: eq 8.9 on the dark-subtracted ``signal`` over the usable range,
    zero where the ``raw`` value is above the linear limit or clipped."""
    w = triangle_weight(signal, white_level - black_level, out=out)
    limit = white_level if linear_limit is None else min(float(linear_limit), white_level)
    w[raw > limit] = 0.0
    w[raw >= white_level] = 0.0
    return w


@dataclass
class HdrResult:
    """A merged image in dark-subtracted DN per second, float32 (H, W)."""

    radiance: np.ndarray
    clipped: int               # pixels with no usable exposure (shortest exposure's value used)
    exposures: list[float]
    method: str = ""

    @property
    def clipped_fraction(self) -> float:
        return self.clipped / self.radiance.size


class HdrMerge:
    """Collects exposures of one light (and one subject) and merges them into an HDR mosaic (fused kernels,
    kernels.py).

    >>> m = HdrMerge(white_level=15520, black_level=600)          # method: the parsimony study's default
    >>> m.add(raw_short, 1/250, dark_short); m.add(raw_long, 1/15, dark_long)
    >>> result = m.result()        # HdrResult, radiance in DN/s

    ``work`` is an optional dict of scratch buffers reused between merges of the same frame size; unless
    ``own_result``, the radiance of ``result()`` lives in one of them (valid until the next merge).
    """

    def __init__(self, white_level: float, linear_limit: float | None = LINEAR_LIMIT_DN, *,
                 black_level: float = 0.0, method: str | None = None, noise: HdrNoise = HdrNoise(),
                 band_rows: int = DEFAULT_BAND_ROWS, work: dict | None = None, own_result: bool = False,
                 mode: str | None = None):
        if white_level <= black_level:
            raise ValueError(f"white level {white_level} must be above the black level {black_level}")
        self.white_level = float(white_level)
        self.black_level = float(black_level)
        self.linear_limit = linear_limit
        self.method = check_method(method) if method is not None else default_method(mode)   # the study's, per mode
        self.noise = noise
        self.band_rows = band_rows
        self._work = work if work is not None else {}
        self._own_result = own_result or work is None
        self._sums: np.ndarray | None = None        # (slots, H, W) float32, one slot per exposure time
        self._counts: np.ndarray | None = None      # (slots, H, W) uint8: usable | all frames << 4
        self._slot_times: list[float] = []
        self._slot_frames: list[int] = []
        self.exposures: list[float] = []

    def _slot(self, exposure_s: float, shape: tuple[int, int]) -> tuple[int, bool]:
        """The slot of this exposure time (frames of one exposure time share one: their mean is merged) and
        whether it is new; grows the slot buffers as exposure times arrive."""
        from dualrgb.app.processing.calibration import _buffer

        for k, t in enumerate(self._slot_times):
            if abs(t - exposure_s) <= 1e-3 * max(t, exposure_s):
                if self._slot_frames[k] == MAX_FRAMES_PER_TIME:
                    raise ValueError(f"exposure {exposure_s:.6g} s: at most {MAX_FRAMES_PER_TIME} frames per "
                                     f"exposure time in one HDR merge")
                return k, False
        k = len(self._slot_times)
        if k == MAX_EXPOSURE_TIMES:
            raise ValueError(f"exposure {exposure_s:.6g} s: at most {MAX_EXPOSURE_TIMES} exposure times per HDR merge")
        if self._sums is None or k == self._sums.shape[0]:
            cap = 2 if self._sums is None else min(2 * self._sums.shape[0], MAX_EXPOSURE_TIMES)
            sums = _buffer(self._work, "hdr_sums", (cap,) + shape, np.float32)
            counts = _buffer(self._work, "hdr_counts", (cap,) + shape, np.uint8)
            if self._sums is not None and self._counts is not None:     # grow: keep the slots filled so far
                sums[:k], counts[:k] = self._sums[:k], self._counts[:k]
            self._sums, self._counts = sums, counts
        self._slot_times.append(float(exposure_s))
        self._slot_frames.append(0)
        return k, True

    def add(self, frame: FrameLike, exposure_s: float, dark: np.ndarray | float | None = None,
            cancel: CancelToken | None = None) -> None:
        """Add one exposure: raw mosaic (uint16 DN), its exposure time (s) and its master dark (None: the black
        level is subtracted instead)."""
        from dualrgb.app.processing.kernels import hdr_store

        check(cancel)
        if not exposure_s or exposure_s <= 0:
            raise ValueError(f"exposure time must be positive, got {exposure_s}")
        raw = mosaic_of(frame)
        if self._sums is not None and raw.shape != self._sums.shape[1:]:
            raise ValueError(f"exposure {exposure_s:.6g} s has shape {raw.shape}, earlier ones {self._sums.shape[1:]}")
        if isinstance(dark, np.ndarray) and dark.shape != raw.shape:
            raise ValueError(f"a frame of {raw.shape[1]}x{raw.shape[0]} px against the calibration's master dark of "
                             f"{dark.shape[1]}x{dark.shape[0]} px: the camera's image size or area changed since "
                             "calibrating; set it back (--frame-size on the virtual lab) or calibrate again")
        if raw.dtype.kind not in "ui":
            raise ValueError(f"raw mosaic must hold integer DN, got {raw.dtype}")
        k, new = self._slot(float(exposure_s), raw.shape)
        use_array = isinstance(dark, np.ndarray)
        dark_arr = np.ascontiguousarray(dark, dtype=np.float32) if use_array else np.zeros((1, 1), np.float32)
        dark_value = np.float32(0.0 if use_array else (self.black_level if dark is None else float(dark)))
        limit = self.white_level if self.linear_limit is None else min(float(self.linear_limit), self.white_level)
        hdr_store(np.ascontiguousarray(raw), dark_arr, dark_value, use_array, limit, self.white_level, k, self._sums,
                  self._counts, new)
        self._slot_frames[k] += 1
        self.exposures.append(float(exposure_s))

    @property
    def slots(self) -> tuple[np.ndarray, np.ndarray]:
        """(sums, counts) of the exposure-time slots added so far (kernels.hdr_store), before the merge ends."""
        sums, counts = self._require()
        n = len(self._slot_times)
        return sums[:n], counts[:n]

    def _require(self) -> tuple[np.ndarray, np.ndarray]:
        """(sums, counts) of the slots; ValueError before the first exposure."""
        if self._sums is None or self._counts is None:
            raise ValueError("no exposures added")
        return self._sums, self._counts

    def _kernel_args(self) -> KernelArgs:
        sums, counts = self._require()
        order = np.argsort(np.asarray(self._slot_times), kind="stable").astype(np.int64)
        ts = np.asarray(self._slot_times, dtype=np.float32)[order]
        return (sums, counts, order, ts, (np.float32(1.0) / ts).astype(np.float32),
                HDR_METHOD_CODES[self.method], np.float32(1.0 / (self.white_level - self.black_level)),
                np.float32(1.0 / self.noise.electrons_per_dn), np.float32(self.noise.read_variance))

    def _warn_clipped(self, clipped: int, size: int) -> None:
        """Said once per shortest exposure (every merge of a day repeated it), with what to do; later merges
        at that exposure log at debug level."""
        if not clipped:
            return
        shortest = float(min(self.exposures))
        # a few hot or specular pixels (under CLIPPED_WARN_FRACTION of the frame) are nothing to act on: logged
        # at INFO; more are a light whose shortest exposure is too long (issue 43: warnings only with an action)
        matters = clipped / size >= CLIPPED_WARN_FRACTION
        level = logging.DEBUG if shortest in _CLIPPED_SAID else logging.WARNING if matters else logging.INFO
        _CLIPPED_SAID.add(shortest)
        log.log(level, "HDR: %d pixels (%.3f %%) exceed the linear limit in every exposure (shortest %s used)%s",
                clipped, 100.0 * clipped / size, format_exposure(shortest),
                ": give that light a shorter exposure and calibrate again; said once" if matters else
                " (too few to matter)")

    def _done(self) -> None:
        self._sums = self._counts = None
        self._slot_times, self._slot_frames = [], []

    def result(self) -> HdrResult:
        from dualrgb.app.processing.calibration import _buffer
        from dualrgb.app.processing.kernels import hdr_merge

        shape = self._require()[0].shape[1:]
        out = np.empty(shape, np.float32) if self._own_result else _buffer(self._work, "hdr_out", shape, np.float32)
        clipped = int(hdr_merge(*self._kernel_args(), out))
        self._warn_clipped(clipped, out.size)
        self._done()
        return HdrResult(out, clipped, list(self.exposures), self.method)

    def flat_superpixel(self, white: np.ndarray, threshold: float, cfa: str, out: np.ndarray) -> int:
        """Merge, flat-field by ``white`` (eq 7.1, NaN where white <= threshold) and write the half-size R,
        mean(G1, G2), B into ``out`` (H/2, W/2, 3) in one pass. Returns the clipped-pixel count."""
        from dualrgb.app.processing.kernels import hdr_merge_flat_superpixel
        from dualrgb.app.processing.mosaic import cfa_channel_index

        shape = self._require()[0].shape[1:]
        if white.shape != shape:
            raise ValueError(f"image {shape} and white {white.shape} differ in size")
        clipped = int(hdr_merge_flat_superpixel(*self._kernel_args(), white, np.float32(threshold),
                                                cfa_channel_index(cfa), out))
        self._warn_clipped(clipped, out.shape[0] * out.shape[1] * 4)
        self._done()
        return clipped

    @classmethod
    def merge(cls, frames: Sequence[FrameLike], exposures: Sequence[float],
              darks: Sequence[np.ndarray | float | None] | None = None, *, white_level: float,
              linear_limit: float | None = LINEAR_LIMIT_DN, black_level: float = 0.0,
              method: str | None = None, noise: HdrNoise = HdrNoise(),
              progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> HdrResult:
        """Merge a list of exposures in one call (frames may be paths: each is read once)."""
        if len(frames) != len(exposures):
            raise ValueError(f"{len(frames)} frames but {len(exposures)} exposure times")
        darks = list(darks) if darks is not None else [None] * len(frames)
        m = cls(white_level, linear_limit, black_level=black_level, method=method, noise=noise)
        for i, (f, t, d) in enumerate(zip(frames, exposures, darks, strict=True)):
            m.add(f, t, d, cancel=cancel)
            report(progress, (i + 1) / len(frames), f"merged exposure {t:.6g} s")
        return m.result()
