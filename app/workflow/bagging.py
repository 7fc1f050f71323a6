"""A day's deliverables as a BagIt bag for the transfer to the archive (``dualrgb bag``), made with the Library of
Congress' ``bagit`` package (RFC 8493).

    bag = make_day_bag(session / "deliverables", Path("ACC-day-2026-03-14"), info={"Source-Organization": "..."})

The bag holds, under ``data/``, one folder per original with its current deliverables and sidecar (the previous
sets a re-delivery kept are left out: they are superseded); the payload files are hard links to the delivered
ones where the file system allows (no copy of gigabytes; ``copy=True`` copies). Before anything is linked every
delivery is checked against its sidecar (app.workflow.fixity: a damaged or incomplete delivery is not bagged);
after bagit has written its SHA-256 manifest, each file's digest is compared with the one its sidecar recorded
when it was written, so the bag is known to carry exactly what was delivered.
"""
from __future__ import annotations

import json
import logging
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from dualrgb.app.workflow.fixity import FIXITY_ALGORITHM, VerifyReport, find_sidecars, verify_sidecar

log = logging.getLogger(__name__)

PREVIOUS = "previous"


@dataclass
class DayBag:
    """A bag made by :func:`make_day_bag`."""

    path: Path
    originals: list[str]
    files: int
    bytes: int

    def summary(self) -> str:
        return (f"{self.path}: BagIt bag of {len(self.originals)} original{'s' * (len(self.originals) != 1)}, "
                f"{self.files} files, {self.bytes / 1e6:.1f} MB (manifest {FIXITY_ALGORITHM}, checked against the "
                "sidecars)")


def current_sidecars(source: Path) -> list[Path]:
    """The sidecars of the current deliveries under ``source`` (not the previous sets re-deliveries kept)."""
    source = Path(source)
    return [p for p in find_sidecars(source)
            if PREVIOUS not in p.resolve().relative_to(source.resolve()).parts[:-1]]


def _place(src: Path, dst: Path, copy: bool) -> None:
    if not copy:
        try:
            os.link(src, dst)
            return
        except OSError as exc:                       # another file system, or links not allowed: copy instead
            log.info("%s: not linked (%s), copied", src, exc)
    shutil.copy2(src, dst)


def _check_manifest(bag: Path, expected: dict[str, str]) -> None:
    """bagit's manifest against the sidecars' digests (``expected``: payload path -> sha256)."""
    got = {}
    for line in (bag / f"manifest-{FIXITY_ALGORITHM}.txt").read_text(encoding="utf-8").splitlines():
        digest, _, name = line.partition(" ")
        got[name.strip()] = digest
    for name, digest in expected.items():
        if got.get(name) != digest:
            raise ValueError(f"{bag}: {name} in the bag's manifest ({str(got.get(name))[:12]}...) differs from its "
                             f"sidecar's {FIXITY_ALGORITHM} ({digest[:12]}...): the file changed while it was bagged")


def make_day_bag(source: Path, out: Path, *, info: dict[str, str] | None = None, copy: bool = False,
                 processes: int = 1) -> DayBag:
    """Bag the current deliveries under ``source`` (a deliverables folder or a session) into the new folder
    ``out``; ValueError (one line) when there is nothing to bag, a delivery does not match its sidecar, or
    ``out`` exists and is not empty."""
    import bagit

    source, out = Path(source), Path(out)
    sidecars = current_sidecars(source)
    if not sidecars:
        raise ValueError(f"{source}: no dualrgb delivery to bag")
    report = VerifyReport()
    for sidecar in sidecars:
        verify_sidecar(sidecar, report)
    if report.problems:
        raise ValueError(f"not bagged: {len(report.problems)} problem(s), the first: {report.problems[0]} "
                         f"(dualrgb verify {source} lists them)")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"{out}: exists and is not an empty folder; the bag needs a new one")
    out.mkdir(parents=True, exist_ok=True)
    expected: dict[str, str] = {}
    originals = []
    for sidecar in sidecars:
        doc = json.loads(sidecar.read_text(encoding="utf-8"))
        folder = out / sidecar.parent.name
        folder.mkdir()
        for name, fix in doc["fixity"]["files"].items():
            _place(sidecar.parent / name, folder / name, copy)
            expected[f"data/{folder.name}/{name}"] = fix[FIXITY_ALGORITHM]
        _place(sidecar, folder / sidecar.name, copy)
        originals.append(str(doc["original"]["identifier"]))
    bag_info = {"External-Description": f"dualrgb deliverables of {len(originals)} original(s): "
                                        + ", ".join(originals[:20]) + (" ..." if len(originals) > 20 else ""),
                **(info or {})}
    bag = bagit.make_bag(str(out), bag_info=bag_info, processes=processes, checksums=[FIXITY_ALGORITHM])
    _check_manifest(out, expected)
    oxum_bytes, _, oxum_files = str(bag.info.get("Payload-Oxum", "0.0")).partition(".")
    log.info("bag %s: %d originals, Payload-Oxum %s", out, len(originals), bag.info.get("Payload-Oxum"))
    return DayBag(out, originals, int(oxum_files or 0), int(oxum_bytes or 0))
