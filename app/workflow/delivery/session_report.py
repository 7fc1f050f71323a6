"""The session QA report (``dualrgb report SESSION``): one self-contained HTML page an archivist opens in any
browser - per original a thumbnail, its identifier and title, its QA line, the FADGI / ISO 19264 / Metamorfoze
grades of its calibration and whether its files match their sidecar; per calibration its figures (train / test
mean dE00, the measured criteria and each standard's verdict) and its report's figures.

Nothing unverified is shown: each delivery is checked against its sidecar first (app.workflow.delivery.fixity); a
delivery
that does not match gets its problems in the page instead of a thumbnail. Thumbnails are made from the sRGB
master (memory-mapped, every n-th pixel, 8 bits) and embedded as PNG data, with the calibration's figures, so the
page is one file that can be mailed or archived beside the bag.
"""
from __future__ import annotations

import base64
import html
import io
import logging
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from dualrgb.app.workflow.delivery.bagging import current_sidecars
from dualrgb.app.workflow.delivery.fixity import VerifyReport, unsealed_deliveries, verify_sidecar

log = logging.getLogger(__name__)

THUMB_PX = 240
CAL_FIGURES = ("heatmap_test.png", "tone_test.png", "lab_components_test.png")
STYLE = """body{font-family:sans-serif;margin:2em;color:#222}table{border-collapse:collapse;margin:1em 0}
td,th{border:1px solid #bbb;padding:4px 8px;vertical-align:top;text-align:left}th{background:#eee}
.pass{color:#176217;font-weight:bold}.fail{color:#a31515;font-weight:bold}img.thumb{max-width:240px}
img.fig{max-width:420px;margin:4px}.qa{font-family:monospace;font-size:90%}.bad{color:#a31515}"""


@dataclass
class OriginalRow:
    identifier: str
    title: str
    qa: str
    grades: dict[str, str]
    thumbnail: str = ""                       # PNG data URI ("": none)
    problems: list[str] = field(default_factory=list)
    calibration: str = ""
    files: int = 0
    calibration_file: str = ""                # as the sidecar records it ("": not recorded)


def thumbnail(path: Path, width: int = THUMB_PX) -> str:
    """A PNG data URI of the 16-bit sRGB master at about ``width`` pixels across (every n-th pixel)."""
    import tifffile
    from PIL import Image

    image = tifffile.memmap(path, mode="r")
    step = max(1, int(np.ceil(image.shape[1] / width)))
    small = (np.asarray(image[::step, ::step], dtype=np.uint32) + 128) // 257
    buf = io.BytesIO()
    Image.fromarray(small.astype(np.uint8), "RGB").save(buf, "PNG")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def original_row(sidecar: Path) -> OriginalRow:
    """One original's row: verified first, the thumbnail only from a verified sRGB master."""
    report = VerifyReport()
    doc = verify_sidecar(sidecar, report)
    if doc is None:                         # verify named why; nothing else of it is shown
        return OriginalRow(sidecar.stem, "", "", {}, problems=list(report.problems), files=report.files_ok)
    orig = doc.get("original") or {}
    grading = ((doc.get("qa") or {}).get("grading") or {}).get("standards") or {}
    row = OriginalRow(str(orig.get("identifier", sidecar.stem)), str(orig.get("title") or ""),
                      str((doc.get("qa") or {}).get("text", "")), {s: g["verdict"] for s, g in grading.items()},
                      problems=list(report.problems), calibration=str((doc.get("calibration") or {}).get("id", "")),
                      files=report.files_ok, calibration_file=str((doc.get("calibration") or {}).get("file") or ""))
    srgb = (doc.get("files") or {}).get("srgb")
    if srgb and not report.problems:
        row.thumbnail = thumbnail(sidecar.parent / srgb)
    return row


def _checked_profile(path: Path) -> tuple[dict | None, str]:
    """(the calibration JSON, "") when it passes the profile's checks (schema, ranges, digest), else (None, why)."""
    from dualrgb.app.workflow.calibration.profile_check import check_document, read_document

    try:
        doc = read_document(path)
        check_document(doc, path)
    except (OSError, ValueError) as exc:
        return None, str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return doc, ""


def _calibrations(session: Path, rows: list[OriginalRow]) -> list[dict]:
    """The calibrations the delivered originals' rows name (each checked as a profile is before use; missing or
    failing ones said)."""
    seen: dict[str, dict] = {}
    for row in rows:
        cid = row.calibration
        if not cid or cid in seen:          # a sidecar that fails its checks names no calibration to show
            continue
        path = Path(row.calibration_file)
        candidates = [path, session / "calibration" / f"{cid}.json"]
        found = next((p for p in candidates if str(p) not in ("", ".") and p.is_file()), None)
        doc, problem = _checked_profile(found) if found else (None, "")
        seen[cid] = {"id": cid, "doc": doc, "path": found, "problem": problem}
    return list(seen.values())


def _figure(path: Path) -> str:
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def _verdict(text: str) -> str:
    cls = "fail" if text.startswith("fail") else "pass"
    return f'<span class="{cls}">{html.escape(text)}</span>'


def calibration_html(cal: dict) -> str:
    """A calibration's section: its figures and grading, and its report's figures where they are on disk."""
    e = html.escape
    doc = cal["doc"]
    if doc is None:
        why = cal.get("problem") or "its profile is not in the session"
        return f"<h3>Calibration {e(cal['id'])}</h3><p class=bad>{e(why)}</p>"
    stats = doc.get("statistics") or {}
    best = (stats.get("methods") or {}).get(stats.get("best", ""), {})
    de = {k: (best.get(k) or {}).get("mean") for k in ("train", "test")}
    out = [f"<h3>Calibration {e(cal['id'])}</h3>",
           f"<p>{e(str(doc.get('mode')))}, made {e(str(doc.get('created_at')))}; matrix {e(str(stats.get('best')))}: "
           f"mean dE00 train {_num(de['train'])}, test {_num(de['test'])}</p>"]
    summary = stats.get("quality") or {}
    measured = summary.get("measured") or {}
    if measured:
        out.append("<table><tr><th>measured</th>" + "".join(f"<th>{e(k)}</th>" for k in measured) + "</tr><tr><td>"
                   "value</td>" + "".join(f"<td>{_num(v)}</td>" for v in measured.values()) + "</tr></table>")
    rows = [f"<tr><td>{e(std)}</td><td>{_verdict(g['verdict'])}</td><td>{e(g['scope'])}</td>"
            f"<td>{g['passed']} passed, {g['failed']} failed</td></tr>"
            for std, g in (summary.get("grading") or {}).items()]
    out.append("<table><tr><th>standard</th><th>verdict</th><th>scope</th><th>criteria</th></tr>" + "".join(rows)
               + "</table>" if rows else "<p>no grading recorded (calibrate again)</p>")
    report = Path(str(stats.get("report") or ""))
    folder = report.parent if report.suffix == ".json" else report
    figs = [folder / name for name in CAL_FIGURES if str(folder) not in ("", ".") and (folder / name).is_file()]
    out += [f'<img class=fig alt="{e(p.stem)}" src="{_figure(p)}">' for p in figs]
    return "\n".join(out)


def _num(v: object) -> str:
    return "n/a" if not isinstance(v, int | float) else f"{v:.3g}"


def original_html(row: OriginalRow) -> str:
    e = html.escape
    thumb = (f'<img class=thumb alt="{e(row.identifier)}" src="{row.thumbnail}">' if row.thumbnail
             else '<span class=bad>no thumbnail: the files do not match their sidecar</span>')
    grades = "<br>".join(f"{e(s)}: {_verdict(v)}" for s, v in row.grades.items()) or "not recorded"
    problems = "".join(f"<div class=bad>{e(p)}</div>" for p in row.problems)
    return (f"<tr><td>{thumb}</td><td><b>{e(row.identifier)}</b><br>{e(row.title)}<br>calibration "
            f"{e(row.calibration)}<br>{row.files} files verified</td><td class=qa>{e(row.qa)}{problems}</td>"
            f"<td>{grades}</td></tr>")


def write_report(session: Path, out: Path | None = None) -> tuple[Path, list[OriginalRow]]:
    """Write the session's QA page (default ``<session>/report.html``); (its path, the originals' rows)."""
    from dualrgb.common.atomic_files import atomic_write

    session = Path(session)
    where = session / "deliverables" if (session / "deliverables").is_dir() else session
    sidecars = current_sidecars(where) if where.is_dir() else []
    if not sidecars:
        raise ValueError(f"{session}: no delivered original to report on (no dualrgb delivery sidecar under it)")
    rows = [original_row(s) for s in sidecars]
    rows += [OriginalRow(folder.name, "", "", {}, problems=[line])
             for folder, line in unsealed_deliveries(where, sidecars)]      # a sidecar gone: its row says so
    cals = _calibrations(session, rows)
    e = html.escape
    page = (f"<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>dualrgb QA: {e(session.name)}</title>"
            f"<style>{STYLE}</style></head><body><h1>Session {e(session.name)}: quality report</h1>"
            f"<p>{len(rows)} original(s); made {datetime.now(UTC).isoformat(timespec='seconds')} by dualrgb "
            f"report</p><h2>Originals</h2><table><tr><th>thumbnail</th><th>original</th><th>QA line</th>"
            f"<th>grades (calibration)</th></tr>" + "\n".join(original_html(r) for r in rows) + "</table>"
            "<h2>Calibrations</h2>" + "\n".join(calibration_html(c) for c in cals) + "</body></html>\n")
    path = Path(out) if out is not None else session / "report.html"
    atomic_write(path, page.encode("utf-8"))
    log.info("session report %s: %d originals", path, len(rows))
    return path, rows
