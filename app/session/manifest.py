"""The lines of a session's ``manifest.jsonl`` and what defines a session's frames.

Line kinds (one JSON object per line; a line without ``kind`` is a frame, as written by every version):

* frame    :class:`SessionEntry`  one recorded raw file (name, sha256, size, step, light, camera settings ...)
* dose     :class:`DoseRecord`    one lit period: the light (exact levels) and its on-time, written as it ends
* set_aside :class:`SetAside`     a frame found missing or damaged on resume: its file moved to ``damaged/``
  (never deleted) and its step no longer counted as done

Readers written before a kind existed skip its lines as unreadable (they lack a frame's fields), without
failing. Every field is type-checked: a line that is valid JSON but not an object, or has a field of the
wrong type, is skipped and reported like a torn line (:func:`parse_line` raises ``ValueError``).
"""
from __future__ import annotations

import errno
import json
import logging
import math
import re
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from dualrgb.drivers.camera.base import Camera

from dualrgb.common.strict_json import dumps as strict_dumps

log = logging.getLogger(__name__)

KIND_FRAME, KIND_DOSE, KIND_SET_ASIDE = "frame", "dose", "set_aside"
_SHA256 = re.compile(r"^[0-9a-f]{64}$")


def _check(data: dict, name: str, types: tuple, *, optional: bool = False) -> Any:
    value = data.get(name)
    if value is None and optional:
        return None
    if isinstance(value, bool) and bool not in types or not isinstance(value, types):
        wanted = " or ".join(t.__name__ for t in types) + (" or null" if optional else "")
        raise ValueError(f"field {name!r} is {type(value).__name__} {value!r:.40}, expected {wanted}")
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"field {name!r} is {value}, expected a finite number")
    return value


def _file_name(data: dict, name: str = "file") -> str:
    value = _check(data, name, (str,))
    if not value or value != value.strip() or "/" in value or "\\" in value or value in (".", ".."):
        raise ValueError(f"field {name!r} is {value!r}, expected a plain file name inside the session folder")
    return value


def check_light(value: Any) -> dict | None:
    """A light dict {"name", "leds": [1-based ints], "levels": [numbers]} or None; ValueError otherwise."""
    if value is None:
        return None
    if not isinstance(value, dict):
        raise ValueError(f"field 'light' is {type(value).__name__}, expected an object")
    leds, levels = value.get("leds"), value.get("levels", [])
    if not isinstance(leds, list) or not all(isinstance(n, int) and not isinstance(n, bool) for n in leds):
        raise ValueError("field 'light.leds' must be a list of LED numbers")
    if not isinstance(levels, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                               and math.isfinite(v) for v in levels):
        raise ValueError("field 'light.levels' must be a list of numbers")
    return value


@dataclass
class SessionEntry:
    """One recorded raw file, as one line of manifest.jsonl."""

    seq: int
    file: str                                   # name inside the session folder
    role: str
    sha256: str
    size: int
    step_id: str | None = None
    exposure_s: float | None = None
    iso: int | None = None
    aperture: float | None = None
    camera: str = ""
    camera_filename: str = ""                   # name the camera gave the file (DSC_0001.NEF)
    light: dict | None = None                # {"name", "leds": [1-based], "levels": [0..1]}
    sphere_temperature_c: float | None = None
    settings: dict = field(default_factory=dict)   # camera settings at capture time
    captured_at: str = ""                       # ISO 8601 UTC
    recorded_at: str = ""
    meta: dict = field(default_factory=dict)    # anything else the sequence wants to keep (target, ev, ...)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> SessionEntry:
        """An entry from a manifest object; ``ValueError`` naming the field when a type is wrong."""
        if not isinstance(data, dict):
            raise ValueError(f"expected a JSON object, found {type(data).__name__}")
        number = (int, float)
        seq, size = _check(data, "seq", (int,)), _check(data, "size", (int,))
        if seq < 1 or size < 0:
            raise ValueError(f"seq {seq} / size {size}: expected seq >= 1 and size >= 0")
        sha = _check(data, "sha256", (str,))
        if not _SHA256.match(sha):
            raise ValueError(f"field 'sha256' is {sha!r:.20}, expected 64 hex digits")
        for name in ("exposure_s", "aperture", "sphere_temperature_c", "iso"):
            _check(data, name, number, optional=True)
        for name in ("step_id", "camera", "camera_filename", "captured_at", "recorded_at"):
            _check(data, name, (str,), optional=True)
        for name in ("settings", "meta"):
            _check(data, name, (dict,), optional=True)
        _check(data, "role", (str,))
        check_light(data.get("light"))
        known = set(cls.__dataclass_fields__)
        kwargs = {k: v for k, v in data.items() if k in known and v is not None}
        kwargs["file"] = _file_name(data)
        kwargs["step_id"] = data.get("step_id")
        extra = {k: v for k, v in data.items() if k not in known and k != "kind"}
        entry = cls(**kwargs)
        if extra:
            entry.meta = {**extra, **entry.meta}
        return entry

    @property
    def light_name(self) -> str:
        return (self.light or {}).get("name", "") if self.light else ""

    def exposure(self) -> float:
        """The frame's exposure time (s); ``ValueError`` naming the file where the manifest line has none."""
        if self.exposure_s is None:
            raise ValueError(f"{self.file}: the manifest records no exposure time for this frame (expected "
                             "'exposure_s' in seconds)")
        return float(self.exposure_s)


@dataclass
class DoseRecord:
    """One lit period: ``light`` (exact levels) on for ``on_s`` seconds, for ``step_id`` when a frame's."""

    light: dict
    on_s: float
    step_id: str | None = None
    at: str = ""
    meta: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"kind": KIND_DOSE, **asdict(self)}

    @classmethod
    def from_dict(cls, data: dict) -> DoseRecord:
        light = check_light(data.get("light"))
        if light is None:
            raise ValueError("dose line without a light")
        on_s = _check(data, "on_s", (int, float))
        if on_s < 0:
            raise ValueError(f"field 'on_s' is {on_s}, expected >= 0 s")
        return cls(light, float(on_s), _check(data, "step_id", (str,), optional=True),
                   _check(data, "at", (str,), optional=True) or "", _check(data, "meta", (dict,), optional=True)
                   or {})


@dataclass
class SetAside:
    """Frame ``seq`` was missing or damaged; its file (if any) now lies at ``moved_to`` (relative path)."""

    seq: int
    file: str
    reason: str
    moved_to: str | None = None
    step_id: str | None = None
    at: str = ""

    def to_dict(self) -> dict:
        return {"kind": KIND_SET_ASIDE, **asdict(self)}

    @classmethod
    def from_dict(cls, data: dict) -> SetAside:
        return cls(_check(data, "seq", (int,)), _file_name(data), _check(data, "reason", (str,)),
                   _check(data, "moved_to", (str,), optional=True), _check(data, "step_id", (str,), optional=True),
                   _check(data, "at", (str,), optional=True) or "")


ManifestLine = SessionEntry | DoseRecord | SetAside
_KINDS: dict[str, Callable[[dict], ManifestLine]] = {
    KIND_FRAME: SessionEntry.from_dict, KIND_DOSE: DoseRecord.from_dict, KIND_SET_ASIDE: SetAside.from_dict}


def parse_line(data: Any) -> ManifestLine:
    """The record of one decoded manifest line; ``ValueError`` for anything that is not a valid one."""
    if not isinstance(data, dict):
        raise ValueError(f"expected a JSON object, found {type(data).__name__} {json_preview(data)}")
    kind = data.get("kind", KIND_FRAME)
    if kind not in _KINDS:
        raise ValueError(f"unknown line kind {kind!r:.30}")
    return _KINDS[kind](data)


def json_preview(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 30 else text[:27] + "..."


# ---- errors, checks, JSON ------------------------------------------------------------------------------

class SessionError(OSError):
    """A session problem with a one-line message (disk full, not a session folder, file missing...)."""

    def __init__(self, code: int | None, message: str):
        super().__init__(code or errno.EIO, message)
        self.message = message

    def __str__(self) -> str:
        return self.message


class SessionLockedError(SessionError):
    """Another process writes this session; ``holder`` is its {pid, host, since, program}."""

    def __init__(self, message: str, holder: dict):
        super().__init__(errno.EBUSY, message)
        self.holder = holder


class DefinitionMismatch(SessionError):
    """A resume asked for frames defined differently from the session's; ``differences`` lists them all."""

    def __init__(self, message: str, differences: list[str]):
        super().__init__(errno.EINVAL, message)
        self.differences = differences


class DamagedFramesError(SessionError):
    """Recorded frames are missing or do not match their sha256; ``files`` names them."""

    def __init__(self, message: str, files: list[str]):
        super().__init__(errno.EIO, message)
        self.files = files


@dataclass
class VerifyReport:
    ok: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    corrupted: list[str] = field(default_factory=list)      # sha256 or size mismatch
    orphans: list[str] = field(default_factory=list)        # complete files that no manifest line names
    skipped_lines: list[int] = field(default_factory=list)  # 1-based manifest lines that could not be parsed
    set_aside: list[str] = field(default_factory=list)      # frames moved to damaged/ (their steps re-shot)

    @property
    def valid(self) -> bool:
        return not self.missing and not self.corrupted

    def summary(self) -> str:
        return (f"{len(self.ok)} ok, {len(self.missing)} missing, {len(self.corrupted)} corrupted, "
                f"{len(self.orphans)} orphan files, {len(self.skipped_lines)} unreadable manifest lines, "
                f"{len(self.set_aside)} set aside")


def now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def json_default(obj: Any) -> Any:
    if hasattr(obj, "to_dict"):
        return obj.to_dict()
    if hasattr(obj, "__dataclass_fields__"):
        return asdict(obj)
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot store {type(obj).__name__} in the session manifest")


def normalise(value: Any) -> Any:
    """``value`` as it reads back from JSON (tuples to lists, dataclasses to dicts)."""
    return json.loads(strict_dumps(value, default=json_default))


def read_manifest(path: Path) -> tuple[list, list[int]]:
    """The records of a manifest file and the 1-based numbers of the lines skipped as unreadable (a torn last
    line, a valid JSON value that is not a record, a field of the wrong type); never fails on a line."""
    lines_out: list = []
    skipped: list[int] = []
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise SessionError(errno.ENOENT, f"{path}: manifest missing") from None
    except OSError as exc:
        raise SessionError(exc.errno, f"{path}: cannot read the manifest ({exc.strerror or exc})") from exc
    lines = raw.split(b"\n")
    last_index = len(lines) - 1
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            lines_out.append(parse_line(json.loads(line)))
        except (ValueError, TypeError, UnicodeDecodeError, RecursionError) as exc:
            skipped.append(i + 1)
            where = "last line (truncated by an interrupted write)" if i == last_index else f"line {i + 1}"
            log.warning("%s: skipping unreadable %s: %s", path, where, exc)
    return lines_out, skipped


# ---- what defines a session's frames -------------------------------------------------------------------

def _flatten(value: Any, prefix: str, out: dict) -> None:
    if isinstance(value, dict):
        if not value and prefix:
            out[prefix] = {}
        for k, v in value.items():
            _flatten(v, f"{prefix}.{k}" if prefix else str(k), out)
    else:
        out[prefix] = value


def definition_differences(stored: dict, wanted: dict) -> list[str]:
    """Human-readable differences between two session definitions, by dotted key, e.g.
    ``mode: session 'reflective', this run 'transmissive'``. Keys only one side has are differences too."""
    a: dict[str, Any] = {}
    b: dict[str, Any] = {}
    _flatten(stored, "", a)
    _flatten(wanted, "", b)
    out = []
    for key in sorted(set(a) | set(b)):
        if key not in a:
            out.append(f"{key}: not in the session, this run {json_preview(b[key])}")
        elif key not in b:
            out.append(f"{key}: session {json_preview(a[key])}, not in this run")
        elif a[key] != b[key]:
            out.append(f"{key}: session {json_preview(a[key])}, this run {json_preview(b[key])}")
    return out


def light_definition(light: Any, name: str = "") -> dict:
    """A light as it defines frames: name, LEDs and exact (unrounded) levels."""
    return {"name": name or getattr(light, "name", ""), "leds": [int(n) for n in light.leds],
            "levels": [float(v) for v in light.levels]}


def image_area_definition(camera: Camera) -> dict:
    """``{"image_area": ...}``: the frame size and sensor area the camera reports (Camera.image_area), a top-level
    item of every session's definition, so a resume with another frame size or crop is refused at once; ``{}``
    for a camera that says nothing."""
    area = getattr(camera, "image_area", None)
    text = str(area()) if callable(area) else ""
    return {"image_area": text} if text else {}


def camera_definition(camera: Camera) -> dict:
    """A camera's identity and the settings that change its frames (model, ISO, aperture, quality; the world a
    simulated camera reports it renders)."""
    s = camera.settings()
    summary = {}
    try:
        summary = camera.config_summary()
    except (RuntimeError, OSError, ValueError):   # identity is best effort; such a camera is named by class
        summary = {}
    out = {"model": str(summary.get("camera") or getattr(camera, "name", type(camera).__name__)),
           "serial": str(summary.get("serial", "")), "iso": s.iso, "aperture": s.aperture,
           "image_quality": s.image_quality}
    if summary.get("world"):
        out["world"] = str(summary["world"])
    return out
