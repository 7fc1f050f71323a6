"""Time ``make test``'s stages: ``python -m tools.suite_timing --out FILE.json [--workers N] [--load N] [--cold]``.

Runs what ``make test`` runs, in its order (ruff; then the type check, the wheel smoke and the docs build beside
pytest with ``-n WORKERS --dist loadscope``: the Makefile's ``make -j4 test-parts``), each stage as a child
process, and writes per stage the wall time, the CPU time (user + system of the stage and every process it waited
for: pytest's xdist workers and the CLI processes the tests start), its last output line, pytest's summary line,
the Makefile's one line per side target ("typecheck: passed in 95 s") and the longest test modules' times
(``--durations=0``), with the 1-minute load average sampled every 5 s. The CPU time is the proxy for a quiet
machine's wall time when the machine measured on is shared (docs/notes/issue-26-suite.md).

Stages: ``ruff`` and ``checks+pytest`` (the default: what ``make test`` runs), ``pytest`` alone and
``typecheck+wheel-smoke`` (the type check beside the wheel smoke, as ``make test`` ran them before pytest until
issue 26). ``--workers`` defaults to the Makefile's ``TEST_WORKERS``. ``--load N`` keeps N busy-looping processes
running during each stage (the load-8 check: ``--stages pytest --load 6``, six plus the workers); ``--cold`` gives
pytest an empty numba cache (``NUMBA_CACHE_DIR``), as on a fresh clone. The JSON starts with "format" and
"software" (simulation.versions).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
STAGES = ("ruff", "checks+pytest", "pytest", "typecheck+wheel-smoke")
DEFAULT_STAGES = ("ruff", "checks+pytest")              # make test's order
BUSY = "while True:\n    pass\n"
SUMMARY = re.compile(r"\b\d+ (passed|failed|errors?)\b.* in [\d.]+s\b")          # pytest's last line
DURATION = re.compile(r"^([\d.]+)s (?:setup|call|teardown)\s+([^\s:]+)::", re.MULTILINE)   # --durations=0
SIDE = re.compile(r"\b(typecheck|wheel-smoke|docs): (passed|FAILED).*")   # the Makefile's line per target


def makefile_workers() -> int:
    """The Makefile's ``TEST_WORKERS ?= N``: the workers ``make test`` runs pytest with."""
    found = re.search(r"^TEST_WORKERS \?= (\d+)$", (ROOT / "Makefile").read_text(), re.MULTILINE)
    if found is None:
        raise ValueError("Makefile: no 'TEST_WORKERS ?= N' line")
    return int(found.group(1))


def module_seconds(output: str, top: int = 12) -> dict[str, float]:
    """The ``top`` longest test modules by the sum of their tests' setup, call and teardown times (pytest's
    ``--durations=0`` lines in ``output``): with ``--dist loadscope`` one module's whole time on one worker."""
    total: dict[str, float] = {}
    for seconds, module in DURATION.findall(output):
        total[module] = total.get(module, 0.0) + float(seconds)
    return {m: round(t, 1) for m, t in sorted(total.items(), key=lambda kv: -kv[1])[:top]}


def _command(stage: str, workers: int) -> list[str]:
    return {"ruff": [str(BIN / "ruff"), "check", "."],
            "checks+pytest": ["make", "--no-print-directory", "-j4", "test-parts", f"TEST_WORKERS={workers}"],
            "typecheck+wheel-smoke": ["make", "--no-print-directory", "-j2", "typecheck", "wheel-smoke"],
            "pytest": [sys.executable, "-m", "pytest", "-q", "-n", str(workers), "--dist", "loadscope"]}[stage]


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


class LoadSampler(threading.Thread):
    """The 1-minute load average every ``every_s`` seconds until stopped."""

    def __init__(self, every_s: float = 5.0) -> None:
        super().__init__(daemon=True)
        self.samples: list[float] = []
        self._stop_event, self._every = threading.Event(), every_s

    def run(self) -> None:
        while not self._stop_event.is_set():
            self.samples.append(os.getloadavg()[0])
            self._stop_event.wait(self._every)

    def stop(self) -> dict[str, float]:
        self._stop_event.set()
        self.join()
        s = self.samples or [os.getloadavg()[0]]
        return {"load_1min_mean": round(sum(s) / len(s), 2), "load_1min_max": round(max(s), 2)}


def run_stage(stage: str, workers: int, env: dict[str, str], load: int, log_dir: Path | None = None
              ) -> dict[str, object]:
    """One stage, timed, with ``load`` busy processes beside it."""
    busy = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(load)]
    sampler = LoadSampler()
    sampler.start()
    cpu0, t0 = _children_cpu(), time.perf_counter()
    try:
        proc = subprocess.run(_command(stage, workers), cwd=ROOT, env=env, capture_output=True, text=True)
    finally:
        wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
        for p in busy:
            p.kill()
            p.wait()
    output = proc.stdout + proc.stderr
    tail = output.strip().splitlines()
    summary = [line.strip("= ") for line in tail if SUMMARY.search(line)]
    if log_dir is not None:
        log_dir.mkdir(parents=True, exist_ok=True)
        (log_dir / f"{stage}.log").write_text(proc.stdout + proc.stderr)
    print(f"{stage}: exit {proc.returncode}, {wall:.0f} s wall, {cpu:.0f} s CPU; {tail[-1] if tail else ''}",
          file=sys.stderr)
    return {"command": " ".join(_command(stage, workers)), "exit": proc.returncode, "wall_s": round(wall, 3),
            "cpu_s": round(cpu, 3), **sampler.stop(), "busy_processes": len(busy),
            "last_line": tail[-1] if tail else "", "pytest_summary": summary[-1] if summary else None,
            "side_targets": [m.group(0) for m in map(SIDE.search, tail) if m],    # (after pytest's dots)
            "module_seconds": module_seconds(output)}


def _seconds(stage: dict[str, object], key: str) -> float:
    value = stage[key]
    return float(value) if isinstance(value, (int, float)) else 0.0


def main(argv: list[str] | None = None) -> int:
    from dualrgb.simulation.versions import stamped

    ap = argparse.ArgumentParser(prog="python -m tools.suite_timing", description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, type=Path, help="the JSON to write")
    ap.add_argument("--workers", type=int, default=makefile_workers(),
                    help="pytest-xdist workers (0: one process; default: the Makefile's TEST_WORKERS)")
    ap.add_argument("--load", type=int, default=0, help="busy-looping processes during each stage (default 0)")
    ap.add_argument("--cold", action="store_true", help="pytest with an empty numba cache (a fresh clone's)")
    ap.add_argument("--log-dir", type=Path, help="also write each stage's whole output there (STAGE.log)")
    ap.add_argument("--stages", default=",".join(DEFAULT_STAGES),
                    help=f"comma-separated, of {', '.join(STAGES)} (default: {','.join(DEFAULT_STAGES)})")
    args = ap.parse_args(argv)
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen",      # every test's time, for the modules' times
           "PYTEST_ADDOPTS": f"{os.environ.get('PYTEST_ADDOPTS', '')} --durations=0".strip()}
    with tempfile.TemporaryDirectory(prefix="numba-cold-") as cold:
        if args.cold:
            env["NUMBA_CACHE_DIR"] = cold
        started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        stages = {s: run_stage(s, args.workers, env, args.load, args.log_dir) for s in args.stages.split(",")}
    doc = stamped("dualrgb-suite-timing/1", {
        "started_utc": started, "cpus": os.cpu_count(), "workers": args.workers, "cold_numba_cache": args.cold,
        "stages": stages, "total_wall_s": round(sum(_seconds(s, "wall_s") for s in stages.values()), 3),
        "total_cpu_s": round(sum(_seconds(s, "cpu_s") for s in stages.values()), 3)})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=1) + "\n")
    return 0 if all(s["exit"] == 0 for s in stages.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
