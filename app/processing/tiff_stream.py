"""A TIFF written while its pixels are computed: tifffile writes the header (tags, ICC, XMP) of the known-shape
image, the pixel rows follow band by band from a writer thread, and the file appears atomically when complete.

Why hand-written: the four deliverables of a 24 MP original are ~184 MB of 16-bit pixels. Written whole after
the encoding (``tifffile.imwrite`` of each array), disk time adds to compute time, and copying them into the
page cache costs about as much CPU as the encoding itself (~1 GB/s on the 2-core bench machine: 0.19 s for
184 MB, then 0.08 s of fsync). Here

* tifffile writes everything but the pixels (``imwrite(data=None, shape, dtype, returnoffset=True)``: the
  same header, tags and data offset as for the array, so the file is byte for byte what ``imwrite`` of the whole
  array writes);
* the caller fills row bands in page-aligned buffers (``band()`` / ``commit()``: double-buffered), and each band
  goes to disk while the next one is computed;
* on Linux the bands are written with ``O_DIRECT`` (straight from the buffers to the disk: no page-cache copy),
  in whole 4 KiB blocks - the header bytes of the first block and the tail of each band are carried into the
  next write, the last block is padded and the file truncated to its size. Where the file system refuses
  ``O_DIRECT`` (tmpfs, some network file systems, other OSes) the same writes go through the page cache.

:class:`RawStream` streams a headerless raw file the same way (the data file of an ENVI spectral cube:
app.processing.envi_cube).

Ring mode (``slots`` > 2, :meth:`TiffStream.ring_band` / :meth:`TiffStream.ring_seal`): several threads fill
bands of one file in any order, each in a slot of its own, and a scheduler (app.processing.band_pipeline) seals
them in file order (the digest, the carried tail) and writes them where it likes; the bytes and the digest are
those of the double-buffered mode.

Fixity: with ``digest="sha256"`` the file's SHA-256 is computed from the bytes as they are written (the header
when tifffile has written it, then each write in file order: the writes of one file never overlap in time, each
band waits for the one before), so the checksum costs no second read of the file; :attr:`TiffStream.sha256` and
:attr:`TiffStream.size` give it after :meth:`TiffStream.close`.

Atomic like every output (common.atomic_files): the file is written as ``.<name>.<pid>.tmp`` beside the
target, fsynced once at the end, renamed over the target, the folder fsynced; any error removes the temp file,
leaves the previous file intact and raises a FileWriteError naming the target.
"""
from __future__ import annotations

import errno
import hashlib
import logging
import os
import threading
from collections.abc import Callable
from concurrent.futures import Executor, Future
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.common.atomic_files import fsync_dir, remove_quietly, temp_path, write_error

log = logging.getLogger(__name__)

BLOCK = 4096                              # O_DIRECT alignment of offsets, lengths and buffers (4 KiB sectors)
O_DIRECT = getattr(os, "O_DIRECT", 0)     # Linux only; 0 elsewhere = through the page cache


def aligned_empty(nbytes: int, touch: bool = True) -> np.ndarray:
    """A uint8 buffer of ``nbytes`` (rounded up to BLOCK) starting on a BLOCK boundary, its pages already mapped
    (``touch``).

    Touched here, every page is mapped before any write is in flight: a page first touched by the encoder while an
    O_DIRECT write pins the other buffer's pages waited for the process's memory-map lock, which made the first
    two bands of a delivery 2-5x slower (with 256-row bands, the spectral cube's 59 MB each: +0.25 s at 24 MP).
    The ring mode's slots are not touched (``touch=False``): their first bands are encoded on both cores, where
    the page faults cost less wall time than ~10 MB per file mapped by one thread before the first band (24 MP,
    kernel 6.18: no slower bands measured)."""
    n = -(-nbytes // BLOCK) * BLOCK
    raw = np.empty(n + BLOCK, np.uint8)
    if touch:
        raw[::BLOCK] = 0
    skip = (-raw.ctypes.data) % BLOCK
    return raw[skip: skip + n]


class _Output:
    """The temp file's descriptor: positional writes of whole blocks, O_DIRECT when the file system takes it."""

    def __init__(self, tmp: Path, direct: bool):
        self.tmp = tmp
        self.direct = bool(direct and O_DIRECT)
        self.fd = self._open()
        self._lock = threading.Lock()       # only where os.pwrite is missing (lseek + write)

    def _open(self) -> int:
        if self.direct:
            try:
                return os.open(self.tmp, os.O_WRONLY | O_DIRECT)
            except OSError as exc:
                if exc.errno != errno.EINVAL:
                    raise
                log.debug("%s: O_DIRECT refused, writing through the page cache", self.tmp)
                self.direct = False
        return os.open(self.tmp, os.O_WRONLY)

    def _buffered(self) -> None:
        """Fall back to the page cache for the rest of the file (a short or refused direct write)."""
        os.close(self.fd)
        self.direct = False
        self.fd = self._open()

    def pwrite(self, data: memoryview, pos: int) -> None:
        while len(data):
            try:
                if hasattr(os, "pwrite"):
                    n = os.pwrite(self.fd, data, pos)
                else:  # pragma: no cover - Windows
                    with self._lock:
                        os.lseek(self.fd, pos, os.SEEK_SET)
                        n = os.write(self.fd, data)
            except OSError as exc:
                if not (self.direct and exc.errno == errno.EINVAL):
                    raise
                self._buffered()
                continue
            if n <= 0:  # pragma: no cover - os.pwrite raises instead on real errors
                raise OSError(errno.EIO, "write returned 0")
            data, pos = data[n:], pos + n
            if len(data) and self.direct and n % BLOCK:  # pragma: no cover - short direct write: unaligned now
                self._buffered()

    def finish(self, size: int) -> None:
        os.ftruncate(self.fd, size)
        os.fsync(self.fd)

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


class TiffStream:
    """One TIFF of ``shape`` (rows, ...) and ``dtype`` filled band by band::

        with TiffStream(path, (H, W, 3), np.uint16, tifffile_kwargs, band_rows=64, executor=pool) as out:
            for r0 in range(0, H, 64):
                band = out.band(min(64, H - r0))      # (rows, W, 3) view into a page-aligned buffer
                band[...] = ...                       # compute the rows in place
                out.commit()                          # queued for the writer; the other buffer is next
        # leaving the block without error: the last block, ftruncate, fsync, rename, folder fsync

    ``tifffile_kwargs`` go to ``tifffile.imwrite`` (photometric, tags, ICC, ...; not the data). ``executor``:
    where the writes run (None: in the caller's thread). ``direct``: try O_DIRECT.
    """

    def __init__(self, path: Path, shape: tuple[int, ...], dtype: Any, tifffile_kwargs: dict, *, band_rows: int,
                 executor: Executor | None = None, direct: bool = True, digest: str | None = None,
                 exif: Callable[[int], bytes] | None = None, slots: int = 2):
        self.path = Path(path)
        self._closed = False
        self._exif = exif                         # the EXIF IFD at an offset (app.processing.exif), after the pixels
        self._trailer = b""                       # what follows the pixels: padding and the EXIF IFD
        self._hash = hashlib.new(digest) if digest else None
        self.sha256: str | None = None            # the file's digest (hex) after close, when one was asked for
        self.size = 0                             # the file's size in bytes after close
        self.shape = tuple(int(s) for s in shape)
        self.dtype = np.dtype(dtype)
        self.row_bytes = int(np.prod(self.shape[1:], dtype=np.int64)) * self.dtype.itemsize
        self.band_rows = max(1, min(int(band_rows), self.shape[0]))
        self._executor = executor
        self._tmp = temp_path(self.path)
        self._out: _Output | None = None
        self._pending: list[Future | None] = [None, None]
        self._rows_done = 0
        self._band: np.ndarray | None = None
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._offset, self._nbytes, head = self._write_header(tifffile_kwargs)
            self._out = _Output(self._tmp, direct)
        except (OSError, ValueError) as exc:
            self.abort()
            if isinstance(exc, OSError):
                raise write_error(exc, self.path) from exc
            raise
        self._pos = self._offset - len(head)                 # the file position of buffer byte 0
        size = max(len(head), BLOCK) + BLOCK + self.band_rows * self.row_bytes
        self._buffers = [aligned_empty(size, slots == 2) for _ in range(max(2, slots))]
        self._current = 0
        self._buffers[0][:len(head)] = np.frombuffer(head, np.uint8)
        self._carry = len(head)                             # bytes at the front of the current buffer

    @property
    def slots(self) -> int:
        """Band buffers (2: double-buffered; more in ring mode)."""
        return len(self._buffers)

    @property
    def direct(self) -> bool:
        """Whether the pixels go to disk with O_DIRECT (False: through the page cache)."""
        return bool(self._out and self._out.direct)

    def _write_header(self, kwargs: dict) -> tuple[int, int, bytes]:
        """tifffile's header, tags and an empty pixel area; (data offset, data bytes, the bytes of the data
        offset's block before it)."""
        import tifffile

        with open(self._tmp, "w+b") as fh:
            written = tifffile.imwrite(fh, shape=self.shape, dtype=self.dtype, returnoffset=True, **kwargs)
            if written is None:
                raise ValueError(f"{self.path}: tifffile reported no pixel area (expected one contiguous strip)")
            offset, nbytes = written
            if nbytes != self.shape[0] * self.row_bytes:
                raise ValueError(f"{self.path}: tifffile stores {nbytes} pixel bytes, expected "
                                 f"{self.shape[0] * self.row_bytes} contiguous ones")
            start = offset - offset % BLOCK
            fh.seek(0)
            header = bytearray(fh.read(offset))
            if self._exif is not None:
                self._link_exif(header, offset + nbytes)
            if self._hash is not None:
                self._hash.update(header[:start])       # the rest is hashed as it is written (_write)
            head = bytes(header[start:])
            if self._exif is not None:
                fh.seek(0)
                fh.write(header[:start])                # the linked IFD0 (the rest goes with the pixels)
            fh.truncate(offset)                     # tifffile's sparse end byte: the pixels will extend the file
        return offset, nbytes, head

    def _link_exif(self, header: bytearray, end: int) -> None:
        """Point IFD0's placeholder at the EXIF IFD that will follow the pixels (``end``: their end), and keep
        that IFD (word-aligned) as the file's trailer (app.processing.exif)."""
        from dualrgb.app.processing.exif import patch_placeholder

        assert self._exif is not None
        at = end + end % 2
        if not patch_placeholder(header, at):
            raise ValueError(f"{self.path}: no EXIF placeholder in the TIFF's first IFD")
        self._trailer = b"\0" * (at - end) + self._exif(at)

    def band(self, rows: int) -> np.ndarray:
        """The next ``rows`` rows to fill (a view valid until :meth:`commit`)."""
        if rows < 1 or rows > self.band_rows or self._rows_done + rows > self.shape[0]:
            raise ValueError(f"{self.path}: band of {rows} rows after {self._rows_done} of {self.shape[0]} "
                             f"(at most {self.band_rows} per band)")
        self._wait(self._current)
        buf = self._buffers[self._current]
        view = buf[self._carry: self._carry + rows * self.row_bytes].view(self.dtype)
        self._band = view.reshape((rows,) + self.shape[1:])
        return self._band

    def commit(self) -> None:
        """Queue the band's whole blocks for writing; its tail is carried to the front of the other buffer."""
        if self._band is None:
            raise ValueError(f"{self.path}: commit without a band")
        rows = self._band.shape[0]
        self._band = None
        self._rows_done += rows
        end = self._carry + rows * self.row_bytes
        whole = end - end % BLOCK
        cur, nxt = self._current, 1 - self._current
        self._wait(nxt)
        self._buffers[nxt][:end - whole] = self._buffers[cur][whole:end]
        if whole:
            self._submit(cur, self._buffers[cur][:whole].data, self._pos)
        self._pos += whole
        self._carry = end - whole
        self._current = nxt

    def ring_band(self, k: int) -> np.ndarray:
        """Ring mode: band ``k``'s rows (from ``k * band_rows``) to fill, in slot ``k % slots``, from any thread, once
        the slot is free (the band ``slots`` before it written, the one before it sealed: the caller's schedule)."""
        r0 = k * self.band_rows
        rows = min(self.band_rows, self.shape[0] - r0)
        if rows < 1:
            raise ValueError(f"{self.path}: band {k} starts after the last of {self.shape[0]} rows")
        front = (self._offset + r0 * self.row_bytes) % BLOCK    # the previous band's tail goes before it
        buf = self._buffers[k % len(self._buffers)]
        return buf[front: front + rows * self.row_bytes].view(self.dtype).reshape((rows,) + self.shape[1:])

    def ring_seal(self, k: int) -> tuple[memoryview, int] | None:
        """Ring mode, in band order: band ``k`` (filled) is added to the digest up to its last whole block, its tail
        carried to the front of the next slot; returns (the bytes, their file position) to write with
        :meth:`ring_write` (None: no whole block yet)."""
        r0 = k * self.band_rows
        if r0 != self._rows_done:
            raise ValueError(f"{self.path}: band {k} sealed after {self._rows_done} of {self.shape[0]} rows")
        rows = min(self.band_rows, self.shape[0] - r0)
        n = len(self._buffers)
        buf, nxt = self._buffers[k % n], self._buffers[(k + 1) % n]
        end = self._carry + rows * self.row_bytes
        whole = end - end % BLOCK
        nxt[:end - whole] = buf[whole:end]
        pos = self._pos
        self._rows_done += rows
        self._pos += whole
        self._carry = end - whole
        self._current = (k + 1) % n
        if not whole:
            return None
        data = buf[:whole].data
        if self._hash is not None:
            self._hash.update(data)
        return data, pos

    def ring_write(self, data: memoryview, pos: int) -> None:
        """Ring mode: write what :meth:`ring_seal` returned (from any thread; errors name the file)."""
        try:
            self._output().pwrite(data, pos)
        except OSError as exc:
            raise write_error(exc, self.path) from exc

    def _output(self) -> _Output:
        if self._out is None:                   # only after abort(): a closed stream takes no more rows
            raise ValueError(f"{self.path}: the TIFF stream was aborted")
        return self._out

    def _write(self, data: memoryview, pos: int, hashed: int | None = None) -> None:
        """Write ``data`` at ``pos`` and add its first ``hashed`` bytes (all by default) to the digest."""
        self._output().pwrite(data, pos)
        if self._hash is not None:
            self._hash.update(data if hashed is None else data[:hashed])

    def _submit(self, slot: int, data: memoryview, pos: int) -> None:
        if self._executor is None:
            self._guard(lambda: self._write(data, pos))
        else:
            self._pending[slot] = self._executor.submit(self._write, data, pos)

    def _wait(self, slot: int) -> None:
        fut, self._pending[slot] = self._pending[slot], None
        if fut is not None:
            self._guard(fut.result)

    def _guard(self, call: Callable[[], object]) -> None:
        try:
            call()
        except OSError as exc:
            self.abort()
            raise write_error(exc, self.path) from exc

    def close(self) -> Path:
        """Write the last block, truncate to the TIFF's size, fsync, rename over the target, fsync the folder (once:
        a second call returns the path)."""
        if self._closed:
            return self.path
        if self._rows_done != self.shape[0]:
            self.abort()
            raise ValueError(f"{self.path}: {self._rows_done} of {self.shape[0]} rows written")
        for slot in (0, 1):
            self._wait(slot)
        tail = self._carry + len(self._trailer)
        buf = self._buffers[self._current]
        if tail + BLOCK > len(buf):                     # a trailer longer than the buffer's spare block
            buf = aligned_empty(tail)
            buf[:self._carry] = self._buffers[self._current][:self._carry]
        buf[self._carry:tail] = np.frombuffer(self._trailer, np.uint8)
        padded = -(-tail // BLOCK) * BLOCK
        buf[tail:padded] = 0
        out = self._output()
        size = self._offset + self._nbytes + len(self._trailer)

        def finish() -> None:
            if tail:
                self._write(buf[:padded].data, self._pos, tail)
            out.finish(size)
            out.close()
            os.replace(self._tmp, self.path)
            fsync_dir(self.path.parent)
        self._guard(finish)
        self._closed = True
        self.size = size
        self.sha256 = self._hash.hexdigest() if self._hash is not None else None
        return self.path

    def abort(self) -> None:
        """Drop the temp file (the target keeps its previous content, if any)."""
        for slot in (0, 1):
            fut, self._pending[slot] = self._pending[slot], None
            if fut is not None:
                fut.cancel()
                try:
                    fut.result()
                except Exception:  # noqa: BLE001 - the first error is the one reported
                    pass
        if self._out is not None:
            self._out.close()
        remove_quietly(self._tmp)

    def __enter__(self) -> TiffStream:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


class RawStream(TiffStream):
    """A headerless raw file of ``shape`` and ``dtype`` (C order, the dtype's byte order) filled band by band
    exactly like :class:`TiffStream` (O_DIRECT where the file system takes it, atomic): e.g. an ENVI cube's data
    file, whose header is a separate text file."""

    def __init__(self, path: Path, shape: tuple[int, ...], dtype: Any, *, band_rows: int,
                 executor: Executor | None = None, direct: bool = True, digest: str | None = None):
        super().__init__(path, shape, dtype, {}, band_rows=band_rows, executor=executor, direct=direct,
                         digest=digest)

    def _write_header(self, kwargs: dict) -> tuple[int, int, bytes]:
        """No header: an empty temp file, the pixels from byte 0."""
        with open(self._tmp, "wb"):
            pass
        return 0, self.shape[0] * self.row_bytes, b""
