"""Load camera raw files (NEF from the D610, DNG from the virtual lab) into a Bayer mosaic via rawpy/LibRaw.

``load_raw(path)`` returns a :class:`RawFrame`: the visible-area mosaic as uint16 (H, W), its 2x2 CFA pattern
('RGGB'), black level per channel, white level, camera make/model and exposure where the file has them.
``linear_demosaic(frame)`` gives linear camera RGB (no gamma, no white balance, no colour conversion, white
point left where the file puts it); ``superpixel(frame)`` gives the half-size R, mean(G1, G2), B image in
black-subtracted DN straight from the mosaic.

A file that is missing, empty, truncated, corrupt, not a raw file or not a 2x2 Bayer mosaic raises
:class:`RawFileError` with one line naming the file and the problem.
"""
from __future__ import annotations

import contextlib
import io
import logging
import os
import stat
import struct
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Union

import numpy as np

log = logging.getLogger(__name__)

PathLike = Union[str, "os.PathLike[str]"]

# First bytes of TIFF-based raws (NEF, DNG, CR2, ARW, ...): a LibRaw I/O error on such a file means the data
# ends early (truncated download/copy), on anything else that it is not a raw file at all.
_TIFF_MAGICS = (b"II*\x00", b"MM\x00*")
# what tifffile raises on damaged headers (struct.error on a 4-7 byte file, TypeError on a mangled tag type ...)
_TIFF_ERRORS = (ValueError, OSError, IndexError, KeyError, TypeError, struct.error, EOFError, OverflowError,
                MemoryError, RecursionError, AttributeError)


class RawFileError(ValueError):
    """A raw file that cannot be used, with a one-line message naming the file and the problem."""

    def __init__(self, path: PathLike, problem: str):
        super().__init__(f"{os.fspath(path)}: {problem}")
        self.path = Path(path)
        self.problem = problem


@dataclass(frozen=True)
class RawFrame:
    """One raw exposure as stored by the camera: the Bayer mosaic and what is needed to interpret it."""

    path: Path
    mosaic: np.ndarray                         # (H, W) uint16, visible area, raw DN (black not subtracted)
    pattern: np.ndarray                        # (2, 2) colour indices into color_desc for the top-left cell
    color_desc: str                            # LibRaw's colour names per index, e.g. 'RGBG' (index 3 = G2)
    black_levels: tuple[int, ...]              # per colour index (same indexing as color_desc)
    white_level: int                           # saturation DN
    make: str = ""
    model: str = ""
    exposure_s: float | None = None
    iso: float | None = None
    format: str = ""                           # 'DNG', 'NEF', ...
    extra: dict = field(default_factory=dict)

    @property
    def height(self) -> int:
        return int(self.mosaic.shape[0])

    @property
    def width(self) -> int:
        return int(self.mosaic.shape[1])

    @property
    def cfa_pattern(self) -> str:
        """The 2x2 CFA as a string in raster order, e.g. 'RGGB' (LibRaw's G2 shown as G)."""
        return "".join(_letter(self.color_desc, int(i)) for i in self.pattern.ravel())

    @property
    def colors(self) -> np.ndarray:
        """(H, W) uint8 colour index of every mosaic pixel (same indexing as ``color_desc``)."""
        reps = (-(-self.height // 2), -(-self.width // 2))
        return np.tile(self.pattern.astype(np.uint8), reps)[: self.height, : self.width]

    @property
    def camera(self) -> str:
        """'Make Model' without repeating the make when the model already starts with it."""
        make, model = self.make.strip(), self.model.strip()
        if make and model.lower().startswith(make.split()[0].lower()):
            return model
        return " ".join(p for p in (make, model) if p)

    def channels(self) -> list[tuple[str, tuple[int, int], int]]:
        """The four CFA positions as (name, (row, col) in the 2x2 cell, colour index), ordered R, G1, G2, B.

        Greens are numbered G1, G2 in raster order of the cell.
        """
        out = []
        greens = 0
        for r in range(2):
            for c in range(2):
                idx = int(self.pattern[r, c])
                letter = _letter(self.color_desc, idx)
                if letter == "G":
                    greens += 1
                    name = f"G{greens}"
                else:
                    name = letter
                out.append((name, (r, c), idx))
        order = {"R": 0, "G1": 1, "G2": 2, "B": 3}
        return sorted(out, key=lambda t: order.get(t[0], 9))

    def plane(self, name: str) -> np.ndarray:
        """The (H/2, W/2) sub-image of one CFA position ('R', 'G1', 'G2', 'B'), a view into the mosaic."""
        for n, (r, c), _ in self.channels():
            if n == name:
                return self.mosaic[r::2, c::2]
        raise KeyError(name)


def _letter(color_desc: str, idx: int) -> str:
    return color_desc[idx] if 0 <= idx < len(color_desc) else "?"


def _detect_format(path: Path, head: bytes) -> str:
    """A short format name: 'DNG' for files with a DNGVersion tag, else the extension (NEF, CR2, ...)."""
    if head[:4] in _TIFF_MAGICS:
        try:
            import tifffile

            with tifffile.TiffFile(path) as tif:
                if 50706 in tif.pages.first.tags:  # DNGVersion
                    return "DNG"
        except _TIFF_ERRORS as exc:          # TiffFileError is a ValueError
            log.debug("tifffile could not read %s: %s", path, exc)
    return path.suffix.lstrip(".").upper() or "raw"


def _tiff_make_model(path: Path, head: bytes) -> tuple[str, str]:
    """Make/Model from the first IFD of TIFF-based raws (rawpy does not expose them)."""
    if head[:4] not in _TIFF_MAGICS:
        return "", ""
    try:
        import tifffile

        with tifffile.TiffFile(path) as tif:
            tags = tif.pages.first.tags
            make = tags.get(271)
            model = tags.get(272)
            unique = tags.get(50708)  # DNG UniqueCameraModel
            make_s = str(make.value).strip("\x00 ") if make is not None else ""
            model_s = str(model.value).strip("\x00 ") if model is not None else ""
            if not model_s and unique is not None:
                model_s = str(unique.value).strip("\x00 ")
            return make_s, model_s
    except _TIFF_ERRORS as exc:
        log.debug("no make/model from %s: %s", path, exc)
        return "", ""


def _tiff_data_end(path: Path, head: bytes) -> int | None:
    """The largest offset + byte count of the image data in a TIFF-based raw (main IFDs and SubIFDs, where
    NEF keeps its raw data), or None when the file is not TIFF-based or tifffile cannot parse it.

    Checked before LibRaw reads the file: a truncated file is then reported as such, instead of LibRaw
    printing its own 'Unexpected end of file' to stderr and failing with a bare I/O error.
    """
    if head[:4] not in _TIFF_MAGICS:
        return None
    try:
        import tifffile

        end = 0
        with tifffile.TiffFile(path) as tif:
            stack = list(tif.pages)
            while stack:
                page = stack.pop()
                # a damaged file's two arrays may differ in length: the walk takes the pairs both give
                for off, cnt in zip(page.dataoffsets or (), page.databytecounts or (), strict=False):
                    end = max(end, int(off) + int(cnt))
                if getattr(page, "subifds", None):
                    stack.extend(page.pages or ())
        return end
    except _TIFF_ERRORS as exc:
        log.debug("tifffile could not walk %s: %s", path, exc)
        return None


@contextlib.contextmanager
def _quiet_tiff_log():
    """tifffile logs a warning per damaged tag; a damaged raw is reported once, by RawFileError."""
    logger = logging.getLogger("tifffile")
    previous = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(previous)


@contextlib.contextmanager
def _libraw_stderr(path: Path):
    """LibRaw prints some problems ('Unexpected end of file') to the C stderr: keep them for the debug log,
    so that a damaged file gives exactly the one line of its RawFileError."""
    try:
        saved = os.dup(2)
    except OSError:  # pragma: no cover - no stderr to protect
        yield
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            text = sink.read().decode(errors="replace").strip()
            if text:
                log.debug("LibRaw on %s: %s", path, text)


def _read_head(path: Path) -> bytes:
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise RawFileError(path, "no such file") from None
    except OSError as exc:
        raise RawFileError(path, f"cannot open: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode):
        raise RawFileError(path, "is a folder, expected a raw file (NEF/DNG)")
    if not stat.S_ISREG(mode):                 # a FIFO or a device would block the reader for ever
        raise RawFileError(path, "not a regular file (a pipe, socket or device), expected a raw file (NEF/DNG)")
    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
    except OSError as exc:
        raise RawFileError(path, f"cannot open: {exc.strerror or exc}") from exc
    if not head:
        raise RawFileError(path, "file is empty")
    return head


@contextlib.contextmanager
def libraw_open(p: Path, head: bytes) -> Iterator[Any]:
    """The open rawpy file of ``p`` (LibRaw's stderr kept for the debug log); whatever LibRaw, the OS or rawpy raise
    on a bad file becomes one RawFileError naming ``p`` (``head``: its first bytes, to tell a truncated TIFF)."""
    import rawpy

    try:
        with _libraw_stderr(p), rawpy.imread(libraw_source(p)) as raw:
            yield raw
    except RawFileError:
        raise
    except rawpy.LibRawError as exc:
        raise RawFileError(p, _libraw_problem(exc, head)) from exc
    except OSError as exc:
        raise RawFileError(p, f"cannot read: {exc.strerror or exc}") from exc
    except (ValueError, TypeError, MemoryError, OverflowError) as exc:    # rawpy on nonsense sizes/values
        raise RawFileError(p, f"damaged raw data ({type(exc).__name__}: {exc})") from exc


def _libraw_problem(exc: Exception, head: bytes) -> str:
    import rawpy

    if isinstance(exc, rawpy.LibRawFileUnsupportedError):
        return "not a raw file LibRaw can read (unsupported format or damaged header)"
    if isinstance(exc, rawpy.LibRawIOError):
        if head[:4] in _TIFF_MAGICS:
            return "truncated or damaged: the raw data ends early (I/O error while reading it)"
        return "not a raw file (no raw/TIFF header; I/O error while reading)"
    if isinstance(exc, rawpy.LibRawDataError):
        return "damaged raw data (LibRaw data error)"
    if isinstance(exc, rawpy.LibRawTooBigError):
        return "raw image too big for LibRaw"
    msg = exc.args[0] if exc.args else exc
    if isinstance(msg, bytes):
        msg = msg.decode(errors="replace")
    return f"cannot read raw data ({type(exc).__name__}: {msg})"


def load_raw(path: PathLike) -> RawFrame:
    """Read a Bayer raw file into a :class:`RawFrame` (mosaic copied out; the file is closed on return)."""
    p = Path(path)
    head = _read_head(p)
    with _quiet_tiff_log():
        data_end = _tiff_data_end(p, head)
        size = p.stat().st_size
        if data_end is not None and data_end > size:
            raise RawFileError(p, f"truncated or damaged: {size} bytes, but its image data runs to byte {data_end}")
        return _load(p, head)


def _cfa_problem(pattern) -> str:
    """Why a file's CFA is not a 2x2 Bayer pattern; X-Trans is named only for X-Trans' own 6x6 layout."""
    shape = "none" if pattern is None else "x".join(map(str, np.asarray(pattern).shape))
    if pattern is not None and np.asarray(pattern).shape == (6, 6):
        return "an X-Trans sensor (6x6 CFA), not a 2x2 Bayer mosaic"
    return f"no 2x2 Bayer CFA pattern (found {shape}): a damaged file or a non-Bayer sensor"


def libraw_source(p: Path) -> Any:
    """The path as LibRaw takes it (UTF-8), or, for a path that is not UTF-8 (a folder name in another
    encoding: its undecodable bytes cannot be passed on), the file's bytes in memory."""
    name = os.fspath(p)
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        return io.BytesIO(p.read_bytes())
    return name


def bayer_pattern(raw: Any, p: Path) -> tuple[np.ndarray, str]:
    """The (2, 2) CFA pattern and LibRaw's colour names of an open rawpy file, or RawFileError (one line naming
    ``p``) for a file that is not a 2x2 RGB Bayer mosaic (a film scanner's RGB NEF, a linear DNG, X-Trans)."""
    import rawpy

    if raw.raw_type != rawpy.RawType.Flat:
        raise RawFileError(p, "not a Bayer mosaic (the file holds demosaiced/linear RGB data)")
    pattern = raw.raw_pattern
    color_desc = raw.color_desc.decode("ascii", errors="replace")
    if pattern is None or np.asarray(pattern).shape != (2, 2):
        raise RawFileError(p, _cfa_problem(pattern))
    pattern = np.array(pattern, dtype=np.uint8)
    letters = sorted(_letter(color_desc, int(i)) for i in pattern.ravel())
    if letters != ["B", "G", "G", "R"]:
        raise RawFileError(p, f"not an RGB Bayer sensor (CFA colours {''.join(letters)}), or a damaged file")
    return pattern, color_desc


def _load(p: Path, head: bytes) -> RawFrame:
    with libraw_open(p, head) as raw:
        pattern, color_desc = bayer_pattern(raw, p)
        mosaic = np.array(raw.raw_image_visible, dtype=np.uint16, copy=True)
        black = tuple(int(b) for b in raw.black_level_per_channel)
        white = int(raw.white_level)
        other = raw.other
        exposure = float(other.shutter_speed) if other.shutter_speed and other.shutter_speed > 0 else None
        iso = float(other.iso_speed) if other.iso_speed and other.iso_speed > 0 else None
        sizes = raw.sizes
    if mosaic.ndim != 2 or mosaic.size == 0:
        raise RawFileError(p, f"raw image has shape {mosaic.shape}, expected a 2-D mosaic")
    if white <= max(black):
        raise RawFileError(p, f"white level {white} is not above the black level {max(black)}")
    make, model = _tiff_make_model(p, head)
    frame = RawFrame(path=p, mosaic=mosaic, pattern=pattern, color_desc=color_desc, black_levels=black,
                     white_level=white, make=make, model=model, exposure_s=exposure, iso=iso,
                     format=_detect_format(p, head),
                     extra={"raw_size": (int(sizes.raw_height), int(sizes.raw_width)),
                            "margins": (int(sizes.top_margin), int(sizes.left_margin))})
    log.debug("loaded %s: %s %dx%d %s black %s white %d", p, frame.format, frame.width, frame.height,
              frame.cfa_pattern, black, white)
    return frame


# LibRaw settings for linear output: no gamma, no auto-brightening, unit white balance, camera RGB, no rotation,
# and adjust_maximum_thr=0 so LibRaw does not move the white point from the file's value (without it, it does).
LINEAR_POSTPROCESS = dict(gamma=(1, 1), no_auto_bright=True, output_bps=16, user_wb=[1.0, 1.0, 1.0, 1.0],
                          output_color=None, user_flip=0, adjust_maximum_thr=0.0)


def _linear_args() -> dict:
    import rawpy

    args = dict(LINEAR_POSTPROCESS)
    args["output_color"] = rawpy.ColorSpace.raw
    return args


def linear_demosaic(frame: RawFrame, *, half_size: bool = False,
                    algorithm: str | None = None) -> np.ndarray:
    """Linear camera RGB as uint16 (H, W, 3) from LibRaw, black subtracted and scaled so the white level
    maps to 65535.

    ``half_size=True`` gives the (H/2, W/2, 3) 'superpixel' image instead (R, mean of the greens, B per 2x2
    cell, no interpolation). ``algorithm`` names a rawpy.DemosaicAlgorithm member (default: LibRaw's AHD).
    The file at ``frame.path`` is read again (LibRaw demosaics from its own unpacked copy).
    """
    import rawpy

    args = _linear_args()
    if half_size:
        args["half_size"] = True
    if algorithm:
        try:
            args["demosaic_algorithm"] = rawpy.DemosaicAlgorithm[algorithm]
        except KeyError:
            names = ", ".join(a.name for a in rawpy.DemosaicAlgorithm)
            raise ValueError(f"demosaic algorithm {algorithm!r} unknown; expected one of {names}") from None
    head = _read_head(frame.path)
    try:
        with _libraw_stderr(frame.path), rawpy.imread(libraw_source(Path(frame.path))) as raw:
            return raw.postprocess(**args)
    except rawpy.LibRawError as exc:
        raise RawFileError(frame.path, _libraw_problem(exc, head)) from exc


def bayer_superpixel(mosaic: np.ndarray, cfa: str, *, black: Sequence[float] | None = None,
                     out: np.ndarray | None = None) -> np.ndarray:
    """(H/2, W/2, 3) float32 R, (G1 + G2) / 2, B of each 2x2 cell of a Bayer mosaic (an odd last row/column is
    dropped). ``cfa``: the cell's letters in raster order ('RGGB'); ``black``: the black level of each cell
    position (raster order), subtracted and clipped at 0. NaN in a green pixel makes that cell's G NaN (not
    silently the other green): invalid stays visible."""
    h2, w2 = mosaic.shape[0] // 2, mosaic.shape[1] // 2
    if out is None:
        out = np.empty((h2, w2, 3), dtype=np.float32)
    greens = []
    for k, letter in enumerate(cfa):
        r, c = divmod(k, 2)
        plane = mosaic[r: 2 * h2: 2, c: 2 * w2: 2]
        if black is not None:
            plane = np.maximum(plane.astype(np.float32) - np.float32(black[k]), 0.0)
        if letter == "R":
            out[..., 0] = plane
        elif letter == "B":
            out[..., 2] = plane
        else:
            greens.append(plane)
    np.add(greens[0], greens[1], out=out[..., 1], dtype=np.float32)
    out[..., 1] *= 0.5
    return out


def superpixel(frame: RawFrame, *, subtract_black: bool = True) -> np.ndarray:
    """(H/2, W/2, 3) float32 R, (G1+G2)/2, B per 2x2 cell in DN, black subtracted (clipped at 0) by default.

    Computed from the in-memory mosaic, so values are exact (LibRaw's half_size output is the same image
    rounded and scaled to 16 bit); an odd last row/column is dropped.
    """
    colours = [int(frame.pattern[r, c]) for r in range(2) for c in range(2)]
    cfa = "".join(_letter(frame.color_desc, idx) for idx in colours)
    black = [float(frame.black_levels[idx]) for idx in colours] if subtract_black else None
    return bayer_superpixel(frame.mosaic, cfa, black=black)
