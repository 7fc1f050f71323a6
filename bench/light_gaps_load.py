"""The light's timing on a busy host (issue 41): a calibration on the virtual lab (240x160) with ``--busy N`` busy
loops beside it (default 8: load 8 on top of whatever runs), then from its session's manifest: every lit frame's
light-on-to-trigger and exposure-end-to-light-off gaps (core.shooter), the largest of each, the lit periods
whose trigger the host was too late for (not sent, shot again), the frames set aside, and whether the calibration
ended with every frame (no frame lost). The busy loops are this script's own processes, ended by their ids.

    python -m bench.light_gaps_load [--busy N] [--json PATH]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.child import write_result

ROOT = Path(__file__).resolve().parents[1]
DOCS_JSON = ROOT / "docs" / "data" / "bench" / "light_gaps_load.json"


def _manifest_gaps(session: Path) -> dict:
    on, off, late, rejected = [], [], 0, 0
    for line in (session / "manifest.jsonl").read_text().splitlines():
        rec = json.loads(line)
        gaps = (rec.get("meta") or {}).get("light_gaps")
        rejected += rec.get("role") == "rejected"
        if not gaps:
            continue
        if "sha256" in rec and rec.get("role") != "rejected":
            on.append(gaps["on_to_trigger_s"])
            off.append(gaps["end_to_off_s"])
        elif "sha256" not in rec and gaps.get("end_to_off_s") is None:
            late += gaps.get("on_to_trigger_s", 0) > gaps.get("trigger_bound_s", 1e9)
    return {"lit_frames": len(on), "max_on_to_trigger_s": max(on, default=None),
            "median_on_to_trigger_s": sorted(on)[len(on) // 2] if on else None,
            "max_end_to_off_s": max(off, default=None), "trigger_bound_s": None,
            "lit_periods_host_late": late, "frames_set_aside": rejected}


def bench_light_gaps_load(busy: int = 8, json_path: Path | None = DOCS_JSON) -> dict:
    loops = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(busy)]
    try:
        time.sleep(2.0)                                 # the load settles in
        load_before = os.getloadavg()[0]
        with tempfile.TemporaryDirectory(prefix="dualrgb-light-gaps-") as tmp:
            session = Path(tmp) / "calib"
            t0 = time.perf_counter()
            run = subprocess.run([sys.executable, "-m", "dualrgb", "calibrate", "--session", str(session),
                                  "--virtual-lab", "--frame-size", "240x160", "--dark-frames", "2", "--flat-frames",
                                  "2", "--no-de-fit", "--json", str(Path(tmp) / "cal.json")],
                                 capture_output=True, text=True)
            wall = time.perf_counter() - t0
            load_after = os.getloadavg()[0]
            gaps = _manifest_gaps(session)
            bound = next((json.loads(line)["meta"]["light_gaps"]["trigger_bound_s"]
                          for line in (session / "manifest.jsonl").read_text().splitlines()
                          if "light_gaps" in line), None)
    finally:
        for p in loops:                                 # our own busy loops, by their ids
            p.kill()
            p.wait()
    gaps["trigger_bound_s"] = bound
    result = {"busy_loops": busy, "cpus": os.cpu_count(), "load_1min": [round(load_before, 2), round(load_after, 2)],
              "calibrated": run.returncode == 0, "wall_s": round(wall, 1),
              "last_line": (run.stderr.strip().splitlines() or [""])[-1] if run.returncode else "", **gaps}
    return write_result(result, json_path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--busy", type=int, default=8)
    p.add_argument("--json", type=Path, default=DOCS_JSON)
    args = p.parse_args(argv)
    print(json.dumps(bench_light_gaps_load(args.busy, args.json), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
