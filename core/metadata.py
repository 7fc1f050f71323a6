"""The metadata of an original, checked before any device acts: the one place that validates and normalises every
field of an original (identifier, title, operator, notes, mode, the extra columns of a queue CSV), renders text
for TIFF's 7-bit ASCII tags and derives file names and XMP property names from it. The GUI, the CLI, the queue
import (app.workflow.day.queue_csv) and delivery all build an :class:`Original`, whose construction runs it.

    original = Original("ACC-5", title="Öl auf Holz")          # MetadataError (a ValueError): one line
    original.file_stem                                         # 'ACC-5'; Original("ACC 1").file_stem: 'ACC_1_<hash>'

Per field (README "Metadata of an original" has the whole table):

=========== ================================ ============ ========== ===========
field       line breaks (LF, CR, CRLF, VT,   tab          trimmed    at most
            U+2028, U+2029)                                          (characters)
=========== ================================ ============ ========== ===========
identifier  refused (one line)               refused      yes        100
title       one space per run of breaks      one space    yes        500
operator    one space per run of breaks      one space    yes        100
notes       LF (CRLF, CR, VT -> LF)          kept         yes        4000
extra value LF, as notes                     kept         yes        1000 (any number of columns, names 100)
=========== ================================ ============ ========== ===========

Every field: Unicode NFC (after the mapping). Refused everywhere, with one line naming the field and the
character position in the text as given (``title: control character U+0001 at character 4 is not allowed``):
other C0 controls (NUL ...), DEL, C1 controls (U+0080-U+009F), surrogates, noncharacters (U+FDD0-U+FDEF,
U+xFFFE / U+xFFFF): a superset of what XML 1.0 forbids, so an XMP packet made of the fields always parses. The
identifier also refuses invisible format characters (Unicode Cf: zero-width joiners, bidi marks, soft hyphen),
maps other spaces (no-break space ...) to U+0020 and needs a letter or a digit.

File names (:func:`file_stem`): deterministic from the identifier alone; Unicode NFC, keeping every letter, digit
and combining mark of any script (``東博-A-1`` stays ``東博-A-1``), other characters as ``_`` (only letters, digits,
marks and ``. _ -``: nothing a Windows, macOS or Linux file system refuses), no Windows reserved name (also
``COM¹``), no leading or trailing dot, at most 57 characters. An identifier that is its own rendering (no lower
case, those characters only, not reserved, short) is used as it is (``ACC-123``, ``東博-A-1``); any other gets its
rendering plus ``_`` and 8 hex digits of the SHA-256 of its exact UTF-8 text (``ACC 1`` -> ``ACC_1_8f7b...``).
Distinct identifiers never share a name, also on case-insensitive file systems: kept names have no lower case and
never end like a hash suffix; hashed names differ in the hash. Where a file system takes ASCII names only (an old
Samba share, ISO 9660), :func:`ascii_stem` gives the documented, reversible transliteration: the stem as it is when
ASCII, else ``xn--`` + its Punycode (RFC 3492, as IDNA writes host names: ``東博-A-1`` -> ``xn---A-1-...``);
:func:`stem_of_ascii` reads it back. :func:`unicode_names_work` tells which a folder takes.

TIFF ASCII tags (:func:`ascii_text`): TIFF 6.0 allows 7-bit ASCII only, so they carry a transliteration (NFKD,
combining marks dropped, a few letters spelled out, typographic quotes and dashes as ASCII, '?' for the rest); the
exact text is in the XMP packet (UTF-8) and the sidecar JSON.
"""
from __future__ import annotations

import hashlib
import logging
import os
import re
import unicodedata
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from itertools import groupby
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from dualrgb.core.vocabulary import Subject

log = logging.getLogger(__name__)

MODES = ("reflective", "transmissive")
LINE_BREAKS = "\n\r\x0b\u2028\u2029"        # LF, CR, VT (FileMaker's in-field break), line / paragraph separator
_BREAK = re.compile(r"\r\n|[\n\r\x0b\u2028\u2029]")
_BREAK_RUN = re.compile(r"[ \t]*(?:(?:\r\n|[\n\r\x0b\u2028\u2029])[ \t]*)+")


class Whitespace(StrEnum):
    """What a field does with a line break or a tab."""

    REFUSE = "refused"
    SPACE = "one space"
    KEEP = "kept"          # line breaks kept as LF, tabs as tabs


@dataclass(frozen=True)
class FieldRule:
    """How one field is normalised: line breaks, tabs, the most characters, whether it is an identifier."""

    name: str
    max_chars: int
    breaks: Whitespace
    tabs: Whitespace
    identifier: bool = False


FIELD_RULES = {
    "identifier": FieldRule("identifier", 100, Whitespace.REFUSE, Whitespace.REFUSE, identifier=True),
    "title": FieldRule("title", 500, Whitespace.SPACE, Whitespace.SPACE),
    "operator": FieldRule("operator", 100, Whitespace.SPACE, Whitespace.SPACE),
    "notes": FieldRule("notes", 4000, Whitespace.KEEP, Whitespace.KEEP),
}
EXTRA_RULE = FieldRule("extra", 1000, Whitespace.KEEP, Whitespace.KEEP)
COLLECTION_RULE = FieldRule("collection", 100, Whitespace.REFUSE, Whitespace.REFUSE)
CREDIT_RULES = {"creator": FieldRule("creator", 200, Whitespace.SPACE, Whitespace.SPACE),
                "rights": FieldRule("rights", 1000, Whitespace.SPACE, Whitespace.SPACE),
                "credit": FieldRule("credit", 500, Whitespace.SPACE, Whitespace.SPACE),
                "source": FieldRule("source", 500, Whitespace.SPACE, Whitespace.SPACE)}
COLUMN_RULE = FieldRule("column name", 100, Whitespace.REFUSE, Whitespace.REFUSE)
MAX_EXTRA = 10_000          # extra fields of one original: any export's columns (a sanity bound, not a policy)


class MetadataError(ValueError):
    """A field that cannot be delivered: ``str()`` is one line naming the field and the problem."""

    def __init__(self, field: str, problem: str):
        super().__init__(f"{field}: {problem}")
        self.field, self.problem = field, problem


# ---------------------------------------------------------------- characters
def _forbidden(ch: str) -> str | None:
    """Why ``ch`` may not appear in any field (None: it may)."""
    o = ord(ch)
    if o < 0x20 or o == 0x7F or 0x80 <= o <= 0x9F:
        return "control character"
    if 0xD800 <= o <= 0xDFFF:
        return "lone surrogate"
    if 0xFDD0 <= o <= 0xFDEF or (o & 0xFFFE) == 0xFFFE:
        return "noncharacter"
    return None


def _why_refused(rule: FieldRule, ch: str) -> str | None:
    if ch in LINE_BREAKS:
        return "line break" if rule.breaks is Whitespace.REFUSE else None
    if ch == "\t":
        return "tab" if rule.tabs is Whitespace.REFUSE else None
    why = _forbidden(ch)
    if why is None and rule.identifier and unicodedata.category(ch) == "Cf":
        why = "invisible format character"
    return why


def _check_characters(rule: FieldRule, text: str, label: str) -> None:
    for i, ch in enumerate(text, start=1):
        why = _why_refused(rule, ch)
        if why is not None:
            hint = " (one line, no tabs)" if why in ("line break", "tab") else ""
            raise MetadataError(label, f"{why} U+{ord(ch):04X} at character {i} is not allowed{hint}")


def normalise(rule: FieldRule, value: object, label: str | None = None) -> str:
    """``value`` as ``rule`` keeps it (see the module docstring), or MetadataError naming ``label``.

    Parameters
    ----------
    rule
        The field's rule (:data:`FIELD_RULES`, :data:`EXTRA_RULE`, :data:`COLUMN_RULE`).
    value
        The text as typed or imported (None: empty).
    label
        How the error names the field (default the rule's name; a CSV column's name in a queue import).

    Returns
    -------
    str
        The normalised text: NFC, line breaks and tabs mapped, trimmed, within the length limit.
    """
    label = label or rule.name
    if value is None:
        return ""
    if not isinstance(value, str):
        raise MetadataError(label, f"expected text, got {type(value).__name__}")
    _check_characters(rule, value, label)
    text = value
    if rule.breaks is Whitespace.SPACE:
        text = _BREAK_RUN.sub(" ", text)
    elif rule.breaks is Whitespace.KEEP:
        text = _BREAK.sub("\n", text)
    if rule.tabs is Whitespace.SPACE:
        text = text.replace("\t", " ")
    if rule.identifier:
        text = "".join(" " if unicodedata.category(ch) == "Zs" else ch for ch in text)
    text = unicodedata.normalize("NFC", text).strip()
    if len(text) > rule.max_chars:
        raise MetadataError(label, f"{len(text)} characters, at most {rule.max_chars}")
    return text


def normalise_identifier(value: object, label: str = "identifier") -> str:
    text = normalise(FIELD_RULES["identifier"], value, label)
    if not text:
        raise MetadataError(label, "required: the accession number, e.g. ACC-123 (it names every file)")
    if not any(ch.isalnum() for ch in text):
        raise MetadataError(label, f"{text!r} needs at least one letter or digit")
    return text


def normalise_mode(value: object, label: str = "mode") -> str:
    text = str(value or "").strip().lower()
    if text not in MODES:
        raise MetadataError(label, f"{value!r}: expected {' or '.join(MODES)}")
    return text


def normalise_extra(extra: Mapping[str, object] | None) -> dict[str, str]:
    """Extra fields (a queue CSV's other columns): names as column names, values as notes; empty values dropped."""
    out: dict[str, str] = {}
    for name, value in (extra or {}).items():
        key = normalise(COLUMN_RULE, name, "column name")
        if not key:
            raise MetadataError("column name", "empty: every extra field needs a name")
        if key in out:
            raise MetadataError(key, "named twice")
        text = normalise(EXTRA_RULE, value, key)
        if text:
            out[key] = text
    if len(out) > MAX_EXTRA:
        raise MetadataError("extra fields", f"{len(out)}, at most {MAX_EXTRA}")
    return out


# ---------------------------------------------------------------- the original
@dataclass(frozen=True)
class Credits:
    """Who made an original's files and on what terms, from its collection's preset
    (app.workflow.day.collection_presets): XMP ``dc:creator``, ``dc:rights`` (and the TIFF Copyright tag),
    ``photoshop:Credit`` (the credit line), ``photoshop:Source`` (the institution). An empty field: the delivery
    settings' (app.workflow.delivery.delivery_settings). Normalised on construction (:data:`CREDIT_RULES`)."""

    creator: tuple[str, ...] = ()
    rights: str = ""
    credit: str = ""
    source: str = ""

    def __post_init__(self) -> None:
        creators = (self.creator,) if isinstance(self.creator, str) else tuple(self.creator or ())
        rule = CREDIT_RULES["creator"]
        object.__setattr__(self, "creator", tuple(t for t in (normalise(rule, c) for c in creators) if t))
        for k in ("rights", "credit", "source"):
            object.__setattr__(self, k, normalise(CREDIT_RULES[k], getattr(self, k)))

    def __bool__(self) -> bool:
        return bool(self.creator or self.rights or self.credit or self.source)

    def to_dict(self) -> dict[str, Any]:
        """The fields that are set (``creator`` a list)."""
        out: dict[str, Any] = {"creator": list(self.creator)} if self.creator else {}
        return out | {k: getattr(self, k) for k in ("rights", "credit", "source") if getattr(self, k)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | Credits | None) -> Credits:
        if isinstance(data, Credits):
            return data
        if data is not None and not isinstance(data, Mapping):
            raise MetadataError("credits", f"expected a table of creator, rights, credit, source, got {data!r}")
        unknown = sorted(set(data or {}) - set(cls.__dataclass_fields__))
        if unknown:
            raise MetadataError(unknown[0], "unknown credit field (expected creator, rights, credit or source)")
        return cls(**dict(data or {}))


@dataclass(frozen=True)
class Original:
    """An object to digitise; every field normalised on construction (MetadataError, one line, otherwise). The
    identifier (accession number) is required and names every file (:attr:`file_stem`)."""

    identifier: str
    title: str = ""
    operator: str = ""
    notes: str = ""
    mode: str = "reflective"
    extra: Mapping[str, str] = field(default_factory=dict)
    collection: str = ""                    # the collection whose preset was applied (its name)
    credits: Credits = field(default_factory=Credits)

    def __post_init__(self) -> None:
        values = {"identifier": normalise_identifier(self.identifier),
                  **{k: normalise(FIELD_RULES[k], getattr(self, k)) for k in ("title", "operator", "notes")},
                  "mode": normalise_mode(self.mode), "extra": normalise_extra(self.extra),
                  "collection": normalise(COLLECTION_RULE, self.collection),
                  "credits": Credits.from_dict(self.credits)}
        for k, v in values.items():
            object.__setattr__(self, k, v)

    @property
    def subject(self) -> Subject:
        from dualrgb.core.vocabulary import Subject  # (numpy through simulation: kept off the CLI's start-up)

        return Subject.original(self.identifier)

    @property
    def file_stem(self) -> str:
        return file_stem(self.identifier)

    def to_dict(self) -> dict[str, Any]:
        """The fields (``collection`` and ``credits`` only when set: sidecars without them read as before)."""
        return {"identifier": self.identifier, "title": self.title, "operator": self.operator, "notes": self.notes,
                "mode": self.mode, "extra": dict(self.extra),
                **({"collection": self.collection} if self.collection else {}),
                **({"credits": self.credits.to_dict()} if self.credits else {})}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], **over: Any) -> Original:
        """From a sidecar's / session.json's ``original`` (unknown keys ignored), validated again."""
        known = {k: v for k, v in data.items() if k in cls.__dataclass_fields__}
        return cls(**{**known, **over})


def check_original(original: Original) -> None:
    """Validate ``original`` again (an object built or changed past its constructor): MetadataError if any field
    is not what its normalisation gives. Run before any device acts."""
    have = original.to_dict()
    for k, v in Original.from_dict(have).to_dict().items():
        if have[k] != v:
            raise MetadataError(k, f"{have[k]!r} is not normalised (expected {v!r})")


# ---------------------------------------------------------------- ASCII renderings and names
_SPELLED = str.maketrans({"ß": "ss", "ẞ": "SS", "æ": "ae", "Æ": "AE", "œ": "oe", "Œ": "OE", "ø": "o", "Ø": "O",
                          "ł": "l", "Ł": "L", "đ": "d", "Đ": "D", "ð": "d", "Ð": "D", "þ": "th", "Þ": "Th",
                          "ı": "i", "\u2018": "'", "\u2019": "'", "\u201a": "'", "\u201c": '"', "\u201d": '"',
                          "\u201e": '"', "\u00ab": '"', "\u00bb": '"', "\u2013": "-", "\u2014": "-", "\u2212": "-",
                          "\u00a0": " "})


def ascii_text(text: str) -> str:
    """A 7-bit ASCII rendering for TIFF ASCII tags (TIFF 6.0: 7-bit ASCII, NUL-terminated).

    NFKD with combining marks dropped (é -> e, ﬁ -> fi, full-width letters -> ASCII), a few letters spelled out
    (ß -> ss, Æ -> AE, Ø -> O, Œ -> OE, Ł -> L, Þ -> Th), typographic quotes and dashes as ASCII, anything else
    (CJK, symbols) '?'. LF and tab are kept (notes); no field holds another control character.

    Parameters
    ----------
    text
        A normalised field.

    Returns
    -------
    str
        Characters U+0020-U+007E, LF and tab only.
    """
    out = []
    for ch in unicodedata.normalize("NFKD", text).translate(_SPELLED):
        if unicodedata.combining(ch):
            continue
        out.append(ch if " " <= ch <= "~" or ch in "\n\t" else "?")
    return "".join(out)


STEM_CHARS = 48                 # of the ASCII rendering; + "_" + 8 hex digits when hashed
HASH_DIGITS = 8
WINDOWS_RESERVED = frozenset({"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(10)),
                              *(f"LPT{i}" for i in range(10))})
_HASH_TAIL = re.compile(rf"_[0-9a-f]{{{HASH_DIGITS}}}$", re.IGNORECASE)


def _hash(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()[:HASH_DIGITS]


def _name_char(ch: str) -> bool:
    """Whether a file name may hold ``ch`` on every common file system (a letter, digit or mark of any script,
    '.', '_', '-')."""
    return ch in "._-" or unicodedata.category(ch)[0] in "LNM"


def _reserved(base: str) -> bool:
    return unicodedata.normalize("NFKC", base).upper() in WINDOWS_RESERVED     # 'COM¹' is 'COM1' to Windows


def _rendering(identifier: str) -> str:
    runs = groupby(unicodedata.normalize("NFC", identifier), key=_name_char)     # each run of others: one '_'
    text = "".join("".join(chars) if kept else "_" for kept, chars in runs).strip("._-")
    text = text[:STEM_CHARS].strip("._-")
    base, dot, rest = text.partition(".")
    if _reserved(base):                          # 'CON', 'nul.txt': reserved with any extension
        text = f"{base}_{rest}".rstrip("_")
    return text or "original"


def ascii_stem(stem: str) -> str:
    """The reversible ASCII form of a file stem, for a file system that takes ASCII names only: ``stem`` when it
    is ASCII, else ``xn--`` + its Punycode (RFC 3492); :func:`stem_of_ascii` is its inverse."""
    return stem if stem.isascii() else "xn--" + stem.encode("punycode").decode("ascii")


def stem_of_ascii(name: str) -> str:
    """The file stem :func:`ascii_stem` made ``name`` from."""
    return name[4:].encode("ascii").decode("punycode") if name.startswith("xn--") else name


def unicode_names_work(folder: Path) -> bool:
    """Whether ``folder``'s file system keeps a non-ASCII name (a CJK letter and an accented one) as written,
    up to Unicode normalisation (HFS+ stores NFD): a probe file made and removed."""
    probe = f".dualrgb-name-東é-{os.getpid()}"
    try:
        (folder / probe).touch(exist_ok=False)
    except (OSError, UnicodeError):
        return False
    try:
        names = {unicodedata.normalize("NFC", n) for n in os.listdir(folder)}
        return probe in names
    finally:
        (folder / probe).unlink(missing_ok=True)


def frame_stem(subject_key: object) -> str:
    """What a raw frame's file name carries of its subject: an original's file stem (the name of its deliverables:
    ``0062_ACC-1_original_VIRT_0062.DNG``), '' for targets, darks and flats."""
    from dualrgb.core.vocabulary import Subject, SubjectKind

    if not isinstance(subject_key, str):
        return ""
    try:
        subject = Subject.parse(subject_key)
        return file_stem(subject.name) if subject.kind is SubjectKind.ORIGINAL else ""
    except ValueError:
        return ""


def file_stem(identifier: str) -> str:
    """The file-name stem of an original (its deliverables folder and every file in it); see the module docstring.

    Parameters
    ----------
    identifier
        The normalised identifier (:func:`normalise_identifier`).

    Returns
    -------
    str
        ``identifier`` itself (NFC, any script) when it is its own portable rendering, else the rendering + ``_``
        + 8 hex digits of the identifier's SHA-256.
    """
    rendering = _rendering(identifier)
    faithful = (rendering == identifier and identifier == identifier.upper() and not _HASH_TAIL.search(identifier)
                and not _reserved(rendering.partition(".")[0]))
    return rendering if faithful else f"{rendering}_{_hash(identifier)}"


_XML_NAME_UNSAFE = re.compile(r"[^A-Za-z0-9]+")


def xmp_property(column: str) -> str:
    """The ``dualrgb:`` XMP property of an extra field named ``column``: ``Extra_<column>`` when the name is only
    ASCII letters, digits and '_' (and does not end like a hash suffix), else ``Extra_<ASCII rendering>_<8 hex
    digits of its SHA-256>``: an XML name, deterministic, distinct for distinct column names."""
    if re.fullmatch(r"[A-Za-z0-9_]{1,60}", column) and not _HASH_TAIL.search(column):
        return f"Extra_{column}"
    rendering = _XML_NAME_UNSAFE.sub("_", ascii_text(column)).strip("_")[:40].strip("_")
    return f"Extra_{rendering}_{_hash(column)}" if rendering else f"Extra_{_hash(column)}"


__all__ = ["COLLECTION_RULE", "COLUMN_RULE", "CREDIT_RULES", "EXTRA_RULE", "FIELD_RULES", "MAX_EXTRA", "MODES",
           "Credits", "FieldRule", "MetadataError", "Original", "Whitespace", "ascii_stem", "ascii_text",
           "check_original", "file_stem", "frame_stem", "normalise", "normalise_extra", "normalise_identifier",
           "normalise_mode", "stem_of_ascii", "unicode_names_work", "xmp_property"]
