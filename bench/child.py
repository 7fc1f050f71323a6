"""One measurement in a fresh Python process, so its peak RSS (``ru_maxrss``) is that measurement's alone, and the
process CPU time the measurements report beside the wall time."""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cpu_s() -> float:
    """User + system CPU seconds of this process so far, every thread (CLOCK_PROCESS_CPUTIME_ID: nanoseconds,
    where os.times() counts 10 ms ticks, too coarse for a stage summed over many bands)."""
    return time.process_time()


def run_in_child(module: str, function: str, *args: object) -> dict:
    """``module.function(*args)`` (a dict, its arguments plain literals) in a fresh interpreter, with
    ``peak_rss_mb`` added."""
    code = (f"import json, resource, sys; sys.path.insert(0, {str(ROOT)!r}); "
            f"from {module} import {function}; r = {function}(*{args!r}); "
            "r['peak_rss_mb'] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024; print(json.dumps(r))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def write_result(result: dict, json_path: Path | None) -> dict:
    """A bench's JSON written (its folder made) where ``json_path`` names one; the result returned."""
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(result, indent=2) + "\n")
    return result
