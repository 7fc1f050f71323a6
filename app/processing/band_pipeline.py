"""A full-resolution delivery's row bands on every core, written and hashed in file order: each band merged,
flat-fielded, demosaiced and encoded by one thread into slots of the open files (app.processing.tiff_stream's
ring mode), while the same threads add the finished bands to each file's SHA-256 and I/O threads write them.

Why hand-written: on the 2-core stand PC the delivery of a 24 MP original is the last frame's decode plus about
1.1 CPU-s of work that parallelises (merge, demosaic and encodings, SHA-256), and every hand-over costs. The
earlier loop cut each band into row pieces for a pool twice per band (the merge, the encodings) and gave each
file's writes and SHA-256 to a thread of its own: 3 waits per band on the slowest piece, 5 hashing threads and 2
encoding threads taking turns on 2 cores, ~0.15 s of a ~0.9 s delivery with a core idle. Here there is no wait
inside a band: a worker takes the next band whole (its merge and encodings in this thread, the kernels release
the GIL) or, first, the next band of a file whose turn it is to be hashed (SHA-256 is sequential within a file;
hashlib releases the GIL). Only the positional O_DIRECT writes, which wait on the disk and not on a core, go to
I/O threads. A band's slot is reused once that band is written in every file (``slots`` per file, bounded
memory: :func:`ring_slots`).

Cancel: checked before every band and again just before its encoding (common.progress.Cancelled); the bands
after the first start their encoding only once the first is encoded, so a cancel while the first is encoded is
the last band encoded.
"""
from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from contextlib import ExitStack
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from dualrgb.app.processing.demosaic import HALO
from dualrgb.app.processing.tiff_stream import TiffStream
from dualrgb.common.progress import CancelToken, check

if TYPE_CHECKING:
    from dualrgb.app.processing.encode import DeliveryEncoder
    from dualrgb.app.processing.masters import MasterStack

log = logging.getLogger(__name__)

SPARE_SLOTS = 2           # band buffers per file beyond one per worker: being hashed or written
PAGE = 4096


@dataclass
class BandWork:
    """A band's two stages in a worker: ``prepare(k, scratch)`` (the merge: anything that does not write the
    slots) and ``encode(k, prepared)`` (fills band k of every file's slot); ``scratch`` is the worker's own dict."""

    prepare: Callable[[int, dict], Any]
    encode: Callable[[int, Any], None]
    touch: Callable[[int], None] | None = None      # map band k's slot pages (while it waits for the first band)


@dataclass
class _Schedule:
    """What is done (guarded by ``cond``): bands handed to workers, computed, sealed and written per file."""

    n_bands: int
    n_files: int
    slots: int
    cond: threading.Condition = field(default_factory=threading.Condition)
    next_band: int = 0
    computed: list[bool] = field(default_factory=list)
    sealed: list[int] = field(default_factory=list)         # per file: bands sealed (hashed), in order
    sealing: list[bool] = field(default_factory=list)
    written: list[list[bool]] = field(default_factory=list)
    released: list[int] = field(default_factory=list)       # per file: bands written, in order (their slots free)
    first_encoded: threading.Event = field(default_factory=threading.Event)
    error: BaseException | None = None
    writes_pending: int = 0

    def __post_init__(self) -> None:
        self.computed = [False] * self.n_bands
        self.sealed = [0] * self.n_files
        self.sealing = [False] * self.n_files
        self.written = [[False] * self.n_bands for _ in range(self.n_files)]
        self.released = [0] * self.n_files

    def pick(self) -> tuple[str, int, int] | None:
        """The next task (under ``cond``): a file's next band to seal when computed and the slot its tail goes to
        is free; else the next band to compute when its slot is free in every file; None: nothing now."""
        for f in range(self.n_files):
            k = self.sealed[f]
            if (not self.sealing[f] and k < self.n_bands and self.computed[k]
                    and self.released[f] > k + 1 - self.slots):
                self.sealing[f] = True
                return "seal", f, k
        k = self.next_band
        if k < self.n_bands and min(self.released) > k - self.slots:
            self.next_band += 1
            return "compute", -1, k
        return None

    @property
    def finished(self) -> bool:
        return self.next_band == self.n_bands and min(self.sealed) == self.n_bands

    def wrote(self, f: int, k: int) -> None:
        """Band ``k`` of file ``f`` is on disk (under ``cond``)."""
        self.written[f][k] = True
        while self.released[f] < self.n_bands and self.written[f][self.released[f]]:
            self.released[f] += 1
        self.writes_pending -= 1


class BandPipeline:
    """Run ``work`` over ``n_bands`` bands of ``streams`` (ring mode: a band's slot is reused once it is written in
    every stream) on ``workers`` threads (the caller's included), the writes on ``io`` (an executor)::

        BandPipeline(n_bands, streams, BandWork(prepare, encode), io=pool, workers=2).run(cancel)
    """

    def __init__(self, n_bands: int, streams: Sequence[TiffStream], work: BandWork, *, io: Executor, workers: int):
        self.streams = list(streams)
        self.work = work
        self.io = io
        self.workers = max(1, int(workers))
        self.state = _Schedule(n_bands, len(self.streams), min(s.slots for s in self.streams))

    def run(self, cancel: CancelToken | None = None) -> None:
        """Every band computed, sealed and written (raises the first error or Cancelled, after the writes in
        flight have ended)."""
        st = self.state
        threads = [threading.Thread(target=self._worker, args=(cancel,), name=f"band-{i + 1}", daemon=True)
                   for i in range(self.workers - 1)]
        for t in threads:
            t.start()
        self._worker(cancel)
        for t in threads:
            t.join()
        with st.cond:
            st.cond.wait_for(lambda: st.writes_pending == 0)
        if st.error is not None:
            raise st.error

    def _worker(self, cancel: CancelToken | None) -> None:
        st = self.state
        scratch: dict = {}
        while True:
            with st.cond:
                while (task := None if st.error is not None or st.finished else st.pick()) is None:
                    if st.error is not None or st.finished:
                        st.cond.notify_all()
                        return
                    st.cond.wait()
            try:
                kind, f, k = task
                if kind == "seal":
                    self._seal(f, k)
                else:
                    self._compute(k, scratch, cancel)
            except BaseException as exc:  # noqa: BLE001 - handed to run(), which raises it in the caller's thread
                with st.cond:
                    st.error = st.error or exc
                    st.cond.notify_all()
                st.first_encoded.set()          # a worker waiting for the first band goes on, and stops
                return

    def _compute(self, k: int, scratch: dict, cancel: CancelToken | None) -> None:
        st = self.state
        check(cancel)
        prepared = self.work.prepare(k, scratch)
        if k:
            if self.work.touch is not None and not st.first_encoded.is_set():
                self.work.touch(k)                  # the page faults its encoding would take, while it waits
            st.first_encoded.wait()
            if st.error is not None:
                return
        check(cancel)
        self.work.encode(k, prepared)
        if not k:
            st.first_encoded.set()
        with st.cond:
            st.computed[k] = True
            st.cond.notify_all()

    def _seal(self, f: int, k: int) -> None:
        st = self.state
        job = self.streams[f].ring_seal(k)
        with st.cond:
            st.sealed[f] += 1
            st.sealing[f] = False
            st.writes_pending += 1
            if job is None:
                st.wrote(f, k)
            st.cond.notify_all()
        if job is not None:
            self.io.submit(self._write, f, k, job)

    def _write(self, f: int, k: int, job: tuple[memoryview, int]) -> None:
        st = self.state
        try:
            self.streams[f].ring_write(*job)
        except BaseException as exc:  # noqa: BLE001 - handed to run()
            with st.cond:
                st.error = st.error or exc
        with st.cond:
            st.wrote(f, k)
            st.cond.notify_all()


def ring_slots(workers: int) -> int:
    """Band buffers per file for ``workers``: one band being computed per worker, SPARE_SLOTS being sealed or
    written (fewer and the workers wait for the disk; 24 MP: 2.3 MB each)."""
    return max(1, workers) + SPARE_SLOTS


def open_all(openers: dict[str, Callable[[], TiffStream]], io: Executor, opened: ExitStack) -> dict[str, TiffStream]:
    """Every stream made at once on ``io`` (a TIFF's header and its buffers' pages take ~10 ms each) and entered
    into ``opened`` (so an error aborts them); the first error is raised after all have ended."""
    futures = {k: io.submit(make) for k, make in openers.items()}
    out: dict[str, TiffStream] = {}
    first: BaseException | None = None
    for k, fut in futures.items():
        try:
            out[k] = opened.enter_context(fut.result())
        except Exception as exc:  # noqa: BLE001 - the others are entered (and aborted) before it is raised
            first = first or exc
    if first is not None:
        raise first
    return out


def close_all(streams: Sequence[TiffStream], io: Executor) -> None:
    """Close every stream at once on ``io`` (each: its last block, fsync, rename, folder fsync); the first error
    is raised after all have ended."""
    futures = [io.submit(s.close) for s in streams]
    errors = [f.exception() for f in futures]
    first = next((e for e in errors if e is not None), None)
    if first is not None:
        raise first


def encode_master(stack: MasterStack, enc: DeliveryEncoder, xyz: TiffStream, rgb: Sequence[TiffStream],
                  chans: Sequence[TiffStream], *, io: Executor, cancel: CancelToken | None = None,
                  workers: int | None = None) -> None:
    """Every band of a full-resolution original (``stack``) encoded by ``enc`` into the streams (ring mode, the
    same ``band_rows``: the XYZ, the RGB spaces in ``enc.spaces`` order, the lights' camera RGB), each band merged
    and encoded by one worker (:meth:`MasterStack.mosaic_band_into`, :meth:`DeliveryEncoder.encode_mosaic`), then
    every stream closed (:func:`close_all`)."""
    H, rows = stack.height, xyz.band_rows
    streams = [xyz, *rgb, *chans]

    def prepare(k: int, scratch: dict) -> Any:
        return stack.mosaic_band_into(k * rows, min(rows, H - k * rows), scratch)

    def encode(k: int, mosaic: Any) -> None:
        enc.encode_mosaic(k * rows, xyz.ring_band(k), [s.ring_band(k) for s in rgb], [s.ring_band(k) for s in chans],
                          mosaic=mosaic, p0=HALO, cfa=stack.cfa_index, in_thread=True)
    def touch(k: int) -> None:
        for s in streams:
            s.ring_band(k).reshape(-1).view(np.uint8)[::PAGE] = 0
    work = BandWork(prepare, encode, touch)
    BandPipeline(-(-H // rows), streams, work, io=io, workers=workers or enc.threads).run(cancel)
    close_all(streams, io)
