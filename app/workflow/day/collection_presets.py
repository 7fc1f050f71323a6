"""Metadata presets per collection (issue 42): what an archivist sets once per collection - the creator, the rights
statement, the credit line, the institution (source), default extra fields and optionally the identifier template -
kept as one JSON file per collection and applied to every original added under it. The window's Originals form
(*Collection*) and ``dualrgb capture --queue`` (a CSV's ``collection`` column, or ``--collection``) call the same
:func:`with_collection`.

    <per-user data folder>/presets/collections/GEM.json        (DUALRGB_DATA_DIR moves it; --collections DIR)
    {"format": "dualrgb-collection/1",
     "creator": ["Example Museum, Imaging Studio"],
     "rights": "CC BY 4.0, Example Museum",
     "credit": "Gemäldegalerie, Example Museum",
     "source": "Example Museum",
     "extra": {"collection": "Gemäldegalerie", "department": "Paintings"},
     "identifier_template": "GEM-{date}-{counter:04}"}

The file's name is the collection's name (matched ignoring case). Every field is checked when the file is read
(the JSON Schema ``resources/schemas/dualrgb-collection-1.schema.json``, then core.metadata's rules for the text):
a bad file is one line naming the file and the field. Applying a preset (:func:`apply_preset`): the extra fields
merged, the original's own values winning; the creator, rights, credit line and source become the original's
``credits`` (core.metadata.Credits: in its sidecar, session and XMP; an empty one falls back to the delivery
settings'), unless the original has its own; the collection's name is recorded as ``original.collection``.

Making or editing a preset without writing JSON: the window's *Edit preset…* (app.gui.preset_editor) and ``dualrgb
collection set`` build it with :func:`make_preset` - the fields as typed, checked by the same code that reads a
file (the schema, then the rules; a PresetError naming the field, nothing written) - and write it with
:func:`save_preset` (checked again, then written atomically).
"""
from __future__ import annotations

import dataclasses
import json
import logging
import unicodedata
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any, TypeVar

from dualrgb import resources
from dualrgb.app.workflow.day.naming import expand
from dualrgb.core.metadata import COLLECTION_RULE, Credits, MetadataError, Original, normalise, normalise_extra

log = logging.getLogger(__name__)

PRESET_FORMAT = "dualrgb-collection/1"
SCHEMA_FILE = "dualrgb-collection-1.schema.json"
FOLDER = ("presets", "collections")
MAX_PRESET_BYTES = 1024 * 1024        # a preset is a few hundred bytes; whatever the file says: never read more
FIELDS = ("creator", "rights", "credit", "source", "extra", "identifier_template")      # a preset's fields, in order
T = TypeVar("T")


class PresetError(ValueError):
    """A collection preset that cannot be used: ``str()`` is one line naming the file (when it was read from one)
    and the field; :attr:`field` is that field (one of :data:`FIELDS`, ``name`` for the collection's name, or
    another key the file should not have; empty: the whole file)."""

    def __init__(self, message: str, field: str = ""):
        super().__init__(message)
        self.field = field


@dataclass(frozen=True)
class CollectionPreset:
    """A collection's metadata preset (the module docstring); its fields normalised as core.metadata's."""

    name: str
    credits: Credits = field(default_factory=Credits)
    extra: Mapping[str, str] = field(default_factory=dict)
    identifier_template: str = ""
    path: Path | None = None              # the file it was read from

    def to_dict(self) -> dict[str, Any]:
        """The file's content (beside its format header)."""
        return {**self.credits.to_dict(), **({"extra": dict(self.extra)} if self.extra else {}),
                **({"identifier_template": self.identifier_template} if self.identifier_template else {})}

    def summary(self) -> str:
        """One line for the window: what the preset sets."""
        parts = [f"creator {'; '.join(self.credits.creator)}"] if self.credits.creator else []
        parts += [f"{k} {getattr(self.credits, k)}" for k in ("rights", "credit", "source") if getattr(self.credits, k)]
        parts += [f"{len(self.extra)} extra field{'s' if len(self.extra) != 1 else ''}"] if self.extra else []
        parts += [f"template {self.identifier_template}"] if self.identifier_template else []
        return f"preset {self.name}: " + (", ".join(parts) if parts else "sets nothing")


def default_folder() -> Path:
    """Where the collection presets are: ``<per-user data folder>/presets/collections`` (not created)."""
    return resources.user_path(*FOLDER)


def check_name(name: str) -> str:
    """A collection's name, normalised (core.metadata), that can name its preset file (letters, digits and marks of
    any script, space, ``. _ - & ( ) ,``; not starting with a dot); PresetError (one line) otherwise."""
    try:
        text = normalise(COLLECTION_RULE, name)
    except MetadataError as exc:
        raise PresetError(f"collection {name!r}: {exc.problem}", "name") from None
    bad = [ch for ch in text if not (ch in " ._-&(),'" or unicodedata.category(ch)[0] in "LNM")]
    if not text or text.startswith(".") or bad:
        why = f"{bad[0]!r} cannot be in a file name" if bad else "empty" if not text else "starts with a dot"
        raise PresetError(f"collection {text!r}: {why} (the preset file is named after the collection)", "name")
    return text


def preset_path(name: str, folder: Path | None = None) -> Path:
    """The file of collection ``name``'s preset in ``folder`` (None: :func:`default_folder`): an existing file whose
    name matches ignoring case, else ``<name>.json``."""
    name = check_name(name)
    folder = Path(folder) if folder is not None else default_folder()
    for path in _files(folder):
        if path.stem.casefold() == name.casefold():
            return path
    return folder / f"{name}.json"


def _files(folder: Path) -> list[Path]:
    try:
        return sorted(p for p in folder.glob("*.json") if p.is_file())
    except OSError:
        return []


def collection_names(folder: Path | None = None) -> list[str]:
    """The collections with a preset file in ``folder`` (None: :func:`default_folder`), sorted."""
    return [p.stem for p in _files(Path(folder) if folder is not None else default_folder())]


@cache
def _validator() -> Any:
    import jsonschema

    schema = json.loads(resources.path("schemas", SCHEMA_FILE).read_text(encoding="utf-8"))
    return jsonschema.Draft202012Validator(schema)


def _read(path: Path) -> Any:
    """The preset file's JSON (PresetError naming the file when it cannot be read)."""
    try:
        if path.stat().st_size > MAX_PRESET_BYTES:
            raise PresetError(f"{path}: {path.stat().st_size} bytes is not a collection preset (at most "
                              f"{MAX_PRESET_BYTES})")
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PresetError(f"{path}: not a readable JSON file ({exc})") from None


def _check_schema(doc: Any, prefix: str) -> dict[str, Any]:
    """``doc`` checked against the preset's JSON Schema; PresetError ``prefix`` + the field otherwise."""
    import jsonschema

    error = jsonschema.exceptions.best_match(_validator().iter_errors(doc))
    if error is not None and error.validator == "additionalProperties" and isinstance(error.instance, dict):
        known = error.schema.get("properties", {})
        unknown = sorted(k for k in error.instance if k not in known)[:1] or ["?"]
        raise PresetError(f"{prefix}{unknown[0]}: unknown field (expected {', '.join(known)})", unknown[0])
    if error is not None:
        where = ".".join(str(p) for p in error.absolute_path) or "the file"
        message = " ".join(error.message.split())
        raise PresetError(f"{prefix}{where}: {message[:160]} (a {PRESET_FORMAT} preset: see "
                          f"resources/schemas/{SCHEMA_FILE})", str(next(iter(error.absolute_path), "")))
    return dict(doc)


def _field(field: str, prefix: str, make: Callable[[], T]) -> T:
    """``make()``; its ValueError (core.metadata's MetadataError, naming.TemplateError, a PresetError) as a
    PresetError naming ``field``, its one line after ``prefix``."""
    try:
        return make()
    except MetadataError as exc:
        if field == "extra" and exc.field not in ("column name", "extra fields"):
            raise PresetError(f"{prefix}extra.{exc}", field) from None          # a value: extra.department: ...
        if field == "extra":                                                    # a name, the count
            what = "field name" if exc.field == "column name" else exc.field
            raise PresetError(f"{prefix}extra: {what}: {exc.problem}", field) from None
        raise PresetError(f"{prefix}{exc}", exc.field if field == "credits" else field) from None
    except ValueError as exc:
        raise PresetError(f"{prefix}{exc}", getattr(exc, "field", "") or field) from None


def _from_document(name: str, doc: Any, prefix: str = "", path: Path | None = None) -> CollectionPreset:
    """The preset ``doc`` (a preset file's content) describes for collection ``name``: the schema, then
    core.metadata's rules and the template's tokens; PresetError (``prefix`` + the field) at the first problem."""
    doc = _check_schema(doc, prefix)
    name = _field("name", prefix, lambda: check_name(name))
    credits = _field("credits", prefix,
                     lambda: Credits(**{k: doc[k] for k in ("creator", "rights", "credit", "source") if k in doc}))
    extra = _field("extra", prefix, lambda: normalise_extra(doc.get("extra")))
    template = str(doc.get("identifier_template", "")).strip()
    if template:                               # an unknown token, a bad format: 'identifier template: ...'
        _field("identifier_template", prefix,
               lambda: expand(template, counter=1, operator="operator", collection=name))
    return CollectionPreset(name, credits, extra, template, path)


def load_preset(path: Path) -> CollectionPreset:
    """The preset in ``path`` (its name: the file's stem); PresetError, one line naming the file and the field."""
    path = Path(path)
    return _from_document(path.stem, _read(path), f"{path}: ", path)


def make_preset(name: str, *, creator: Sequence[str] = (), rights: str = "", credit: str = "", source: str = "",
                extra: Iterable[tuple[str, str]] = (), identifier_template: str = "") -> CollectionPreset:
    """The preset of collection ``name`` these fields describe (as typed: the window's editor, ``collection
    set``), checked by the code that reads a preset file; nothing is written (:func:`save_preset` writes it).

    ``extra`` is (name, value) pairs: a name given twice is refused, a pair with an empty value is left out.
    PresetError (one line naming the field; :attr:`PresetError.field`) at the first problem.
    """
    pairs = [(str(k).strip(), v) for k, v in extra]
    names = [k for k, _ in pairs]
    twice = next((k for i, k in enumerate(names) if k in names[:i]), None)
    if twice is not None:
        raise PresetError(f"extra.{twice}: named twice (one value per extra field)", "extra")
    doc = {"format": PRESET_FORMAT, "creator": list(creator), "rights": rights, "credit": credit, "source": source,
           "extra": dict(pairs), "identifier_template": identifier_template}
    return _from_document(name, doc)


def find_preset(name: str, folder: Path | None = None) -> CollectionPreset | None:
    """Collection ``name``'s preset in ``folder`` (None: :func:`default_folder`); None when there is no file for it
    (no name, or one that cannot name a file); PresetError when its file is bad."""
    try:
        path = preset_path(name, folder)
    except PresetError:
        return None
    return load_preset(path) if path.is_file() else None


def save_preset(preset: CollectionPreset, folder: Path | None = None) -> Path:
    """Write ``preset`` into ``folder`` (None: :func:`default_folder`; made when missing) as ``<name>.json``
    (replacing the collection's file, atomically); checked as a file is read before anything is written
    (PresetError, nothing written) and by reading it back; returns the path."""
    from dualrgb.common.atomic_files import atomic_write
    from dualrgb.common.strict_json import dumps as strict_dumps
    from dualrgb.simulation.versions import stamped

    preset = _from_document(preset.name, {"format": PRESET_FORMAT, **preset.to_dict()})    # before anything is written
    path = preset_path(preset.name, folder)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = strict_dumps(stamped(PRESET_FORMAT, preset.to_dict()), indent=2, ensure_ascii=False)
    atomic_write(path, text + "\n")
    log.info("collection preset %s saved: %s", preset.name, path)
    return load_preset(path).path or path


def apply_preset(original: Original, preset: CollectionPreset | None) -> Original:
    """``original`` under ``preset`` (None: as it is): the preset's extra fields with the original's own values
    winning, the preset's credits where the original has none of its own, the collection's name recorded."""
    if preset is None:
        return original
    own, default = original.credits, preset.credits
    credits = Credits(own.creator or default.creator, own.rights or default.rights, own.credit or default.credit,
                      own.source or default.source)
    return dataclasses.replace(original, extra={**preset.extra, **original.extra}, credits=credits,
                               collection=preset.name)


def with_collection(original: Original, collection: str, folder: Path | None = None) -> Original:
    """``original`` under collection ``collection``'s preset (:func:`find_preset`, :func:`apply_preset`); as it is
    when the collection is empty or has no preset file. The window's *Add* and the CLI's queue both call this."""
    return apply_preset(original, find_preset(collection, folder))


__all__ = ["FIELDS", "FOLDER", "PRESET_FORMAT", "CollectionPreset", "PresetError", "apply_preset", "check_name",
           "collection_names", "default_folder", "find_preset", "load_preset", "make_preset", "preset_path",
           "save_preset", "with_collection"]
