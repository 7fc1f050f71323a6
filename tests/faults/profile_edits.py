"""Re-sealed edits of a real calibration profile (issue 38 item 5): every field of tests/data/profiles' profile (as
`dualrgb calibrate --virtual-lab` wrote it, frames shrunk to 8 x 12) edited one at a time and the digest
recomputed, as anyone can (it is a plain SHA-256), for the fault suite's `calibration show` cases."""
from __future__ import annotations

import copy
import json
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from dualrgb.app.workflow.calibration.profile_check import seal

PROFILES = Path(__file__).resolve().parents[1] / "data" / "profiles"
PROFILE = next(PROFILES.glob("cal-*.json"))
SKIP = ("digest", "format")             # the digest itself; the format tag (another file type altogether)
Path_ = tuple[str | int, ...]


def fields(value: Any, at: Path_ = ()) -> Iterator[Path_]:
    """Every field's path (containers too); of a list only the first and last items (their siblings are alike)."""
    if at:
        yield at
    if isinstance(value, dict):
        for key, item in value.items():
            if not at and key in SKIP:
                continue
            yield from fields(item, (*at, key))
    elif isinstance(value, list):
        for i in sorted({0, len(value) - 1} if value else set()):
            yield from fields(value[i], (*at, i))


def get(doc: Any, at: Path_) -> Any:
    for part in at:
        doc = doc[part]
    return doc


def put(doc: Any, at: Path_, value: Any) -> None:
    get(doc, at[:-1])[at[-1]] = value


def name(at: Path_) -> str:
    out = ""
    for part in at:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _shorter(value: Any) -> Any:
    return value[:-1] if isinstance(value, list) else None


EDITS = {                               # kind -> (applies to the value, the edited value)
    "null": (lambda v: True, lambda v: None),
    "a string": (lambda v: not isinstance(v, str), lambda v: "x"),
    "a number": (lambda v: not isinstance(v, (int, float)) or isinstance(v, bool), lambda v: 7),
    "-1": (lambda v: isinstance(v, (int, float)) and not isinstance(v, bool), lambda v: -1),
    "1e300": (lambda v: isinstance(v, (int, float)) and not isinstance(v, bool), lambda v: 1e300),
    "empty": (lambda v: isinstance(v, (list, dict, str)) and len(v) > 0, lambda v: type(v)()),
    "one item fewer": (lambda v: isinstance(v, list) and len(v) > 0, _shorter),
}


def edits(kind: str) -> Iterator[tuple[str, dict]]:
    """(field name, the re-sealed document) for every field the edit ``kind`` applies to."""
    doc = json.loads(PROFILE.read_text())
    applies, edit = EDITS[kind]
    for at in fields(doc):
        value = get(doc, at)
        if not applies(value):
            continue
        edited = copy.deepcopy(doc)
        put(edited, at, edit(value))
        edited.pop("digest", None)
        yield name(at), seal(edited)


def write(folder: Path, doc: dict) -> Path:
    """``doc`` as the profile JSON in ``folder``, its arrays beside it."""
    folder.mkdir(parents=True, exist_ok=True)
    npz = PROFILE.with_suffix(".npz")
    if not (folder / npz.name).exists():
        shutil.copy(npz, folder / npz.name)
    path = folder / PROFILE.name
    path.write_text(json.dumps(doc))
    return path
