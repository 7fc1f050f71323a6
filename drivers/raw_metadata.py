"""What a raw file says about its shot, without keeping its pixels: format, camera make, model and serial, exposure,
ISO, aperture, capture time, mosaic size, CFA and the black and white levels (``dualrgb import`` checks a folder of
raw files with it before anything is written).

Every field comes from the file. LibRaw (rawpy) reads the mosaic's layout, the levels, exposure, ISO, aperture and
the capture time of every format it knows (NEF, CR2, CR3, ARW, DNG, IIQ, ...), and a file that is not a 2x2 Bayer
mosaic (a film scanner's RGB NEF, a linear DNG, X-Trans) is refused in one line, as :func:`drivers.raw.load_raw`
refuses it. LibRaw does not give the body's serial number or the make and model of every format: those come from
the TIFF tags of TIFF-based raws (DNG ``CameraSerialNumber``, EXIF ``BodySerialNumber``) and from exiftool when it
is installed (:func:`exiftool_tags`: one process for a whole folder; its ``SerialNumber`` reads the maker notes of
NEF, CR2, CR3, ARW ...). A field no source has stays empty (None or ''): the caller decides whether it is needed.

References
----------
Adobe, *Digital Negative (DNG) Specification* 1.4.0.0: CameraSerialNumber (50735). CIPA DC-008, *Exif 2.3*:
BodySerialNumber (42033), SubSecTimeOriginal (37521).
"""
from __future__ import annotations

import json
import logging
import shutil
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from dualrgb.drivers.raw import (
    _TIFF_ERRORS,
    PathLike,
    RawFileError,
    _detect_format,
    _letter,
    _quiet_tiff_log,
    _read_head,
    _tiff_data_end,
    _tiff_make_model,
    bayer_pattern,
    libraw_open,
)

log = logging.getLogger(__name__)

EXIFTOOL_TAGS = ("Make", "Model", "SerialNumber", "InternalSerialNumber", "ExposureTime", "ISO", "FNumber",
                 "DateTimeOriginal", "SubSecTimeOriginal")
EXIFTOOL_TIMEOUT_S = 600.0          # a hang guard for a folder of hundreds of files, far above normal
_SERIAL_TAGS = (50735, 42033)       # DNG CameraSerialNumber (IFD0), EXIF BodySerialNumber (EXIF IFD)


@dataclass(frozen=True)
class RawMetadata:
    """One raw file's shot and sensor as the file states them (empty where it does not)."""

    path: Path
    format: str
    make: str
    model: str
    serial: str
    exposure_s: float | None
    iso: float | None
    aperture: float | None
    captured_at: datetime | None        # the camera's clock (no time zone: cameras store none)
    width: int
    height: int
    cfa: str                            # 'RGGB', ...
    black_levels: tuple[int, ...]
    white_level: int
    extra: dict = field(default_factory=dict)     # "signal": the mean above black, fraction of black..white

    @property
    def camera(self) -> str:
        """'Make Model' without repeating the make when the model starts with it (as drivers.raw.RawFrame)."""
        make, model = self.make.strip(), self.model.strip()
        if make and model.lower().startswith(make.split()[0].lower()):
            return model
        return " ".join(p for p in (make, model) if p)


def _positive(value: Any) -> float | None:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return None
    return v if v > 0 else None


def _tiff_serial(path: Path, head: bytes) -> str:
    """The body serial of a TIFF-based raw (DNG CameraSerialNumber in IFD0, EXIF BodySerialNumber), else ''."""
    if head[:4] not in (b"II*\x00", b"MM\x00*"):
        return ""
    try:
        import tifffile

        with tifffile.TiffFile(path) as tif:
            tags = tif.pages.first.tags
            found = tags.get(_SERIAL_TAGS[0])
            if found is not None:
                return str(found.value).strip("\x00 ")
            exif = tags.get(34665)
            value = exif.value.get("BodySerialNumber") if exif is not None and isinstance(exif.value, dict) else None
            return str(value).strip("\x00 ") if value else ""
    except _TIFF_ERRORS as exc:
        log.debug("no serial from %s: %s", path, exc)
        return ""


def _libraw_fields(p: Path, head: bytes) -> dict[str, Any]:
    with libraw_open(p, head) as raw:
        pattern, color_desc = bayer_pattern(raw, p)
        other, sizes = raw.other, raw.sizes
        black, white = float(np.mean(raw.black_level_per_channel)), float(raw.white_level)
        sample = raw.raw_image_visible
        signal = (float(sample.mean(dtype=np.float64)) - black) / max(white - black, 1.0) if sample.size else 0.0
        stamp = other.timestamp if isinstance(other.timestamp, datetime) else None
        return {"cfa": "".join(_letter(color_desc, int(i)) for i in pattern.ravel()),
                "black_levels": tuple(int(b) for b in raw.black_level_per_channel),
                "white_level": int(raw.white_level), "exposure_s": _positive(other.shutter_speed),
                "iso": _positive(other.iso_speed), "aperture": _positive(other.aperture),
                "captured_at": stamp if stamp is not None and stamp.year > 1970 else None,
                "width": int(sizes.width), "height": int(sizes.height), "extra": {"signal": signal}}


def exif_time(text: Any, subsec: Any = None) -> datetime | None:
    """A capture time as exiftool prints EXIF's ``YYYY:MM:DD HH:MM:SS`` (with ``SubSecTimeOriginal``'s digits)."""
    if not isinstance(text, str) or not text.strip():
        return None
    try:
        when = datetime.strptime(text.strip()[:19], "%Y:%m:%d %H:%M:%S")
    except ValueError:
        return None
    digits = "".join(ch for ch in str(subsec or "") if ch.isdigit())[:6]
    return when.replace(microsecond=int(digits.ljust(6, "0"))) if digits else when


def _merged(libraw: dict[str, Any], tool: dict[str, Any]) -> dict[str, Any]:
    """LibRaw's fields, exiftool's over them where it has them: its exposure time and f-number are the files'
    exact rationals (LibRaw's are single-precision floats), its capture time has the sub-second."""
    out = dict(libraw)
    for key, tag in (("exposure_s", "ExposureTime"), ("iso", "ISO"), ("aperture", "FNumber")):
        value = _positive(tool.get(tag))
        if value is not None:
            out[key] = value
    when = exif_time(tool.get("DateTimeOriginal"), tool.get("SubSecTimeOriginal"))
    if when is not None:                    # the camera's own clock, to the sub-second where it says it
        out["captured_at"] = when
    return out


def read_raw_metadata(path: PathLike, tool: dict[str, Any] | None = None) -> RawMetadata:
    """The metadata of one raw file (module docstring); ``tool``: exiftool's tags of it (:func:`exiftool_tags`),
    when the caller has them. RawFileError (one line naming the file) for a file that is missing, damaged, not a raw
    file or not a 2x2 Bayer mosaic."""
    p = Path(path)
    head = _read_head(p)
    tool = tool or {}
    with _quiet_tiff_log():
        data_end = _tiff_data_end(p, head)
        size = p.stat().st_size
        if data_end is not None and data_end > size:
            raise RawFileError(p, f"truncated or damaged: {size} bytes, but its image data runs to byte {data_end}")
        fields = _merged(_libraw_fields(p, head), tool)
        make, model = _tiff_make_model(p, head)
        serial = _tiff_serial(p, head)
        fmt = _detect_format(p, head)
    make = make or str(tool.get("Make") or "").strip()
    model = model or str(tool.get("Model") or "").strip()
    serial = serial or str(tool.get("SerialNumber") or tool.get("InternalSerialNumber") or "").strip()
    return RawMetadata(path=p, format=fmt, make=make, model=model, serial=serial, **fields)


def exiftool_tags(paths: Sequence[Path], *, executable: str | None = None) -> dict[Path, dict[str, Any]]:
    """exiftool's :data:`EXIFTOOL_TAGS` of every file in ``paths`` (numbers as numbers), by path, in one run;
    ``{}`` when exiftool is not installed or fails (logged: LibRaw's fields then stand alone)."""
    exe = executable or shutil.which("exiftool")
    if not exe or not paths:
        return {}
    args = [exe, "-json", "-n", "-q", "-q", "-charset", "filename=utf8", *(f"-{t}" for t in EXIFTOOL_TAGS), "--",
            *(str(p) for p in paths)]
    try:
        run = subprocess.run(args, capture_output=True, timeout=EXIFTOOL_TIMEOUT_S, check=False)
        rows = json.loads(run.stdout.decode("utf-8", errors="replace") or "[]")
    except (OSError, subprocess.SubprocessError, ValueError) as exc:
        log.warning("exiftool could not be run (%s): serial numbers come from the TIFF tags alone", exc)
        return {}
    by_name = {str(Path(p)): Path(p) for p in paths}
    out = {}
    for row in rows if isinstance(rows, list) else []:
        if isinstance(row, dict) and str(row.get("SourceFile")) in by_name:
            out[by_name[str(row["SourceFile"])]] = row
    return out


__all__ = ["EXIFTOOL_TAGS", "RawMetadata", "exif_time", "exiftool_tags", "read_raw_metadata"]
