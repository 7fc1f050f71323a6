"""``make bench``: run every benchmark, print a summary and write bench/results/<name>.json."""
from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import sys
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"

# name -> (module, function, kwargs); each returns a JSON-able dict
BENCHES = {
    "startup": ("bench.startup", "bench_startup", {}),
    "simulation": ("bench.simulation_bench", "bench_simulation", {}),
    "virtual_camera": ("bench.virtual_camera", "bench_render", {}),
    "processing": ("bench.processing_bench", "bench_processing", {}),
    "digitise": ("bench.digitise_bench", "bench_digitise", {}),
    "unbinned": ("bench.studies", "bench_unbinned", {}),
    "cancel_latency": ("bench.cancel_latency", "bench_cancel_latency", {}),
    "process": ("bench.process_bench", "bench_process", {}),
    "input_bounds": ("bench.input_bounds", "bench_input_bounds", {}),
    "masters": ("bench.masters_bench", "bench_masters", {}),
    "stand_wait": ("bench.stand_wait", "bench_stand_wait", {}),
    "stand_wait_24mp": ("bench.stand_wait", "bench_stand_wait_24mp", {}),
    "gui_stall": ("bench.gui_stall", "bench_gui_stall", {}),
    "light_gaps_load": ("bench.light_gaps_load", "bench_light_gaps_load", {}),
    "refusals": ("bench.refusals", "bench_refusals", {}),
}


def machine() -> dict:
    return {"python": platform.python_version(), "cpus": os.cpu_count(), "platform": platform.platform(),
            "when": time.strftime("%Y-%m-%dT%H:%M:%S")}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("names", nargs="*", help=f"benchmarks to run (default all: {', '.join(BENCHES)})")
    args = p.parse_args(argv)
    RESULTS.mkdir(parents=True, exist_ok=True)
    names = args.names or list(BENCHES)
    failed = 0
    for name in names:
        mod, fn, kwargs = BENCHES[name]
        print(f"== {name}", flush=True)
        t = time.perf_counter()
        try:
            result = getattr(importlib.import_module(mod), fn)(**kwargs)
        except Exception as exc:  # noqa: BLE001 - a benchmark failing must not hide the others' results
            print(f"   FAILED: {type(exc).__name__}: {exc}", flush=True)
            failed += 1
            continue
        result = {"benchmark": name, "machine": machine(), "wall_s": round(time.perf_counter() - t, 2), **result}
        (RESULTS / f"{name}.json").write_text(json.dumps(result, indent=2) + "\n")
        print(json.dumps(result, indent=2), flush=True)
        lines = getattr(importlib.import_module(mod), "summary_lines", None)       # a bench's own short summary
        if lines is not None:
            print("\n".join(lines(result)), flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
