"""Fixity of delivered files: the size and SHA-256 of every deliverable in its sidecar, and the check of a delivery,
a deliverables folder or a whole session against them (``dualrgb verify``).

The digests are computed while the files are written (app.processing.tiff_stream), so a delivery costs no second
read; :func:`verify` reads every file again and compares. A problem is one line naming the file and what is
wrong (missing, another size, another digest, not listed in its sidecar); a sidecar without a ``fixity`` section
(a delivery made before fixity was recorded) is one problem too, since nothing of it can be checked. The previous
sets a re-delivery keeps (``<stem>/previous/...``) carry their own sidecars and are checked the same way.

Each sidecar is also checked against its JSON Schema (resources/schemas/dualrgb-delivery-1.schema.json, with
jsonschema): a sidecar that does not say what a delivery must say is a problem, one line per finding.

The sidecar's ``fixity`` section::

    "fixity": {"algorithm": "sha256", "files": {"ACC-1_XYZ_16bit.tif": {"bytes": 146948096, "sha256": "9f..."}, ...}}

BagIt (app.workflow.delivery.bagging) computes its own manifest from the files and is compared with these.
"""
from __future__ import annotations

import fnmatch
import glob
import hashlib
import json
import logging
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from dualrgb.app.workflow.delivery.delivery_folder import SIDECAR_FORMAT

log = logging.getLogger(__name__)

FIXITY_ALGORITHM = "sha256"
_CHUNK = 1 << 22


def file_fixity(path: Path) -> dict:
    """{"bytes", "sha256"} of a file on disk."""
    h = hashlib.new(FIXITY_ALGORITHM)
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(_CHUNK), b""):
            h.update(block)
    return {"bytes": Path(path).stat().st_size, FIXITY_ALGORITHM: h.hexdigest()}


def fixity_section(by_name: dict[str, dict]) -> dict:
    """The sidecar's ``fixity`` section from {file name: {"bytes", "sha256"}}."""
    return {"algorithm": FIXITY_ALGORITHM, "files": {name: dict(v) for name, v in sorted(by_name.items())}}


@dataclass
class VerifyReport:
    """What :func:`verify` found: the sidecars checked, the files that matched, and one line per problem."""

    sidecars: list[Path] = field(default_factory=list)
    files_ok: int = 0
    problems: list[str] = field(default_factory=list)
    debris: list[Path] = field(default_factory=list)      # files other tools leave beside a delivery (not problems)

    def notes(self) -> list[str]:
        """One line per debris file: what left it, and that it is not part of the delivery."""
        return [f"{p}: {debris_kind(p.name)}, not part of the delivery (dualrgb bag leaves it out)"
                for p in self.debris]

    @property
    def ok(self) -> bool:
        return not self.problems and bool(self.sidecars)

    def summary(self) -> str:
        n = len(self.sidecars)
        state = "all match" if self.ok else f"{len(self.problems)} problem{'s' * (len(self.problems) != 1)}"
        return f"{n} deliver{'ies' if n != 1 else 'y'}, {self.files_ok} files match their sidecars; {state}"

    def to_dict(self) -> dict:
        return {"ok": self.ok, "sidecars": [str(p) for p in self.sidecars], "files_ok": self.files_ok,
                "problems": list(self.problems), "debris": [str(p) for p in self.debris]}


# files that other programs leave beside the files they open (name or suffix -> what leaves it)
DEBRIS = {".aux.xml": "left by GDAL (its statistics and metadata, e.g. after gdalinfo -stats or QGIS)",
          ".DS_Store": "left by the macOS Finder (folder view settings)",
          "Thumbs.db": "left by Windows Explorer (thumbnail cache)",
          "desktop.ini": "left by Windows Explorer (folder settings)",
          "._": "left by macOS on a non-Mac file system (AppleDouble resource fork)"}


def debris_kind(name: str) -> str | None:
    """What left a file named ``name`` beside a delivery, when it is one of :data:`DEBRIS`'s; else None."""
    for key, what in DEBRIS.items():
        if name == key or (key.startswith(".") and len(name) > len(key) and name.endswith(key)) or \
                (key == "._" and name.startswith(key)):
            return what
    return None


def _is_sidecar(path: Path) -> bool:
    try:
        with open(path, encoding="utf-8") as fh:
            head = fh.read(4096)
    except (OSError, UnicodeDecodeError):
        return False
    return f'"format": "{SIDECAR_FORMAT}"' in head or f'"format":"{SIDECAR_FORMAT}"' in head


def find_sidecars(where: Path) -> Iterator[Path]:
    """The delivery sidecars at ``where``: the file itself, or every one under the folder (a delivery, a
    deliverables folder, a session), in path order."""
    where = Path(where)
    if where.is_file():
        yield where
        return
    for path in sorted(where.rglob("*.json")):
        if path.name.startswith(".") or any(part.startswith(".") for part in path.relative_to(where).parts[:-1]):
            continue                                    # staging folders of a delivery being written
        if _is_sidecar(path):
            yield path


SCHEMA_FILE = "dualrgb-delivery-1.schema.json"


@lru_cache(maxsize=1)
def sidecar_schema() -> dict:
    """The delivery sidecar's JSON Schema (packaged: dualrgb.resources, schemas/)."""
    from dualrgb.resources import path

    return json.loads(path("schemas", SCHEMA_FILE).read_text(encoding="utf-8"))


def schema_problems(doc: object) -> list[str]:
    """What in a sidecar's JSON does not follow the schema: '<where>: <message>' per finding."""
    import jsonschema

    validator = jsonschema.Draft202012Validator(sidecar_schema())
    out = []
    for err in sorted(validator.iter_errors(doc), key=lambda e: list(e.absolute_path)):
        where = "/".join(str(p) for p in err.absolute_path) or "(top)"
        out.append(f"{where}: {err.message}")
    return out


def on_demand(doc: dict, name: str) -> bool:
    """Whether a file named ``name`` beside a delivery is one ``dualrgb cube`` makes on demand for it (its cube,
    its header, a rendering)."""
    cube = ((doc.get("spectral") or {}).get("cube") or {})
    if cube.get("delivery") != "on-demand":
        return False
    stem = str(doc.get("file_stem") or "")
    return (name in (f"{stem}_spectral.img", f"{stem}_spectral.hdr")
            or fnmatch.fnmatchcase(name, f"{glob.escape(stem)}_under_*_prophoto_16bit.tif"))


def verify_sidecar(sidecar: Path, report: VerifyReport) -> dict | None:
    """Check one delivery's files against its sidecar (problems and matches into ``report``); the sidecar's JSON
    when it is readable and follows its schema (None otherwise: ``report`` says why), so that a caller showing it
    neither reads nor checks it again."""
    report.sidecars.append(sidecar)
    try:
        doc = json.loads(sidecar.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        report.problems.append(f"{sidecar}: cannot read the sidecar ({exc})")
        return None
    schema = schema_problems(doc)
    report.problems.extend(f"{sidecar}: schema {SCHEMA_FILE}: {line}" for line in schema)
    valid = doc if isinstance(doc, dict) and not schema else None
    section = doc.get("fixity") if isinstance(doc, dict) else None
    files = section.get("files") if isinstance(section, dict) else None
    if not isinstance(section, dict) or not isinstance(files, dict) or section.get("algorithm") != FIXITY_ALGORITHM:
        report.problems.append(f"{sidecar}: no {FIXITY_ALGORITHM} fixity recorded (delivered before dualrgb "
                               "recorded it): its files cannot be checked")
        return valid
    folder = sidecar.parent
    for name, want in files.items():
        check_file(folder / name, want, report)
    listed = set(files) | {sidecar.name}
    for path in sorted(folder.iterdir()):
        if not path.is_file() or path.name in listed:
            continue
        if debris_kind(path.name):
            report.debris.append(path)
        elif path.name.startswith("."):
            continue                                    # a writer's temp file, hidden
        elif on_demand(doc, path.name):
            report.problems.append(f"{path}: made by dualrgb cube but not in the sidecar {sidecar.name}'s fixity "
                                   "(made by an older dualrgb: run dualrgb cube again to record it)")
        else:
            report.problems.append(f"{path}: not listed in the sidecar {sidecar.name}")
    return valid


DELIVERED_SUFFIXES = (".tif", ".tiff", ".img", ".jp2")


def unsealed_deliveries(where: Path, sidecars: list[Path]) -> list[tuple[Path, str]]:
    """(the folder, one line) per delivery folder under ``where`` (``<id>/<id>_....tif``, the names a delivery
    writes) beside which no readable sidecar was found: a sidecar deleted or damaged must not make its files drop
    out of verify and bag unsaid."""
    sealed = {p.parent.resolve() for p in sidecars}
    out = []
    for folder in sorted({where, *(d for d in where.rglob("*") if d.is_dir())}):
        rel = folder.relative_to(where).parts
        if folder.resolve() in sealed or any(part.startswith(".") for part in rel):
            continue
        files = [p for p in folder.iterdir() if p.is_file() and p.name.startswith(f"{folder.name}_")
                 and p.suffix.lower() in DELIVERED_SUFFIXES]
        if files:
            out.append((folder, f"{folder}: {len(files)} delivered file(s) ({files[0].name}, ...) but no readable "
                                f"dualrgb sidecar beside them ({folder.name}.json missing or damaged): they cannot "
                                "be checked"))
    return out


def check_file(path: Path, want: dict, report: VerifyReport) -> None:
    """One file against its recorded size and digest (a problem line, or one more match, into ``report``)."""
    if not path.is_file():
        report.problems.append(f"{path}: missing")
        return
    size = path.stat().st_size
    if size != want.get("bytes"):
        report.problems.append(f"{path}: {size} bytes, the sidecar says {want.get('bytes')}")
        return
    got = file_fixity(path)[FIXITY_ALGORITHM]
    if got != want.get(FIXITY_ALGORITHM):
        report.problems.append(f"{path}: {FIXITY_ALGORITHM} {got[:12]}... differs from the sidecar's "
                               f"{str(want.get(FIXITY_ALGORITHM))[:12]}... (the file changed)")
        return
    report.files_ok += 1


def verify(where: Path) -> VerifyReport:
    """Check every delivery at ``where`` (a sidecar, a delivery's folder, a deliverables folder or a session)."""
    where = Path(where)
    report = VerifyReport()
    if not where.exists():
        report.problems.append(f"{where}: does not exist")
        return report
    for sidecar in find_sidecars(where):
        verify_sidecar(sidecar, report)
    if where.is_dir():
        report.problems.extend(line for _, line in unsealed_deliveries(where, report.sidecars))
    if not report.sidecars:
        report.problems.append(f"{where}: no dualrgb delivery sidecar ({SIDECAR_FORMAT}) found")
    return report
