"""A queue CSV as a collection database exports it (issue 19), for the queue tests (tests/app/test_queue_csv.py,
tests/e2e/test_metadata_cli.py): 20 originals with German, French and Japanese titles, UTF-8 with a BOM, CRLF,
quoted fields with embedded line breaks and separators, the identifier in a column named 'Inventarnummer', an
extra column 'Standort', and three bad rows (as a spreadsheet numbers them; the header is row 1)."""
from __future__ import annotations

import csv
import io
from pathlib import Path

HEADER = ["Inventarnummer", "Title", "operator", "Notes", "mode", "Standort"]
TITLES = ["Öl auf Holz", "Étude pour « La Grève »", "富嶽三十六景", "Stillleben, mit Äpfeln", "Vue de l'Estaque",
          "京都の町並み"]
BAD = {6: ("Title", "control character U+0001 at character 5 is not allowed"),
       11: ("Inventarnummer", "'Q-3' is also row 4"),
       17: ("mode", "'film': expected reflective or transmissive")}


def rows() -> list[list[str]]:
    out = []
    for n in range(2, 22):                       # spreadsheet rows 2..21
        ident = f"Q-{n - 1}" + ("é" if n % 5 == 0 else "")
        title = f"{TITLES[n % len(TITLES)]} {n}"
        notes = f"Zeile 1\nligne 2 ({n})" if n % 3 == 0 else ""
        mode = "reflective" if n % 4 else ""
        if n == 6:
            title = "Bild\x01 6"
        if n == 11:
            ident = "Q-3"
        if n == 17:
            mode = "film"
        out.append([ident, title, "Jürgen Weiß" if n % 2 else "", notes, mode, f"Depot {n}; Regal {n % 4}"])
    return out


def write_queue_csv(path: Path, *, bom: bool = True, crlf: bool = True) -> Path:
    buf = io.StringIO(newline="")
    writer = csv.writer(buf, lineterminator="\r\n" if crlf else "\n")
    writer.writerow(HEADER)
    writer.writerows(rows())
    path.write_bytes(("\ufeff" if bom else "").encode() + buf.getvalue().encode("utf-8"))
    return path


def good_identifiers() -> list[str]:
    return [r[0] for n, r in enumerate(rows(), start=2) if n not in BAD]
