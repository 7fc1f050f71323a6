"""The docs' screenshot of ``dualrgb report`` (docs/screenshots/session_report.png), rendered by headless Chromium
(Debian ``chromium``). A maintainer script, not shipped:

    .venv/bin/python -m tools.report_screenshot [--out docs/screenshots/session_report.png]

It delivers three small originals (ColorChecker colours, as XYZ through a calibration whose matrix is XYZ itself)
into a temporary session with a calibration carrying a grading, writes the session's report with the real
command, and screenshots the page.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

QUALITY = {"measured": {"colour_mean_de00": 0.42, "colour_p90_de00": 0.78, "colour_max_de00": 1.31,
                        "tone_max_abs_dl": 0.9, "white_balance_max_de": 0.6},
           "grading": {std: {"verdict": "pass (measured criteria)", "scope": "colour accuracy only",
                             "passed": n, "failed": 0, "metrics": {}}
                       for std, n in (("FADGI 4-star", 4), ("ISO 19264-1:2021 A", 4), ("Metamorfoze 2.0 Full", 4))}}


def chart_image(seed: int) -> np.ndarray:
    """A 4 x 6 patch image of the ColorChecker's colours (XYZ / 90, shuffled per original), 96 x 144."""
    import colour

    cc = colour.CCS_COLOURCHECKERS["ColorChecker24 - After November 2014"]
    xyz = colour.xyY_to_XYZ(np.array(list(cc.data.values())))
    order = np.random.default_rng(seed).permutation(24) if seed else np.arange(24)
    cells = xyz[order].reshape(4, 6, 3) * 100 / 90
    return np.repeat(np.repeat(cells, 24, 0), 24, 1).astype(np.float32)


def make_session(root: Path) -> Path:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from workflow_profiles import make_profile

    from dualrgb.app.processing.pipeline import ChannelStack
    from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver

    session = root / "2026-03-14-day1"
    prof = make_profile(session / "calibration", shape=(192, 288))
    prof = replace(prof, statistics={**prof.statistics, "quality": QUALITY})
    prof.save(session / "calibration")
    for i, (ident, title) in enumerate((("ACC-1001", "Still life with apples"), ("ACC-1002", "Harbour at dusk"),
                                        ("ACC-1003", "Portrait of a lady")), start=0):
        source = replace(ChannelStack(chart_image(i), ["R1", "G1", "B1"], ["P light 1"], {"P light 1": 0.0}),
                         resolution="full")
        deliver(source, prof, Original(ident, title=title, operator="J. Doe"), session / "deliverables",
                camera=prof.camera, dose=LightDoseRecord(12.0, 0.8), exposures={"P light 1": [0.04]})
    return session


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("docs/screenshots/session_report.png"))
    args = p.parse_args(argv)
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        print("chromium is not installed (Debian: apt-get install chromium)", file=sys.stderr)
        return 1
    from dualrgb.app.cli import main as dualrgb

    with tempfile.TemporaryDirectory() as tmp:
        session = make_session(Path(tmp))
        if dualrgb(["report", str(session)]) != 0:
            return 1
        args.out.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        f"--screenshot={args.out.resolve()}", "--window-size=1100,1400",
                        (session / "report.html").as_uri()], check=True, capture_output=True, timeout=300)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
