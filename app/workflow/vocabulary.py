"""The session vocabulary: one typed name for every role, subject, light, step and event, built by one function each.

What ties a capture to its processing lives here and nowhere else:

* :class:`Role` - why a frame was taken (dark, flat, target, original, crf, metering);
* :class:`Subject` - what lay on the stand (the training / test target, with or without the stand's ND
  filter, or an original by its identifier); ``Subject.key`` is the one string form (``"target:train"``,
  ``"target:test+nd"``, ``"original:ACC-123"``); in it an identifier's ``% / : # +`` are written ``%25 %2F %3A
  %23 %2B`` (:func:`key_name`), so no identifier can reach into the separators of keys and step ids (``ACC/1``
  is ``original:ACC%2F1``, never a step under ``original:ACC``);
* :func:`light_name` - the one name of a preset's light (``"dual-RGB reflective light 1"``), used for the
  sphere, the session manifest, the flats, the processing and the reports alike;
* :func:`step_id` - the manifest's step id of a frame (resume and re-shoot key on it);
* :class:`SequenceKind` and :class:`EventKind` - what a sequence is and what its progress events say.

Sessions written before this vocabulary (roles ``target-nd``, ``hdr``, ``hdr-nd``, ``object``, ``hdr-meter``;
lights ``<preset>-LS1``; subjects in ``meta["target"]`` / ``meta["subject"]``) still open: :func:`read_role`,
:func:`read_light_name` and :func:`subject_of` read the old strings.
"""
from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)

TAKE_SEPARATOR = "#take"
_KEY_ESCAPES = {c: f"%{ord(c):02X}" for c in "%/:#+"}     # '%' first: the escape itself
_KEY_ESCAPED = re.compile("|".join(re.escape(v) for v in _KEY_ESCAPES.values()), re.IGNORECASE)


class Role(StrEnum):
    """Why a frame was taken (the manifest's ``role``)."""

    DARK = "dark"              # lens cap on (master dark per exposure time, thesis 8.2.1)
    FLAT = "flat"              # open gate / white reference per light (eq 7.1, thesis 8.2.2)
    TARGET = "target"          # a colour target (training or test)
    ORIGINAL = "original"      # the artwork or film being digitised
    CRF = "crf"                # camera response / exposure-time linearity series
    METERING = "metering"      # auto-exposure and HDR metering frames (kept, never processed)
    REJECTED = "rejected"      # lit for less than its exposure (app.workflow.shooter): kept aside, never processed
    CSRF = "csrf"              # a monochromatic frame measuring the camera's spectral sensitivity (thesis 4.2)


class SubjectKind(StrEnum):
    TARGET = "target"
    ORIGINAL = "original"


class SequenceKind(StrEnum):
    """What a sequence does; :func:`app.workflow.sequences.build_sequence` makes one from a kind."""

    DARKS = "darks"
    FLATS = "flats"
    TARGET = "target"          # the target under each light at the calibration's base exposures
    HDR_TARGET = "hdr-target"  # the target with an HDR bracket per light
    ORIGINAL = "original"      # an original with the calibration's exposures (HDR when metering asks)


class EventKind(StrEnum):
    """The ``kind`` of an :class:`app.workflow.messages.ProgressEvent`."""

    PROGRESS = "progress"
    FRAME = "frame"            # a frame was saved in the session
    KEPT = "kept"              # a frame was already in the session and was kept (not shot again)
    REJECTED = "rejected"      # a frame not lit all through was set aside (never used) and its step shot again
    PROMPT = "prompt"          # a person must do something (place the target, cap the lens) and continue
    DONE = "done"
    CANCELLED = "cancelled"


TARGET_NAMES = ("train", "test")


@dataclass(frozen=True)
class Subject:
    """What lay on the stand: a colour target (``name`` 'train' or 'test') or an original (its identifier)."""

    kind: SubjectKind
    name: str
    nd: bool = False           # under the stand's ND filter (thesis 8.3: ND 2.0 over half the target)

    def __post_init__(self) -> None:
        if not self.name or not self.name.strip():
            raise ValueError(f"a {self.kind.value} needs a name (an original: its identifier)")
        if self.kind is SubjectKind.TARGET and self.name not in TARGET_NAMES:
            raise ValueError(f"target {self.name!r}: expected one of {', '.join(TARGET_NAMES)}")

    @classmethod
    def target(cls, name: str, nd: bool = False) -> Subject:
        return cls(SubjectKind.TARGET, name, nd)

    @classmethod
    def original(cls, identifier: str) -> Subject:
        return cls(SubjectKind.ORIGINAL, identifier.strip())

    @property
    def key(self) -> str:
        return f"{self.kind.value}:{key_name(self.name)}" + ("+nd" if self.nd else "")

    @property
    def role(self) -> Role:
        return Role.TARGET if self.kind is SubjectKind.TARGET else Role.ORIGINAL

    @property
    def place(self) -> str:
        """What the (virtual) stand is asked to hold: 'train', 'test' or 'original:<identifier>'."""
        return self.name if self.kind is SubjectKind.TARGET else f"original:{self.name}"

    @property
    def label(self) -> str:
        if self.kind is SubjectKind.ORIGINAL:
            return f"original {self.name}"
        what = "training target" if self.name == "train" else "test target"
        return what + (" under the ND 2.0 filter" if self.nd else "")

    @classmethod
    def parse(cls, key: str) -> Subject:
        """The subject of a key made by :attr:`key` (old keys such as 'hdr-nd:test' are read too)."""
        kind, sep, name = key.partition(":")
        if not sep:
            raise ValueError(f"subject {key!r}: expected 'target:train', 'target:test+nd' or 'original:<id>'")
        nd = name.endswith("+nd")
        name = name[:-3] if nd else name
        role, old_nd = read_role(kind)
        if role is Role.ORIGINAL:
            return cls.original(name_of_key(name + ("+nd" if nd else "")))
        if role is Role.TARGET:
            return cls.target(name, nd or old_nd)
        raise ValueError(f"subject {key!r}: {kind!r} is not a target or an original")

    def __str__(self) -> str:
        return self.key


def key_name(name: str) -> str:
    """A subject's name as it appears in keys and step ids: ``% / : # +`` escaped (``ACC/1`` -> ``ACC%2F1``)."""
    return "".join(_KEY_ESCAPES.get(c, c) for c in name)


def name_of_key(text: str) -> str:
    """The name that :func:`key_name` wrote as ``text`` (keys of sessions before the escaping read unchanged,
    unless an identifier held a '%' followed by one of the escapes' hex pairs)."""
    return _KEY_ESCAPED.sub(lambda m: chr(int(m.group(0)[1:], 16)), text)


# ---------------------------------------------------------------- lights
@dataclass(frozen=True)
class NamedLight:
    """A light of a preset with its one name (:func:`light_name`)."""

    name: str
    light: LightSource


def light_name(preset_name: str, number: int) -> str:
    """The one name of light ``number`` (1-based) of a preset: ``"<preset name> light <number>"``."""
    if number < 1:
        raise ValueError(f"light number {number}: expected 1, 2, ...")
    return f"{preset_name.strip() or 'preset'} light {number}"


def lights_of(preset: Any) -> list[NamedLight]:
    """The preset's lights with their names (the LightSource carries the same name)."""
    out = []
    for i, source in enumerate(preset.sources, start=1):
        name = light_name(preset.name, i)
        out.append(NamedLight(name, LightSource(source.leds, source.levels, name)))
    return out


def monochromatic_light(wavelength_nm: float) -> str:
    """The one name of a monochromator's light set to ``wavelength_nm``: ``"monochromatic 550 nm"``."""
    return f"monochromatic {float(wavelength_nm):g} nm"


_OLD_LIGHT = re.compile(r"^(?P<prefix>.*?)[-_ ]?LS(?P<n>\d+)$")


def read_light_name(text: str) -> str:
    """A light name from a session, old forms read: '<slug>-LS1' -> '<slug> light 1'; new names unchanged."""
    m = _OLD_LIGHT.match(text or "")
    if m:
        return light_name(m.group("prefix") or "preset", int(m.group("n")))
    return text or "light"


def format_exposure(seconds: float | None) -> str:
    """An exposure time as photographers read it ('1/60 s', '2 s'): the camera driver's own notation."""
    from dualrgb.drivers.camera.gphoto_labels import format_shutter

    return format_shutter(seconds)


# ---------------------------------------------------------------- steps
def exposure_key(t: float) -> str:
    """An exposure time as it appears in step ids (6 significant digits)."""
    return f"{t:.6g}"


def step_id(role: Role, *, subject: Subject | None = None, light: str | None = None,
            exposure_s: float | None = None, frame: int | None = None, take: int = 1) -> str:
    """The manifest step id of one frame: ``role[/subject][/light][/exposure][/frame][#takeN]``.

    A resumed sequence skips steps the session already has; a re-shoot records ``take`` 2, 3, ... and the
    latest take of a step is the one processed (:func:`latest_takes`).
    """
    parts = [Role(role).value]
    if subject is not None:
        parts.append(subject.key)
    if light is not None:
        parts.append(light)
    if exposure_s is not None:
        parts.append(exposure_key(exposure_s))
    if frame is not None:
        parts.append(str(frame))
    base = "/".join(parts)
    if take < 1:
        raise ValueError(f"take {take}: expected 1, 2, ...")
    return base if take == 1 else f"{base}{TAKE_SEPARATOR}{take}"


def split_take(step: str) -> tuple[str, int]:
    """(step id without its take suffix, take number)."""
    base, sep, n = (step or "").partition(TAKE_SEPARATOR)
    return base, int(n) if sep and n.isdigit() else 1


# ---------------------------------------------------------------- reading sessions (new and old strings)
_OLD_ROLES = {"target-nd": (Role.TARGET, True), "hdr": (Role.TARGET, False), "hdr-nd": (Role.TARGET, True),
              "object": (Role.ORIGINAL, False), "hdr-meter": (Role.METERING, False)}


def read_role(text: str) -> tuple[Role, bool]:
    """(Role, under the ND filter) of a manifest role string, old ones included."""
    if text in _OLD_ROLES:
        return _OLD_ROLES[text]
    try:
        return Role(text), False
    except ValueError:
        raise ValueError(f"role {text!r}: expected one of {', '.join(r.value for r in Role)} "
                         f"(or an old one: {', '.join(_OLD_ROLES)})") from None


def role_of(entry: Any) -> Role | None:
    """The Role of a manifest entry, or None (with a log line) for a role this version does not know."""
    try:
        return read_role(entry.role)[0]
    except ValueError as exc:
        log.warning("%s: %s", entry.file, exc)
        return None


def subject_of(entry: Any) -> Subject | None:
    """What a target / original frame shows (new manifests: ``meta['subject']`` holds the key)."""
    try:
        role, nd = read_role(entry.role)
    except ValueError:
        return None
    meta = entry.meta or {}
    if role not in (Role.TARGET, Role.ORIGINAL):
        return None
    key = meta.get("subject")
    if isinstance(key, str) and ":" in key:
        return Subject.parse(key)
    name = meta.get("target") or key or ("test" if role is Role.TARGET else "object")
    if role is Role.ORIGINAL:
        return Subject.original(str(name))
    return Subject.target(str(name), nd or bool(meta.get("nd")))


def light_of(entry: Any) -> str:
    """The one light name of a frame (old '<slug>-LS1' names read)."""
    meta = entry.meta or {}
    return read_light_name(meta.get("light_name") or entry.light_name)


def latest_takes(entries: Sequence[Any]) -> list[Any]:
    """Per step (take suffix ignored) only the entry of the highest take, in recording order."""
    best: dict[str, tuple[int, int]] = {}
    for e in entries:
        base, take = split_take(e.step_id or f"#seq{e.seq}")
        if base not in best or take >= best[base][0]:
            best[base] = (take, e.seq)
    keep = {seq for _take, seq in best.values()}
    return [e for e in entries if e.seq in keep]


__all__ = ["EventKind", "format_exposure", "NamedLight", "Role", "SequenceKind", "Subject", "SubjectKind",
           "exposure_key", "key_name", "latest_takes", "light_name", "light_of", "lights_of", "monochromatic_light",
           "name_of_key", "read_light_name", "read_role", "role_of", "split_take", "step_id", "subject_of"]
