"""Full-resolution channels of an original, band by band: each light's exposures dark-subtracted, HDR-merged,
flat-fielded and demosaiced (Malvar-He-Cutler, app.processing.demosaic) to the sensor's full resolution, the
lights' RGBs side by side (R1 G1 B1 R2 G2 B2 ...), one row band at a time.

    frames = proc.begin_master(["light 1", "light 2"])     # CaptureProcessor with the calibration's darks / whites
    frames.add("light 1", ExposureRef(path, 1 / 250))       # as each frame lands: decoded, held, nothing computed
    ...
    with frames.result() as stack:                          # MasterStack: a ChannelSource (app.processing.pipeline)
        for r0 in range(0, stack.height, 64):
            band = stack.band(r0, min(64, stack.height - r0))   # (rows, W, 6) float32

Memory: the exposures as LibRaw decoded them (2 bytes per pixel each, no copy) and a few row bands; the master
darks and whites are read one band at a time (from the calibration's file when it keeps them there:
app.workflow.calibration.profile maps large calibrations instead of loading them), so memory grows with the band and the
number of exposures, not with the frame's float images. Nothing frame-sized is computed before the delivery
asks for its first band (the half-resolution path, app.processing.pipeline.StackBuilder, merges each exposure
as it lands instead).

Each band of each light is computed with its HALO rows above and below (the demosaic's support; mirrored at the
frame's edges), by the fused row kernel of app.processing.master_kernels in the threads of a pool (the kernels
release the GIL). The delivery takes that flat-fielded mosaic band (:meth:`MasterStack.mosaic_band`) and
demosaics each row as it encodes it (app.processing.encode.DeliveryEncoder.encode_mosaic: no N-channel float band,
the same values as :meth:`MasterStack.band`).
"""
from __future__ import annotations

import logging
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any, Protocol

import numba
import numpy as np

from dualrgb.app.processing.demosaic import HALO, demosaic_rows
from dualrgb.app.processing.mosaic import cfa_channel_index, mosaic_of
from dualrgb.common.progress import CancelToken, check
from dualrgb.simulation.camera_model import CHANNELS
from dualrgb.simulation.hdr_estimators import HDR_METHOD_CODES


class Processor(Protocol):
    """What the full-resolution path needs of app.processing.pipeline.CaptureProcessor (which makes it; a
    protocol, so this module and the pipeline do not import each other)."""

    cfa: str | None

    def _prepare(self, frame: Any) -> None: ...

    def _dark_for(self, frame: Any, exposure_s: float, cancel: CancelToken | None) -> np.ndarray | float: ...

    def white(self, light: str) -> Any: ...

    def new_merge(self) -> Any: ...


class Exposure(Protocol):
    """An exposure to add (app.processing.pipeline.ExposureRef)."""

    source: Any
    exposure_s: float
    label: str

log = logging.getLogger(__name__)

FULL, HALF = "full", "half"
RESOLUTIONS = (FULL, HALF)
RESOLUTION_CHOICES = {FULL: "full resolution (the sensor's pixels)", HALF: "half resolution (2x2 Bayer cells)"}
SLOT_RTOL = 1e-3               # exposure times this close share an HDR slot (app.processing.hdr.HdrMerge._slot)


def check_resolution(value: str) -> str:
    """``value`` if it names a resolution ('full' or 'half'), else a one-line ValueError."""
    if value not in RESOLUTIONS:
        raise ValueError(f"resolution {value!r}: expected one of {', '.join(RESOLUTIONS)}")
    return value


def band_of(array: np.ndarray, y0: int, y1: int, buffers: dict, key: str) -> np.ndarray:
    """Rows ``y0`` .. ``y1`` of a frame-size calibration array: a view of one in memory; of one mapped from its
    file (np.memmap: app.workflow.calibration.profile maps large calibrations) read into a reused buffer, so its pages
    are
    never mapped into the process and memory stays one band (a view of the map would keep every page read)."""
    if not isinstance(array, np.memmap) or not array.filename:
        return array[y0:y1]
    shape = (y1 - y0,) + array.shape[1:]
    buf = buffers.get(key)
    if buf is None or buf.shape[0] < shape[0] or buf.shape[1:] != shape[1:] or buf.dtype != array.dtype:
        buf = buffers[key] = np.empty(shape, array.dtype)
    out = buf[: shape[0]]
    row_bytes = int(np.prod(array.shape[1:], dtype=np.int64)) * array.dtype.itemsize
    view = out.reshape(-1).view(np.uint8).data
    with open(array.filename, "rb", buffering=0) as fh:
        fh.seek(int(array.offset) + y0 * row_bytes)
        done = 0
        while done < len(view):
            n = fh.readinto(view[done:])
            if not n:
                raise OSError(f"{array.filename}: ends inside a calibration array")
            done += n
    return out


@dataclass
class _Light:
    """One light's exposures (mosaic views in exposure order) and how the row kernel merges them."""

    name: str
    mosaics: list[np.ndarray]
    exposures: list[float]
    darks: list[np.ndarray | float]
    slots: np.ndarray
    first_in_slot: np.ndarray
    order: np.ndarray
    ts: np.ndarray
    white: np.ndarray
    threshold: float


def _slots(exposures: list[float]) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """Each exposure's slot (exposure times within SLOT_RTOL share one), whether it opens it, the slots' times."""
    times: list[float] = []
    slots, first = [], []
    for t in exposures:
        k = next((i for i, s in enumerate(times) if abs(s - t) <= SLOT_RTOL * max(s, t)), len(times))
        first.append(k == len(times))
        if k == len(times):
            times.append(float(t))
        slots.append(k)
    return np.asarray(slots, np.int64), np.asarray(first, np.bool_), times


class MasterFrames:
    """The exposures of one original, held as decoded until :meth:`result` (see the module docstring)."""

    def __init__(self, proc: Processor, lights: list[str], min_signal_dn: float):
        self.proc = proc
        self.lights = list(lights)
        self.min_signal_dn = float(min_signal_dn)
        self._held = ExitStack()
        self._frames: dict[str, list[tuple[float, np.ndarray, np.ndarray | float]]] = {n: [] for n in self.lights}
        self.shape: tuple[int, int] | None = None

    def add(self, light: str, ref: Exposure, cancel: CancelToken | None = None) -> None:
        """Decode ``ref`` and hold it for ``light`` (the file's LibRaw buffer, no copy)."""
        from dualrgb.app.processing.mosaic import open_raw

        if light not in self._frames:
            raise ValueError(f"{light!r} is not one of this original's lights ({', '.join(self.lights)})")
        check(cancel)
        frame = self._held.enter_context(open_raw(ref.source))
        self.proc._prepare(frame)
        mosaic = mosaic_of(frame)
        if mosaic.dtype.kind not in "ui":
            raise ValueError(f"{ref.label or ref.source}: raw mosaic must hold integer DN, got {mosaic.dtype}")
        if self.shape is None:
            self.shape = (int(mosaic.shape[0]), int(mosaic.shape[1]))
        elif mosaic.shape != self.shape:
            raise ValueError(f"{ref.label or ref.source}: frame {mosaic.shape[1]}x{mosaic.shape[0]}, the "
                             f"original's earlier frames {self.shape[1]}x{self.shape[0]}")
        if mosaic.dtype != np.uint16:
            mosaic = mosaic.astype(np.uint16)
        dark = self.proc._dark_for(frame, ref.exposure_s, cancel)
        self._frames[light].append((float(ref.exposure_s), mosaic, dark))

    def _light(self, name: str, shape: tuple[int, int]) -> _Light:
        frames = sorted(self._frames[name], key=lambda f: f[0])
        exposures = [f[0] for f in frames]
        slots, first, times = _slots(exposures)
        order = np.argsort(np.asarray(times), kind="stable").astype(np.int64)
        ff = self.proc.white(name)
        if ff.white.shape != shape:
            raise ValueError(f"{name}: the calibration's white is {ff.white.shape[1]}x{ff.white.shape[0]}, the "
                             f"original's frames {shape[1]}x{shape[0]}")
        return _Light(name, [f[1] for f in frames], exposures, [f[2] for f in frames], slots, first, order,
                      np.asarray(times, np.float32)[order], ff.white, float(ff.threshold))

    def result(self, threads: int | None = None) -> MasterStack:
        """The stack of the held exposures (it owns them from here: close it, or use it as a context manager)."""
        missing = [n for n in self.lights if not self._frames[n]]
        if missing or self.shape is None:
            self.close()
            raise ValueError(f"no exposures of {', '.join(missing or self.lights)} were added")
        shape = self.shape
        lights = [self._light(n, shape) for n in self.lights]
        held, self._held = self._held, ExitStack()
        return MasterStack(self.proc, lights, shape, self.min_signal_dn, held, threads)

    def close(self) -> None:
        """Release the held exposures (their LibRaw buffers)."""
        self._held.close()
        self._frames = {n: [] for n in self.lights}


class MasterStack:
    """The full-resolution channels of one original, computed band by band (a ChannelSource: ``band``)."""

    resolution = FULL

    def __init__(self, proc: Processor, lights: list[_Light], shape: tuple[int, int], min_signal_dn: float,
                 held: ExitStack, threads: int | None = None):
        self._lights = lights
        self.lights = [lt.name for lt in lights]
        self.channels = [f"{c}{i + 1}" for i in range(len(lights)) for c in CHANNELS]
        self.height, self.width = shape
        self._held = held
        merge = proc.new_merge()
        self._limit = (merge.white_level if merge.linear_limit is None
                       else min(float(merge.linear_limit), merge.white_level))
        self._merge = merge
        self._method = HDR_METHOD_CODES[merge.method]
        self._floor = np.float32(min_signal_dn)
        self._cfa = cfa_channel_index(proc.cfa or "RGGB")
        self.threads = max(1, threads or numba.get_num_threads())
        self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="master")
        self._buffers: dict[str, np.ndarray] = {}
        self._lock = threading.Lock()  # the QA counts, when a pipeline's workers compute bands at once
        self._clipped = dict.fromkeys(self.lights, 0)
        self._fused = True          # the fused variance kernel where it applies (False: always the general one)
        self._weak = 0
        self._rows_done = 0

    @property
    def shape(self) -> tuple[int, int]:
        return self.height, self.width

    @property
    def clipped_fraction(self) -> dict[str, float]:
        """Per light: photosites with no usable exposure, over the rows delivered so far."""
        return {n: c / max(self._rows_done * self.width, 1) for n, c in self._clipped.items()}

    @property
    def underexposed_fraction(self) -> float:
        """Photosites whose every exposure under every light stayed below the minimum signal."""
        return self._weak / max(self._rows_done * self.width, 1)

    def _buffer(self, key: str, shape: tuple[int, ...], dtype: Any, buffers: dict | None = None) -> np.ndarray:
        """A reused buffer of ``buffers`` (default this stack's own) of at least ``shape``'s rows."""
        buffers = self._buffers if buffers is None else buffers
        buf = buffers.get(key)
        if buf is None or buf.shape[0] < shape[0] or buf.shape[1:] != shape[1:]:
            buf = buffers[key] = np.empty(shape, dtype)
        return buf[: shape[0]]

    def _chunks(self, n: int) -> list[tuple[int, int]]:
        cuts = np.linspace(0, n, min(self.threads * 2, max(n, 1)) + 1).astype(int)
        return [(int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a]

    def _flat_band(self, li: int, lt: _Light, y0: int, y1: int, out: np.ndarray, core: tuple[int, int],
                   weak: np.ndarray, buffers: dict, parallel: bool) -> int:
        """Light ``lt``'s flat-fielded mosaic for image rows y0 .. y1 (inside the frame) into ``out`` (y1 - y0,
        W + 2 HALO), mirrored at the columns (``buffers``: where mapped calibration rows are read; ``parallel``: in
        row pieces on the stack's threads, else in this thread); returns its clipped photosites in rows ``core``
        (of the band)."""
        from dualrgb.app.processing.master_kernels import flat_rows, flat_rows_variance

        raws = tuple(np.ascontiguousarray(m[y0:y1]) for m in lt.mosaics)
        placeholder = self._buffer("nodark", (1, self.width), np.float32, buffers)
        darks = tuple(np.ascontiguousarray(band_of(d, y0, y1, buffers, f"dark{li}_{k}"), np.float32)
                      if isinstance(d, np.ndarray) else placeholder for k, d in enumerate(lt.darks))
        use = np.array([isinstance(d, np.ndarray) for d in lt.darks], np.bool_)
        values = np.array([0.0 if isinstance(d, np.ndarray) else d for d in lt.darks], np.float32)
        white = np.ascontiguousarray(band_of(lt.white, y0, y1, buffers, f"white{li}"), np.float32)
        pieces = self._chunks(y1 - y0) if parallel else [(0, y1 - y0)]
        run = self._pool.map if parallel else map
        m = self._merge
        gain, var = np.float32(1.0 / m.noise.electrons_per_dn), np.float32(m.noise.read_variance)
        limit, white_level, threshold = np.float32(self._limit), np.float32(m.white_level), np.float32(lt.threshold)
        if self._fused and self._method == HDR_METHOD_CODES["variance"] and bool(lt.first_in_slot.all()):
            fargs = (raws, darks, values, use, lt.ts, gain, var, limit, white_level, white, threshold, self._floor,
                     out, weak, li == 0)
            done = run(lambda ab: flat_rows_variance(*fargs, ab[0], ab[1], core[0], core[1]), pieces)
        else:
            args = (raws, darks, values, use, lt.slots, lt.first_in_slot, int(lt.slots.max()) + 1, lt.order, lt.ts,
                    (np.float32(1.0) / lt.ts).astype(np.float32), self._method,
                    np.float32(1.0 / (m.white_level - m.black_level)), gain, var, limit, white_level, white,
                    threshold, self._floor, out, weak, li == 0)
            done = run(lambda ab: flat_rows(*args, ab[0], ab[1], core[0], core[1]), pieces)
        return sum(int(c) for c in done)

    def mosaic_band(self, r0: int, rows: int) -> np.ndarray:
        """Rows ``r0`` .. ``r0 + rows`` of every light's flat-fielded mosaic before the demosaic: (L, rows + 2 HALO,
        W + 2 HALO) float32, HALO mirrored rows and columns around (row HALO + r is image row r0 + r; valid until
        the next call); bands come in order, each once (the QA counts add up over them). :meth:`band` demosaics
        it; app.processing.encode.DeliveryEncoder.encode_mosaic demosaics and encodes it in one pass."""
        if r0 != self._rows_done:
            raise ValueError(f"band of rows {r0}..{r0 + rows} after {self._rows_done} of {self.height} (in order, "
                             "each once)")
        return self._mosaic(r0, rows, self._buffers, True)

    def mosaic_band_into(self, r0: int, rows: int, scratch: dict) -> np.ndarray:
        """:meth:`mosaic_band` for one of several threads computing bands at once (app.processing.band_pipeline):
        any band, each once, in any order, computed in the calling thread into ``scratch`` (a dict of that
        thread's buffers; the result is valid until its next call with it)."""
        return self._mosaic(r0, rows, scratch, False)

    def _mosaic(self, r0: int, rows: int, buffers: dict, parallel: bool) -> np.ndarray:
        H, W = self.shape
        if rows < 1 or r0 < 0 or r0 + rows > H:
            raise ValueError(f"band of rows {r0}..{r0 + rows} of {H}")
        top = r0 - HALO                                       # image row of the padded band's first row
        y0, y1 = max(top, 0), min(r0 + rows + HALO, H)        # the rows inside the frame
        weak = self._buffer("weak", (y1 - y0, W), np.bool_, buffers)
        padded = self._buffer("padded", (len(self._lights), rows + 2 * HALO, W + 2 * HALO), np.float32, buffers)
        clipped = []
        for li, lt in enumerate(self._lights):
            p = padded[li]
            clipped.append(self._flat_band(li, lt, y0, y1, p[y0 - top: y1 - top], (r0 - y0, r0 + rows - y0), weak,
                                           buffers, parallel))
            for y in [*range(top, 0), *range(H, r0 + rows + HALO)]:     # outside the frame: mirrored rows
                p[y - top] = p[(-y if y < 0 else 2 * (H - 1) - y) - top]
        n_weak = int(np.count_nonzero(weak[r0 - y0: r0 - y0 + rows]))
        with self._lock:
            for lt, c in zip(self._lights, clipped, strict=True):
                self._clipped[lt.name] += c
            self._weak += n_weak
            self._rows_done += rows
        return padded

    @property
    def cfa_index(self) -> np.ndarray:
        """(2, 2) channel indices (0 = R, 1 = G, 2 = B) of the frame's top-left cell."""
        return self._cfa

    def band(self, r0: int, rows: int) -> np.ndarray:
        """Rows ``r0`` .. ``r0 + rows`` of the channels, (rows, W, N) float32 (valid until the next call); bands
        come in order, each once (the QA counts add up over them)."""
        padded = self.mosaic_band(r0, rows)
        out = self._buffer("band", (rows, self.width, len(self.channels)), np.float32)
        for li in range(len(self._lights)):
            list(self._pool.map(lambda ab, p=padded[li], b=3 * li: demosaic_rows(p, HALO, r0, self._cfa, out, ab[0],
                                                                                  ab[1], b), self._chunks(rows)))
        return out

    def close(self) -> None:
        """Release the exposures and the threads."""
        self._pool.shutdown()
        self._held.close()
        self._buffers.clear()

    def __enter__(self) -> MasterStack:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def decode_threads() -> int:
    """Files decoded at once when a whole original is read from disk (``dualrgb process``)."""
    return max(1, min(2, os.cpu_count() or 1))
