"""HDR merging of raw exposures (thesis 8.2.2 white, 8.2.3 image, weight function eq 8.9).

For each exposure e of one light: dark-subtract with the master dark of its exposure time, divide by the
exposure time t_e (DN/s, a common irradiance scale), and combine with a per-pixel weighted mean::

    E = sum_e w(x_e) (x_e - d_e) / t_e  /  sum_e w(x_e)

Weight (eq 8.9): the thesis' triangle f(x) = x below 8192 and 16383 - x above, x being the dark-corrected
value of 14-bit data. Here, scaled to the sensor's usable range::

    u = (x_raw - dark) / (white_level - black_level),   w = u for u < 0.5,  1 - u for u >= 0.5  (>= 0)
    w = 0 where x_raw > linear_limit (default 11 000 DN, end of the D610's linear range, thesis Fig 4.2)
      or x_raw >= white_level (clipped)

Choices. The triangle is applied to the dark-subtracted signal, as in the thesis, and scaled to the usable
range (white level - black level: 15 520 - 600 for 14-bit Nikon files, 16 383 in the thesis, 65 535 for 16-bit
files) so the hinge sits at half range for any camera. Applying it to the raw value *before* dark subtraction
was tried and rejected: the black pedestal (600 DN) then gives a barely exposed short frame (5 DN of signal,
read noise 3 DN) nearly the same weight as a well exposed long one (180 DN), and the shadows of the merge
came out with up to 66 % error instead of < 2 % (test_hdr_recovers_radiance_that_one_exposure_clips).
The exclusions, on the other hand, use the raw value: clipping and non-linearity happen to what the ADC
records, pedestal included. The linear limit stays in absolute raw DN because it is a measured property of
the sensor (pass another for another camera, None for no limit below the white level).

Pixels with zero weight in every exposure (above the linear limit even in the shortest) take the shortest
exposure's value and are counted as ``clipped`` (a warning names how many). A single exposure whose pixels are
all below the linear limit gives exactly ``(x - d) / t``: HDR with one frame is plain dark subtraction.

The flat-fielded HDR image (8.2.3) is ``FlatField(hdr_white).apply(hdr_scene)``: dividing each exposure by
the white and then averaging with the same weights equals dividing the weighted mean once.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from app.processing.mosaic import DEFAULT_BAND_ROWS, FrameLike, mosaic_of
from simulation.progress import CancelToken, ProgressCallback, check, report

log = logging.getLogger(__name__)

LINEAR_LIMIT_DN = 11000.0   # thesis 4.1.2 / Fig 4.2: the D610 is linear up to ~11 000 DN


def triangle_weight(signal: np.ndarray, full_scale: float, out: Optional[np.ndarray] = None) -> np.ndarray:
    """Eq 8.9 on a 0..1 scale: u = signal / full_scale, w = min(u, 1 - u) clipped at 0; float32."""
    if out is None:
        out = np.empty(np.shape(signal), dtype=np.float32)
    np.multiply(signal, np.float32(1.0 / full_scale), out=out, casting="unsafe")
    np.minimum(out, np.float32(1.0) - out, out=out)
    np.maximum(out, np.float32(0.0), out=out)
    return out


def exposure_weight(raw: np.ndarray, signal: np.ndarray, white_level: float, black_level: float = 0.0,
                    linear_limit: Optional[float] = LINEAR_LIMIT_DN, out: Optional[np.ndarray] = None) -> np.ndarray:
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
    weight_sum: np.ndarray
    clipped: int               # pixels with no usable exposure (shortest exposure's value used)
    exposures: list[float]

    @property
    def clipped_fraction(self) -> float:
        return self.clipped / self.radiance.size


class HdrMerge:
    """Accumulates exposures of one light (and one subject) into an HDR mosaic (fused kernels, kernels.py).

    >>> m = HdrMerge(white_level=15520, black_level=600)
    >>> m.add(raw_short, 1/250, dark_short); m.add(raw_long, 1/15, dark_long)
    >>> result = m.result()        # HdrResult, radiance in DN/s

    ``work`` is an optional dict of scratch buffers reused between merges of the same frame size; unless
    ``own_result``, the radiance of ``result()`` lives in one of them (valid until the next merge).
    """

    def __init__(self, white_level: float, linear_limit: Optional[float] = LINEAR_LIMIT_DN, *,
                 black_level: float = 0.0, band_rows: int = DEFAULT_BAND_ROWS, work: Optional[dict] = None,
                 own_result: bool = False):
        if white_level <= black_level:
            raise ValueError(f"white level {white_level} must be above the black level {black_level}")
        self.white_level = float(white_level)
        self.black_level = float(black_level)
        self.linear_limit = linear_limit
        self.band_rows = band_rows
        self._work = work
        self._own_result = own_result or work is None
        self._num: Optional[np.ndarray] = None
        self._den: Optional[np.ndarray] = None
        self._fallback: Optional[np.ndarray] = None
        self._fallback_t = np.inf
        self.exposures: list[float] = []

    def add(self, frame: FrameLike, exposure_s: float, dark: np.ndarray | float | None = None,
            cancel: Optional[CancelToken] = None) -> None:
        """Add one exposure: raw mosaic (uint16 DN), its exposure time (s) and its master dark (None: the black
        level is subtracted instead)."""
        from app.processing.calibration import _buffer
        from app.processing.kernels import hdr_accumulate

        check(cancel)
        if not exposure_s or exposure_s <= 0:
            raise ValueError(f"exposure time must be positive, got {exposure_s}")
        raw = mosaic_of(frame)
        first = self._num is None
        if first:
            self._num = (np.empty(raw.shape, np.float32) if self._own_result
                         else _buffer(self._work, "hdr_num", raw.shape, np.float32))
            self._den = _buffer(self._work, "hdr_den", raw.shape, np.float32)
            self._fallback = _buffer(self._work, "hdr_fallback", raw.shape, np.float32)
        elif raw.shape != self._num.shape:
            raise ValueError(f"exposure {exposure_s:.6g} s has shape {raw.shape}, earlier ones {self._num.shape}")
        if isinstance(dark, np.ndarray) and dark.shape != raw.shape:
            raise ValueError(f"dark {dark.shape} and raw {raw.shape} differ in shape")
        if raw.dtype.kind not in "ui":
            raise ValueError(f"raw mosaic must hold integer DN, got {raw.dtype}")
        shortest = exposure_s < self._fallback_t
        use_array = isinstance(dark, np.ndarray)
        dark_arr = np.ascontiguousarray(dark, dtype=np.float32) if use_array else np.zeros((1, 1), np.float32)
        dark_value = np.float32(0.0 if use_array else (self.black_level if dark is None else float(dark)))
        limit = self.white_level if self.linear_limit is None else min(float(self.linear_limit), self.white_level)
        hdr_accumulate(np.ascontiguousarray(raw), dark_arr, dark_value, use_array, np.float32(1.0 / exposure_s),
                       np.float32(1.0 / (self.white_level - self.black_level)), limit, self.white_level,
                       self._num, self._den, self._fallback, shortest, first)
        if shortest:
            self._fallback_t = exposure_s
        self.exposures.append(float(exposure_s))

    @property
    def weight_sum(self) -> np.ndarray:
        """Per pixel, the sum of the eq 8.9 weights added so far (before ``result``)."""
        self._require()
        return self._den

    def _require(self) -> None:
        if self._num is None:
            raise ValueError("no exposures added")

    def _warn_clipped(self, clipped: int, size: int) -> None:
        if clipped:
            log.warning("HDR: %d pixels (%.3f %%) exceed the linear limit in every exposure (shortest %.6g s "
                        "used); add a shorter exposure", clipped, 100.0 * clipped / size, self._fallback_t)

    def result(self) -> HdrResult:
        from app.processing.kernels import hdr_finish

        self._require()
        clipped = int(hdr_finish(self._num, self._den, self._fallback))
        self._warn_clipped(clipped, self._num.size)
        res = HdrResult(self._num, self._den, clipped, list(self.exposures))
        self._num = self._den = self._fallback = None
        return res

    def flat_superpixel(self, white: np.ndarray, threshold: float, cfa: str, out: np.ndarray) -> int:
        """Finish the merge, flat-field it by ``white`` (eq 7.1, NaN where white <= threshold) and write the
        half-size R, mean(G1, G2), B into ``out`` (H/2, W/2, 3) in one pass. Returns the clipped-pixel count."""
        from app.processing.kernels import hdr_flat_superpixel
        from app.processing.mosaic import cfa_channel_index

        self._require()
        if white.shape != self._num.shape:
            raise ValueError(f"image {self._num.shape} and white {white.shape} differ in size")
        clipped = int(hdr_flat_superpixel(self._num, self._den, self._fallback, white, np.float32(threshold),
                                          cfa_channel_index(cfa), out))
        self._warn_clipped(clipped, out.shape[0] * out.shape[1] * 4)
        self._num = self._den = self._fallback = None
        return clipped

    @classmethod
    def merge(cls, frames: Sequence[FrameLike], exposures: Sequence[float],
              darks: Sequence[np.ndarray | float | None] | None = None, *, white_level: float,
              linear_limit: Optional[float] = LINEAR_LIMIT_DN, black_level: float = 0.0,
              progress: Optional[ProgressCallback] = None, cancel: Optional[CancelToken] = None) -> HdrResult:
        """Merge a list of exposures in one call (frames may be paths: each is read once)."""
        if len(frames) != len(exposures):
            raise ValueError(f"{len(frames)} frames but {len(exposures)} exposure times")
        darks = list(darks) if darks is not None else [None] * len(frames)
        m = cls(white_level, linear_limit, black_level=black_level)
        for i, (f, t, d) in enumerate(zip(frames, exposures, darks)):
            m.add(f, t, d, cancel=cancel)
            report(progress, (i + 1) / len(frames), f"merged exposure {t:.6g} s")
        return m.result()
