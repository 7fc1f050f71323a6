"""From raw files to the N-channel stack, the characterisation, the output files and the report.

Steps (thesis 7 and 8.2):
  1. master dark per exposure time (8.2.1), built lazily from the dark frames when an exposure first needs it;
  2. per light, the HDR white (8.2.2): dark-subtracted, per-second, weighted mean of the white exposures (hdr.py);
  3. per light and subject, the HDR image (8.2.3) of the subject's exposures, flat-fielded by that white
     (eq 7.1), reduced to the half-size superpixel RGB (no demosaic);
  4. the lights' RGBs side by side: an (H/2, W/2, 3 x n_lights) float32 stack, channels R1 G1 B1 R2 G2 B2 ...

Each raw file is decoded once per use and processed in row bands; the mosaic-size buffers alive at a time are
the master darks in use, one HDR accumulator (3 arrays) and one HDR white per light, so a 24 MP dual-RGB HDR
set stays well under 2.5 GB (see bench/bench_processing.py for the measured figures).

API for the sequences and the demo::

    proc = CaptureProcessor(dark_frames=[ExposureRef(path, t), ...], white_level=15520)
    proc.set_white("light 1", [ExposureRef(white_short, 1/250), ExposureRef(white_long, 1/15)])
    proc.set_white("light 2", [...])
    stack = proc.stack({"light 1": [ExposureRef(...), ...], "light 2": [...]})  # ChannelStack
    train = grid.sample(stack.data)                                          # PatchGrid -> PatchValues

A whole session (frames grouped by subject and light) is processed by app.workflow.calibration.session_processing.
"""
from __future__ import annotations

import logging
from collections import OrderedDict, defaultdict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np

from dualrgb.app.processing.calibration import FlatField, MasterDark
from dualrgb.app.processing.hdr import LINEAR_LIMIT_DN, HdrMerge, HdrResult
from dualrgb.app.processing.mosaic import FrameLike, cfa_of, iter_open_raw, mosaic_of, white_level_of
from dualrgb.common.progress import CancelToken, ProgressCallback, check, report
from dualrgb.simulation.camera_model import CHANNELS

if TYPE_CHECKING:
    from dualrgb.app.processing.masters import MasterFrames

log = logging.getLogger(__name__)

MIN_SIGNAL_DN = 100.0     # below this in its best exposure a pixel counts as under-exposed (the HDR plan's floor)


@dataclass
class ExposureRef:
    """One raw exposure: a path, a drivers.raw.RawFrame or a mosaic array, and its exposure time (s).

    For bare arrays pass ``white_level`` and ``black_level`` to the CaptureProcessor (files carry their own)."""

    source: FrameLike
    exposure_s: float
    label: str = ""


class ChannelSource(Protocol):
    """The channels of an original as delivery reads them, one row band at a time: a half-resolution
    :class:`ChannelStack` (in memory) or a full-resolution app.processing.masters.MasterStack (computed per band).
    The QA figures (``clipped_fraction``, ``underexposed_fraction``) are final once every band was read."""

    resolution: str
    channels: list[str]
    lights: list[str]

    @property
    def shape(self) -> tuple[int, int]: ...

    @property
    def clipped_fraction(self) -> dict[str, float]: ...

    @property
    def underexposed_fraction(self) -> float: ...

    def band(self, r0: int, rows: int) -> np.ndarray: ...

    def close(self) -> None: ...


@dataclass
class ChannelStack:
    """Flat-fielded HDR superpixel channels: ``data`` (H/2, W/2, C) float32, channel names R1, G1, B1, ...
    (a half-resolution ChannelSource)."""

    data: np.ndarray
    channels: list[str]
    lights: list[str]
    clipped_fraction: dict[str, float] = field(default_factory=dict)        # per light: no usable exposure
    underexposed_fraction: float = 0.0      # superpixels whose every channel under every light stays < min signal
    resolution: str = "half"

    def rgb(self, light_index: int = 0) -> np.ndarray:
        return self.data[..., 3 * light_index: 3 * light_index + 3]

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.data.shape[0]), int(self.data.shape[1])

    def band(self, r0: int, rows: int) -> np.ndarray:
        """Rows ``r0`` .. ``r0 + rows`` (a view; float32, contiguous)."""
        return np.ascontiguousarray(self.data[r0: r0 + rows], dtype=np.float32)

    def close(self) -> None:
        """Nothing to release (the full-resolution source releases its frames)."""


def sub_progress(progress: ProgressCallback | None, lo: float, hi: float) -> ProgressCallback | None:
    if progress is None:
        return None
    return lambda f, m: progress(lo + (hi - lo) * min(max(f, 0.0), 1.0), m)


class CaptureProcessor:
    """Darks -> HDR whites -> flat-fielded HDR stacks, with caching of master darks and whites."""

    def __init__(self, *, darks: MasterDark | None = None, dark_frames: Sequence[ExposureRef] = (),
                 white_level: float | None = None, black_level: float | None = None,
                 linear_limit: float | None = LINEAR_LIMIT_DN, cfa: str | None = None, band_rows: int = 256,
                 reject_high: int = 1, reject_low: int = 1, hdr_method: str | None = None,
                 mode: str | None = None):
        """``hdr_method``: the HDR merge estimator (app.processing.hdr; None: the HDR study's default for ``mode``,
        'reflective' or 'transmissive')."""
        self.darks = darks or MasterDark()
        self._dark_frames: dict[float, list[ExposureRef]] = defaultdict(list)
        for ref in dark_frames:
            self._dark_frames[self._dark_key(ref.exposure_s)].append(ref)
        self.white_level = white_level
        self.black_level = black_level
        self.linear_limit = linear_limit
        self.cfa = cfa
        self.band_rows = band_rows
        self.reject = (reject_high, reject_low)
        self.hdr_method = hdr_method
        self.mode = mode
        self._whites: OrderedDict[str, FlatField] = OrderedDict()
        self._work: dict = {}          # scratch buffers reused across darks and merges (see calibration._buffer)

    def _dark_key(self, t: float) -> float:
        for k in self._dark_frames:
            if abs(k - t) <= 0.02 * max(k, t):
                return k
        return float(t)

    # ---- darks ----
    def master_dark(self, exposure_s: float, *, progress: ProgressCallback | None = None,
                    cancel: CancelToken | None = None) -> np.ndarray | None:
        """The master dark for ``exposure_s`` (built from the dark frames on first use), or None if none."""
        if exposure_s in self.darks:
            return self.darks.get(exposure_s)
        refs = self._dark_frames.get(self._dark_key(exposure_s))
        if not refs:
            return None
        self.darks.add(exposure_s, [r.source for r in refs], reject_high=self.reject[0],
                       reject_low=self.reject[1], progress=progress, cancel=cancel, work=self._work)
        return self.darks.get(exposure_s)

    def _dark_for(self, frame, exposure_s: float, cancel) -> np.ndarray | float:
        d = self.master_dark(exposure_s, cancel=cancel)
        if d is not None:
            return d
        black = getattr(frame, "black_levels", None)
        level = float(np.mean(black)) if black else float(self.black_level or 0.0)    # a bare array: the given one
        log.warning("no dark frames for %.6g s: subtracting the file's black level (%.1f DN) instead", exposure_s,
                    level)
        return level

    # ---- HDR ----
    def _merge(self, refs: Sequence[ExposureRef], progress, cancel, own_result: bool) -> HdrMerge:
        if not refs:
            raise ValueError("no exposures to merge")
        merge: HdrMerge | None = None
        refs = sorted(refs, key=lambda r: r.exposure_s)
        for i, (ref, frame) in enumerate(zip(refs, iter_open_raw([r.source for r in refs]), strict=True)):
            check(cancel)
            self._prepare(frame)
            if merge is None:
                merge = self.new_merge(own_result=own_result)
            dark = self._dark_for(frame, ref.exposure_s, cancel)
            merge.add(mosaic_of(frame), ref.exposure_s, dark, cancel=cancel)
            report(progress, (i + 1) / len(refs), f"exposure {ref.exposure_s:.6g} s {ref.label}".strip())
        assert merge is not None                    # refs is not empty
        return merge

    def hdr(self, refs: Sequence[ExposureRef], *, progress: ProgressCallback | None = None,
            cancel: CancelToken | None = None) -> HdrResult:
        """Dark-subtracted HDR mosaic (DN/s, the configured estimator) of the exposures of one light and subject
        (in new arrays: the result is the caller's to keep)."""
        return self._merge(refs, progress, cancel, True).result()

    def set_white(self, light: str, refs: Sequence[ExposureRef], *, min_fraction: float = 0.01,
                  progress: ProgressCallback | None = None, cancel: CancelToken | None = None) -> FlatField:
        """HDR white of one light (8.2.2), kept for flat-fielding that light's images."""
        res = self.hdr(refs, progress=progress, cancel=cancel)
        ff = FlatField(res.radiance, min_fraction=min_fraction)
        self._whites[light] = ff
        log.info("white for %s: %d exposures, %.3f %% clipped", light, len(refs), 100 * res.clipped_fraction)
        return ff

    def has_white(self, light: str) -> bool:
        return light in self._whites

    def white(self, light: str) -> FlatField:
        """The HDR white of ``light`` set by set_white (the quality report measures its uniformity)."""
        return self._whites[light]

    def put_white(self, light: str, white: FlatField) -> None:
        """Use a white made earlier (a calibration profile's) for ``light``."""
        self._whites[light] = white

    def begin_stack(self, lights: Sequence[str], *, min_signal_dn: float = MIN_SIGNAL_DN) -> StackBuilder:
        """A stack filled exposure by exposure as frames arrive (see :class:`StackBuilder`)."""
        missing = [n for n in lights if n not in self._whites]
        if missing:
            raise ValueError(f"no white (flat) frames for {', '.join(missing)}: call set_white first")
        return StackBuilder(self, list(lights), min_signal_dn)

    def begin_master(self, lights: Sequence[str], *, min_signal_dn: float = MIN_SIGNAL_DN) -> MasterFrames:
        """The full-resolution counterpart of :meth:`begin_stack`: exposures are held as they land and merged,
        flat-fielded and demosaiced band by band when delivered (app.processing.masters)."""
        from dualrgb.app.processing.masters import MasterFrames

        missing = [n for n in lights if n not in self._whites]
        if missing:
            raise ValueError(f"no white (flat) frames for {', '.join(missing)}: call set_white first")
        return MasterFrames(self, list(lights), min_signal_dn)

    def stack(self, scenes: Mapping[str, Sequence[ExposureRef]], *, progress: ProgressCallback | None = None,
              cancel: CancelToken | None = None) -> ChannelStack:
        """Flat-fielded HDR superpixel RGB of each light (in mapping order), stacked into one image."""
        builder = self.begin_stack(list(scenes))
        for li, name in enumerate(scenes):
            merge = self._merge(scenes[name], sub_progress(progress, li / len(scenes), (li + 0.9) / len(scenes)),
                                cancel, False)
            check(cancel)
            builder.finish_light(name, merge)
            report(progress, (li + 1) / len(scenes), f"{name} flat-fielded")
        return builder.result()

    def _prepare(self, frame) -> None:
        """Take white level, CFA and black level from the first frame when not given."""
        if self.white_level is None:
            self.white_level = white_level_of(frame)
        if self.cfa is None:
            self.cfa = cfa_of(frame)
        if self.black_level is None:
            black = getattr(frame, "black_levels", None)
            self.black_level = float(np.mean(black)) if black else 0.0

    def new_merge(self, *, own_result: bool = False) -> HdrMerge:
        """An HDR merge with this processor's levels (known once a frame was prepared, or given)."""
        if self.white_level is None or self.black_level is None:
            raise ValueError("the raw white and black levels are unknown: no frame seen yet (pass white_level and "
                             "black_level for bare arrays)")
        return HdrMerge(self.white_level, self.linear_limit, black_level=self.black_level, method=self.hdr_method,
                        mode=self.mode, band_rows=self.band_rows, work=self._work, own_result=own_result)


def _weak_cells(slots: tuple[np.ndarray, np.ndarray], floor_dn: float, so_far: np.ndarray | None) -> np.ndarray:
    """Superpixels none of whose four pixels reached ``floor_dn`` in any usable exposure, AND-ed with the lights
    before (a cell is under-exposed only if it is under every light); ``slots`` = HdrMerge.slots."""
    from dualrgb.app.processing.encode import weak_cells

    sums, counts = slots
    out = np.empty((sums.shape[1] // 2, sums.shape[2] // 2), dtype=np.bool_) if so_far is None else so_far
    weak_cells(sums, counts, np.float32(floor_dn), out, so_far is None)
    return out


class StackBuilder:
    """Builds a ChannelStack light by light while frames arrive: ``add(light, ref)`` merges one exposure as soon
    as it lands (decode + eq 8.9 accumulate), ``finish_light`` flat-fields that light's merge into its three
    channels; after the last frame only that frame and the last light's flat field remain to be done.
    """

    def __init__(self, proc: CaptureProcessor, lights: list[str], min_signal_dn: float):
        self.proc = proc
        self.lights = lights
        self.min_signal_dn = min_signal_dn
        self.out: np.ndarray | None = None
        self.clipped: dict[str, float] = {}
        self._weak: np.ndarray | None = None     # superpixels under-exposed under every light so far
        self._merges: dict[str, HdrMerge] = {}

    def add(self, light: str, ref: ExposureRef, cancel: CancelToken | None = None) -> None:
        from dualrgb.app.processing.mosaic import open_raw

        if light not in self.lights:
            raise ValueError(f"{light!r} is not one of this stack's lights ({', '.join(self.lights)})")
        if light in self.clipped:
            raise ValueError(f"{light} is already flat-fielded: add every exposure of a light before the next light")
        for other in [n for n in self._merges if n != light]:     # merges share scratch buffers: one at a time
            self.finish_light(other)
        with open_raw(ref.source) as frame:
            self.proc._prepare(frame)
            merge = self._merges.get(light) or self._merges.setdefault(light, self.proc.new_merge())
            dark = self.proc._dark_for(frame, ref.exposure_s, cancel)
            merge.add(mosaic_of(frame), ref.exposure_s, dark, cancel=cancel)

    def finish_light(self, light: str, merge: HdrMerge | None = None) -> None:
        merge = merge or self._merges.pop(light)
        ff = self.proc._whites[light]
        h, w = ff.white.shape
        if self.out is None:
            self.out = np.empty((h // 2, w // 2, 3 * len(self.lights)), dtype=np.float32)
        li = self.lights.index(light)
        self._weak = _weak_cells(merge.slots, self.min_signal_dn, self._weak)
        n_clipped = merge.flat_superpixel(ff.white, ff.threshold, self.proc.cfa or "RGGB",
                                          self.out[..., 3 * li: 3 * li + 3])
        self.clipped[light] = n_clipped / (h * w)

    def close(self) -> None:
        """Nothing to release (the stack is in memory; the full-resolution builder releases its frames)."""

    def result(self) -> ChannelStack:
        for light in list(self._merges):
            self.finish_light(light)
        missing = [n for n in self.lights if n not in self.clipped]
        if missing or self.out is None:
            raise ValueError(f"no exposures of {', '.join(missing) or 'any light'} were added")
        channels = [f"{c}{i + 1}" for i in range(len(self.lights)) for c in CHANNELS]
        under = float(self._weak.mean()) if self._weak is not None else 0.0
        return ChannelStack(self.out, channels, self.lights, self.clipped, under)
