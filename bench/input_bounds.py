"""Every input's memory bounded (issue 38): ``dualrgb capture --queue Q --check`` on a 1e6-row, 14 MB queue (under the
16 MiB cap; refused in one line before any row is checked) and on a queue of exactly the stated maximum
(app.workflow.day.queue_csv.MAX_QUEUE_ROWS, every row checked), each in its own process: wall and CPU seconds and peak
RSS. Before issue 38 the first ran past 300 s and 793 MB. Run alone: ``python -m bench.run input_bounds``.
"""
from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
from pathlib import Path


def _queue(path: Path, rows: int) -> Path:
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("identifier,title\n")
        fh.writelines(f"ACC-{i:07d},T\n" for i in range(rows))
    return path


PROBE = ("import json, resource, sys, time; from dualrgb.app.cli import main; t = time.perf_counter(); "
         "rc = main(sys.argv[1:]); print(json.dumps({'exit': rc, 'command_s': time.perf_counter() - t, "
         "'peak_rss_mb': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))")


def _check(queue: Path, profile: Path, work: Path) -> dict:
    """One `capture --check` in a fresh process: exit code, its last line, the command's seconds (imports
    excluded), the process's CPU seconds and peak RSS."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run([sys.executable, "-c", PROBE, "capture", "--virtual-lab", "--calibration", str(profile),
                        "--queue", str(queue), "--check", "--session", str(work / "session")],
                       capture_output=True, text=True, check=False)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    seen = json.loads(r.stdout.strip().splitlines()[-1])
    last = (r.stderr.strip().splitlines() or [""])[-1]
    return {"rows": sum(1 for _ in open(queue, encoding="utf-8")) - 1, "bytes": queue.stat().st_size,
            "exit": seen["exit"], "last_line": last.replace(str(queue), queue.name)[:200],
            "command_s": round(seen["command_s"], 3), "process_cpu_s": round(after.ru_utime + after.ru_stime
                                                                             - before.ru_utime - before.ru_stime, 2),
            "peak_rss_mb": round(seen["peak_rss_mb"], 1)}


def bench_input_bounds() -> dict:
    from dualrgb.app.workflow.day.queue_csv import MAX_QUEUE_ROWS

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from workflow_profiles import make_profile

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        profile = make_profile(work / "cal").path
        million = _check(_queue(work / "million.csv", 1_000_000), profile, work)
        most = _check(_queue(work / "most.csv", MAX_QUEUE_ROWS), profile, work)
    return {"max_queue_rows": MAX_QUEUE_ROWS, "queue_1e6_rows": million, "queue_at_the_maximum": most}
