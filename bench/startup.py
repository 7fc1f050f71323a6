"""Start-up of the CLI: ``dualrgb --help``, ``sphere --help``, ``raw-info FILE`` (and ``--version``,
``devices --help``) against a bare ``python -c pass``, as the ratio and in seconds (median of repeats).

Target (issue 13): each starts in <= 0.5 s on the 2-core development machine. For a command over the target
the import profile's top entries (``python -X importtime``, cumulative) are printed, which names what to make
lazy. Run alone: ``python -m bench.startup``.
"""
from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_S = 0.5
REPEATS = 7


def _cli() -> list[str]:
    script = Path(sys.executable).with_name("dualrgb")
    return [str(script)] if script.exists() else [sys.executable, "-m", "dualrgb"]


def _seconds(argv: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    return time.perf_counter() - t0


def _medians(runs: dict[str, list[str]], repeats: int) -> dict[str, float]:
    """Median seconds of each command, run in interleaved rounds so a load change hits all of them alike."""
    times: dict[str, list[float]] = {label: [] for label in runs}
    for _ in range(repeats):
        for label, argv in runs.items():
            times[label].append(_seconds(argv))
    return {label: statistics.median(t) for label, t in times.items()}


def import_profile(args: list[str], top: int = 12) -> list[str]:
    """The ``top`` imports with the largest cumulative time (microseconds) of ``dualrgb ARGS``."""
    code = f"import sys; from dualrgb.app.cli import main; sys.argv[0] = 'dualrgb'; main({args!r})"
    r = subprocess.run([sys.executable, "-X", "importtime", "-c", code], capture_output=True, text=True)
    rows = []
    for line in r.stderr.splitlines():
        if line.startswith("import time:") and "|" in line:
            _, cumulative, name = (p.strip() for p in line[len("import time:"):].split("|"))
            if cumulative.isdigit():
                rows.append((int(cumulative), name))
    return [f"{us / 1000:8.1f} ms  {name}" for us, name in sorted(rows, reverse=True)[:top]]


def _sample_dng(folder: Path) -> Path:
    import numpy as np

    from dualrgb.drivers.virtual.dng import DngInfo, save_dng

    mosaic = np.random.default_rng(0).integers(600, 15520, (64, 96), dtype=np.uint16)
    return save_dng(folder / "sample.dng", mosaic, DngInfo(exposure_s=1 / 60, iso=100))


def bench_startup(repeats: int = REPEATS, commands: dict[str, list[str]] | None = None) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        dng = _sample_dng(Path(tmp))
        commands = commands or {"--help": ["--help"], "--version": ["--version"], "sphere --help": ["sphere", "--help"],
                                "devices --help": ["devices", "--help"], "raw-info FILE": ["raw-info", str(dng)]}
        medians = _medians({"bare": [sys.executable, "-c", "pass"],
                            **{label: _cli() + args for label, args in commands.items()}}, repeats)
        bare = medians["bare"]
        out: dict = {"target_s": TARGET_S, "repeats": repeats, "bare_python_s": round(bare, 4), "commands": {}}
        for label, args in commands.items():
            seconds = medians[label]
            row = {"seconds": round(seconds, 4), "ratio_to_bare_python": round(seconds / bare, 1),
                   "within_target": seconds <= TARGET_S}
            print(f"   {label:<16} {seconds:6.3f} s  {seconds / bare:5.1f}x bare python  "
                  f"{'ok' if seconds <= TARGET_S else f'OVER {TARGET_S} s'}", flush=True)
            if seconds > TARGET_S:
                row["import_profile"] = import_profile(args)
                print("\n".join("      " + line for line in row["import_profile"]), flush=True)
            out["commands"][label] = row
    out["all_within_target"] = all(r["within_target"] for r in out["commands"].values())
    return out


if __name__ == "__main__":
    import json

    print(json.dumps(bench_startup(), indent=2))
