"""A day's deliverables as a BagIt bag for the transfer to the archive (``dualrgb bag``), made with the Library of
Congress' ``bagit`` package and written as BagIt 1.0 (RFC 8493).

    bag = make_day_bag(session / "deliverables", Path("ACC-day-2026-03-14"), info={"Source-Organization": "..."})

The bag holds, under ``data/``, one folder per original with its current deliverables and sidecar (the previous
sets a re-delivery kept are left out: they are superseded), SHA-256 payload and tag manifests, and bag-info with
the institution's fields (the delivery settings' ``[bag-info]``, then ``--organization`` / ``--info``).

A bag of its own: the payload files are copies - a reflink (copy-on-write clone: instant, no space used until
either side changes) where the file system offers one (Btrfs, XFS, APFS-like), else a byte copy - so editing a
file in the bag (adding rights metadata with exiv2, say) never changes the session's master. Hard links only when
asked (``link=True``), for a bag that is moved away at once.

Nothing unverified is packed: before anything is copied every delivery is checked against its sidecar
(app.workflow.delivery.fixity: a damaged or incomplete delivery is not bagged); files other programs left beside a
delivery (GDAL's ``.aux.xml``, ``.DS_Store``, ``Thumbs.db``) are left out and named; after bagit has written its
manifest, each file's digest is compared with the one its sidecar recorded when it was written.

Nothing half-made is left: the bag is built in a hidden folder beside ``out`` and renamed to ``out`` only when
complete; any error (a full disk included) removes it and is one line.
"""
from __future__ import annotations

import errno
import json
import logging
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from dualrgb.app.workflow.delivery.fixity import (
    FIXITY_ALGORITHM,
    VerifyReport,
    debris_kind,
    find_sidecars,
    unsealed_deliveries,
    verify_sidecar,
)

log = logging.getLogger(__name__)

PREVIOUS = "previous"


@dataclass
class DayBag:
    """A bag made by :func:`make_day_bag`."""

    path: Path
    originals: list[str]
    files: int
    bytes: int
    placed: dict[str, int] = field(default_factory=dict)     # how the payload was placed: reflink / copy / link
    left_out: list[str] = field(default_factory=list)        # one line per debris file not packed

    def summary(self) -> str:
        how = ", ".join(f"{n} {k}" for k, n in sorted(self.placed.items()))
        return (f"{self.path}: BagIt 1.0 bag of {len(self.originals)} original{'s' * (len(self.originals) != 1)}, "
                f"{self.files} files, {self.bytes / 1e6:.1f} MB ({how}; manifests {FIXITY_ALGORITHM}, checked "
                "against the sidecars)")


def current_sidecars(source: Path) -> list[Path]:
    """The sidecars of the current deliveries under ``source`` (not the previous sets re-deliveries kept)."""
    source = Path(source)
    return [p for p in find_sidecars(source)
            if PREVIOUS not in p.resolve().relative_to(source.resolve()).parts[:-1]]


FICLONE = 0x40049409          # Linux ioctl: clone a whole file (reflink), where the file system supports it


def reflink(src: Path, dst: Path) -> bool:
    """Make ``dst`` a copy-on-write clone of ``src``; False (nothing left at ``dst``) where it is not offered."""
    try:
        import fcntl
    except ImportError:                          # pragma: no cover - Windows
        return False
    with open(src, "rb") as fin:
        fd = os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        try:
            fcntl.ioctl(fd, FICLONE, fin.fileno())
        except OSError as exc:
            os.close(fd)
            os.unlink(dst)
            if exc.errno in (errno.EOPNOTSUPP, errno.EXDEV, errno.EINVAL, errno.ENOTTY, errno.EPERM,
                             errno.EBADF):
                return False
            raise
        os.close(fd)
    shutil.copystat(src, dst)
    return True


def place(src: Path, dst: Path, link: bool = False) -> str:
    """Put ``src`` at ``dst``: a hard link when ``link`` (a copy where links are refused), else a reflink where the
    file system offers one, else a byte copy; returns which ('link', 'reflink', 'copy')."""
    if link:
        try:
            os.link(src, dst)
            return "link"
        except OSError as exc:                       # another file system, or links not allowed: copy instead
            log.info("%s: not linked (%s), copied", src, exc)
    elif reflink(src, dst):
        return "reflink"
    shutil.copy2(src, dst)
    return "copy"


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


def make_day_bag(source: Path, out: Path, *, info: dict[str, str] | None = None, link: bool = False,
                 processes: int = 1) -> DayBag:
    """Bag the current deliveries under ``source`` (a deliverables folder or a session) into the new folder
    ``out`` (module docstring); ValueError (one line) when there is nothing to bag, a delivery does not match its
    sidecar, ``out`` exists and is not empty, or writing fails (then nothing is left at ``out``)."""
    source, out = Path(source), Path(out)
    sidecars = current_sidecars(source)
    if not sidecars:
        raise ValueError(f"{source}: no dualrgb delivery to bag")
    report = VerifyReport()
    for sidecar in sidecars:
        verify_sidecar(sidecar, report)
    if source.is_dir():                          # a delivery whose sidecar is gone is not left out unsaid
        report.problems.extend(line for _, line in unsealed_deliveries(source, sidecars))
    if report.problems:
        raise ValueError(f"not bagged: {len(report.problems)} problem(s), the first: {report.problems[0]} "
                         f"(dualrgb verify {source} lists them)")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"{out}: exists and is not an empty folder; the bag needs a new one")
    out.parent.mkdir(parents=True, exist_ok=True)
    work = out.parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(work, ignore_errors=True)
    try:
        bag = _build(sidecars, work, info or {}, link, processes)
        if out.exists():
            out.rmdir()
        os.rename(work, out)
    except BaseException as exc:
        shutil.rmtree(work, ignore_errors=True)
        if isinstance(exc, OSError):
            raise ValueError(_write_failure(exc, out)) from None
        raise
    bag.path = out
    bag.left_out = [f"left out {p}: {debris_kind(p.name)}" for p in report.debris]
    log.info("bag %s: %d originals, %d files", out, len(bag.originals), bag.files)
    return bag


def _write_failure(exc: OSError, out: Path) -> str:
    what = "no space left on the device" if exc.errno == errno.ENOSPC else (exc.strerror or str(exc))
    where = f" ({exc.filename})" if exc.filename else ""
    return f"not bagged: {what}{where}; nothing was left at {out} (free space, or choose another folder, and run again)"


def _build(sidecars: list[Path], work: Path, info: dict[str, str], link: bool, processes: int) -> DayBag:
    """The bag in the folder ``work``: payload placed, bagit's manifests, BagIt 1.0, checked against the sidecars."""
    import bagit

    work.mkdir()
    expected: dict[str, str] = {}
    originals: list[str] = []
    placed: dict[str, int] = {}
    for sidecar in sidecars:
        doc = json.loads(sidecar.read_text(encoding="utf-8"))
        folder = work / sidecar.parent.name
        folder.mkdir()
        for name, fix in doc["fixity"]["files"].items():
            how = place(sidecar.parent / name, folder / name, link)
            placed[how] = placed.get(how, 0) + 1
            expected[f"data/{folder.name}/{name}"] = fix[FIXITY_ALGORITHM]
        how = place(sidecar, folder / sidecar.name, link)
        placed[how] = placed.get(how, 0) + 1
        originals.append(str(doc["original"]["identifier"]))
    bag_info = {"External-Description": f"dualrgb deliverables of {len(originals)} original(s): "
                                        + ", ".join(originals[:20]) + (" ..." if len(originals) > 20 else ""),
                **info}
    bagit.make_bag(str(work), bag_info=bag_info, processes=processes, checksums=[FIXITY_ALGORITHM])
    (work / "bagit.txt").write_text("BagIt-Version: 1.0\nTag-File-Character-Encoding: UTF-8\n", encoding="utf-8")
    bag = bagit.Bag(str(work))
    bag.save(processes=processes)                    # the tag manifests again, over the 1.0 bagit.txt
    _check_manifest(work, expected)
    oxum_bytes, _, oxum_files = str(bag.info.get("Payload-Oxum", "0.0")).partition(".")
    return DayBag(work, originals, int(oxum_files or 0), int(oxum_bytes or 0), placed)
