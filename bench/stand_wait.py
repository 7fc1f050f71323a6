"""Stand wait per original (issue 41): a queue of 3 originals captured on the virtual lab at 600x400 with the D610's
timing (a world with ``camera_timing: "d610"``: 0.07 s shutter lag, 1 s download per frame;
drivers/virtual/camera_timing.py), pipelined (original N delivered while N+1 is metered and shot: the day
``capture --queue`` runs) and sequential (each delivered before the next is metered), interleaved, on the same
calibration (made once, in the same world, with ``dualrgb calibrate``).

Per original it records ``capture_s``, ``deliver_s`` and ``stand_wait_s`` (app.workflow.day.queue_run: between the
end of one original's last exposure and the next one's first trigger, the seconds the stand waited for the computer -
placement, prompts, the light's settle time and the downloads excluded) and the raw gap; and over every lit frame
of the day the largest light-on-to-trigger and exposure-end-to-light-off gaps from the session's manifest
(core.shooter) and how many frames were shot again because the host was late. Target: the pipelined
median ``stand_wait_s`` <= 0.5 s. ``make bench`` runs it at 600x400 (stand_wait.json) and at the D610's 24 MP,
6080x4028 (stand_wait_24mp.json: one repeat; the calibration is made at the same size).

    python -m bench.stand_wait [--repeats N] [--frame WxH] [--json PATH]
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench.child import write_result

ROOT = Path(__file__).resolve().parents[1]
DOCS_JSON = ROOT / "docs" / "data" / "bench" / "stand_wait.json"
DOCS_JSON_24MP = ROOT / "docs" / "data" / "bench" / "stand_wait_24mp.json"
FRAME_24MP = "6080x4028"
FRAME = "600x400"
ORIGINALS = ("BENCH-1", "BENCH-2", "BENCH-3")
TARGET_S = 0.5


def _calibrate(root: Path, world: Path, frame: str) -> Path:
    out = root / "cal.json"
    subprocess.run([sys.executable, "-m", "dualrgb", "calibrate", "--session", str(root / "calib"), "--virtual-lab",
                    "--world", str(world), "--frame-size", frame, "--dark-frames", "1", "--flat-frames", "1",
                    "--no-de-fit", "--json", str(out)], check=True, capture_output=True, text=True)
    return Path(json.loads(out.read_text())["calibration"])


def _gaps(session: Path) -> dict:
    """The largest light gaps of the session's lit frames and the frames the host's lateness cost."""
    on, off, late = [], [], 0
    for line in (session / "manifest.jsonl").read_text().splitlines():
        rec = json.loads(line)
        gaps = (rec.get("meta") or {}).get("light_gaps")
        if not gaps:
            continue
        if "sha256" in rec:
            on.append(gaps["on_to_trigger_s"])
            off.append(gaps["end_to_off_s"])
        elif gaps.get("end_to_off_s") is None and gaps.get("on_to_trigger_s", 0) > gaps.get("trigger_bound_s", 1e9):
            late += 1
    return {"lit_frames": len(on), "max_on_to_trigger_s": max(on, default=None),
            "max_end_to_off_s": max(off, default=None), "reshot_host_late": late}


def _day(root: Path, world: Path, calibration: Path, pipelined: bool, n: int, frame: str) -> dict:
    from dualrgb.app.workflow.calibration.profile import load_profile
    from dualrgb.app.workflow.day.queue_run import capture_queue, median_stand_wait
    from dualrgb.app.workflow.stand.copystand import CopyStand, StandSettings
    from dualrgb.core.metadata import Original
    from dualrgb.core.session.capture_session import CaptureSession
    from dualrgb.drivers.virtual.lab import VirtualLab

    profile = load_profile(calibration)
    w, h = (int(v) for v in frame.split("x"))
    name = f"{'pipelined' if pipelined else 'sequential'}-{n}"
    with VirtualLab(frame_size=(w, h), world=world) as lab:
        session = CaptureSession.create(root / name, {"bench": "stand wait"})

        def place(what: str, nd: bool = False):
            return lab.place("original:painting" if what.startswith("original:") else what, nd)
        stand = CopyStand(lab.camera, lab.sphere, session, stand=place, settings=StandSettings())
        outcomes = capture_queue(stand, [Original(i) for i in ORIGINALS], profile, out_dir=root / name / "out",
                                 pipelined=pipelined)
        session.close()
    return {"originals": [{"identifier": o.original.identifier, **o.timings()} for o in outcomes],
            "median_stand_wait_s": median_stand_wait(outcomes), **_gaps(root / name)}


def bench_stand_wait(repeats: int = 2, json_path: Path | None = DOCS_JSON, frame: str = FRAME) -> dict:
    from dualrgb.app.warm_kernels import ensure_ready
    from dualrgb.drivers.virtual.camera_timing import PRESETS

    ensure_ready()
    with tempfile.TemporaryDirectory(prefix="dualrgb-stand-wait-") as tmp:
        root = Path(tmp)
        world = root / "d610-timing.json"
        world.write_text(json.dumps({"name": "nominal with D610 timing", "camera_timing": "d610"}))
        calibration = _calibrate(root, world, frame)
        runs: dict[str, list[dict]] = {"pipelined": [], "sequential": []}
        for n in range(repeats):                       # interleaved: the machine's load hits both alike
            for mode in runs:
                runs[mode].append(_day(root, world, calibration, mode == "pipelined", n, frame))
    medians = {m: statistics.median(r["median_stand_wait_s"] for r in rs) for m, rs in runs.items()}
    timing = PRESETS["d610"]
    result = {"frame": frame, "originals": len(ORIGINALS), "repeats": repeats,
              "camera_timing": {"preset": "d610", "shutter_lag_s": timing.shutter_lag_s,
                                "download_s": timing.download_s},
              "median_stand_wait_s": {m: round(v, 3) for m, v in medians.items()},
              "target_stand_wait_s": TARGET_S, "meets_target": medians["pipelined"] <= TARGET_S,
              "max_on_to_trigger_s": max(r["max_on_to_trigger_s"] or 0 for rs in runs.values() for r in rs),
              "reshot_host_late": sum(r["reshot_host_late"] for rs in runs.values() for r in rs),
              "runs": runs}
    return write_result(result, json_path)


def bench_stand_wait_24mp(repeats: int = 1, json_path: Path | None = DOCS_JSON_24MP) -> dict:
    """The same day at the D610's full 24 MP frame (the virtual camera renders and writes full-size DNGs)."""
    return bench_stand_wait(repeats, json_path, FRAME_24MP)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--frame", default=FRAME, help=f"the virtual camera's frame WxH (default {FRAME}; 6080x4028: 24 MP)")
    p.add_argument("--json", type=Path, default=DOCS_JSON)
    args = p.parse_args(argv)
    print(json.dumps(bench_stand_wait(args.repeats, args.json, args.frame), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
