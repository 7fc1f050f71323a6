"""Time to a refusal (issue 43): a capture or ``process`` whose calibration, session or file is missing is refused
before the heavy imports and the kernels' warm-up (app.cli_refusals), as fast as ``verify`` answering a missing
folder. Median seconds of each command (interleaved rounds), its exit status and the refusal's line.

Target: within 2 s on a quiet machine. Run alone: ``python -m bench.refusals`` (``make bench`` writes
bench/results/refusals.json; docs/data/bench/refusals.json is the committed run the docs cite).
"""
from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_S = 2.0
REPEATS = 5


def _cli() -> list[str]:
    return [sys.executable, "-m", "dualrgb"]


def _runs(tmp: Path) -> dict[str, list[str]]:
    from dualrgb.core.session.capture_session import CaptureSession

    empty = tmp / "empty-session"                 # a session with no calibration in it
    CaptureSession.create(empty, {"bench": "refusals"}).close()
    return {
        "capture_missing_session": ["capture", "--session", str(tmp / "no-such-day"), "--id", "ACC-1",
                                    "--virtual-lab"],
        "capture_no_calibration_in_session": ["capture", "--session", str(empty), "--id", "ACC-1", "--virtual-lab"],
        "capture_missing_calibration_file": ["capture", "--calibration", str(tmp / "cal-none.json"), "--id", "ACC-1",
                                             "--virtual-lab"],
        "process_missing_session": ["process", str(tmp / "no-such-day")],
        "process_no_calibration_in_session": ["process", str(empty)],
        "verify_missing_folder": ["verify", str(tmp / "no-such-folder")],
    }


def _once(argv: list[str]) -> tuple[float, int, str]:
    t0 = time.perf_counter()
    r = subprocess.run([*_cli(), *argv], capture_output=True, text=True, check=False)
    lines = (r.stderr.strip() or r.stdout.strip()).splitlines()
    return time.perf_counter() - t0, r.returncode, lines[-1] if lines else ""


def bench_refusals(repeats: int = REPEATS) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        runs = _runs(Path(tmp))
        times: dict[str, list[float]] = {k: [] for k in runs}
        said: dict[str, tuple[int, str]] = {}
        for _ in range(repeats):
            for label, argv in runs.items():
                s, rc, line = _once(argv)
                times[label].append(s)
                said[label] = (rc, line.replace(tmp, "<tmp>"))
    out = {label: {"median_s": round(statistics.median(t), 3), "max_s": round(max(t), 3), "exit": said[label][0],
                   "said": said[label][1]} for label, t in times.items()}
    slowest = max(v["median_s"] for k, v in out.items() if not k.startswith("verify"))
    return {"target_s": TARGET_S, "repeats": repeats, "commands": out, "slowest_refusal_median_s": slowest,
            "within_target": slowest <= TARGET_S}


if __name__ == "__main__":
    import json

    print(json.dumps(bench_refusals(), indent=2))
