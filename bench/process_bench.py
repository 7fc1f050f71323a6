"""Re-delivery at archive scale (issue 41): ``dualrgb process`` of 3 sessions x 4 originals (virtual lab, 600x400
frames, full resolution) serially, with ``--jobs 2`` and on a local Dask cluster of two workers (``dask scheduler``
+ 2 ``dask worker``), in wall seconds and CPU seconds (this process's children: the CLI and its workers, or the
Dask workers), with the efficiency of each against the serial run; then a paper model of 10 and 100 machines from
the measured cost per original and the file system's bandwidth.

On the 2-core development machine parity is the expectation, not speed-up: the serial run already keeps the two
cores partly busy (the delivery's writer threads), so the figure of interest is the efficiency (how much of the
work is lost to the parallel machinery) and that every run delivers the same bytes.

    python -m bench.process_bench [--originals 4] [--sessions 3] [--frame 600x400]
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EPOCH = "1767225600"
ENV = {**os.environ, "PYTHONUNBUFFERED": "1", "SOURCE_DATE_EPOCH": EPOCH}
MACHINES = (10, 100)
CORES_PER_MACHINE = 8                   # the paper model's assumed archive worker
FS_MB_S = (500, 2000)                   # a shared file system's aggregate read+write bandwidth, MB/s: NFS on 10 GbE,
                                        # a parallel file system (assumed; the local disk's measured figure is beside)


def _cli(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    r = subprocess.run([sys.executable, "-m", "dualrgb", *args], capture_output=True, text=True, env=ENV)
    if check and r.returncode != 0:
        raise RuntimeError(f"dualrgb {' '.join(args[:2])} failed: {r.stderr[-2000:]}")
    return r


def make_sessions(root: Path, sessions: int, originals: int, frame: str) -> tuple[list[Path], str]:
    """``sessions`` sessions of ``originals`` originals each, the first calibrated, all captured with that
    calibration (passed to ``process`` with --calibration: it lies outside the other sessions); and its path."""
    first = root / "s1"
    _cli("calibrate", "--session", str(first), "--virtual-lab", "--frame-size", frame, "--settle", "0",
         "--json", str(root / "cal.json"))
    cal = json.loads((root / "cal.json").read_text())["calibration"]
    out = []
    for s in range(sessions):
        session = root / f"s{s + 1}"
        for o in range(originals):
            _cli("capture", "--session", str(session), "--calibration", cal, "--id", f"S{s + 1}-{o + 1}",
                 "--virtual-lab", "--frame-size", frame, "--settle", "0")
        out.append(session)
    return out, cal


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _digests(folder: Path) -> str:
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            h.update(str(p.relative_to(folder)).encode() + hashlib.sha256(p.read_bytes()).digest())
    return h.hexdigest()


def _timed_process(sessions: list[Path], cal: str, out: Path, *extra: str) -> dict:
    shutil.rmtree(out, ignore_errors=True)
    c0, t0, load0 = _children_cpu(), time.perf_counter(), os.getloadavg()[0]
    _cli("process", *map(str, sessions), "--calibration", cal, "--out", str(out),
         "--json", str(out.with_suffix(".json")), *extra)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - c0
    doc = json.loads(out.with_suffix(".json").read_text())
    per = [o["cpu_s"] for o in doc["originals"]]
    return {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2), "originals": len(doc["originals"]),
            "task_cpu_s_mean": round(sum(per) / len(per), 3), "task_s_mean":
            round(sum(o["seconds"] for o in doc["originals"]) / len(per), 3),
            "task_s_sum": round(sum(o["seconds"] for o in doc["originals"]), 2),
            "workers": len({o["worker"] for o in doc["originals"]}), "digest": _digests(out),
            "load_1min": [round(load0, 2), round(os.getloadavg()[0], 2)]}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _dask_cluster(workers: int) -> tuple[str, list[subprocess.Popen], float]:
    from distributed import Client

    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = str(Path(sys.executable).with_name("dask"))
    t0 = time.perf_counter()
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=ENV)]
    procs += [subprocess.Popen([dask, "worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=ENV) for _ in range(workers)]
    with Client(address, timeout=120) as client:
        client.wait_for_workers(workers, timeout=600)
    return address, procs, time.perf_counter() - t0


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in reversed(procs):
        p.send_signal(signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=60)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def _disk_gb_s(folder: Path, mb: int = 256) -> float:
    """This machine's sequential write+read bandwidth (GB/s) with a ``mb`` MB file (fsynced; read cold-ish)."""
    path = folder / "bandwidth.bin"
    block = os.urandom(1 << 20)
    t0 = time.perf_counter()
    with open(path, "wb") as fh:
        for _ in range(mb):
            fh.write(block)
        fh.flush()
        os.fsync(fh.fileno())
    with open(path, "rb") as fh:
        while fh.read(1 << 22):
            pass
    seconds = time.perf_counter() - t0
    path.unlink()
    return round(2 * mb / 1024 / seconds, 2)


def paper_model(task_cpu_s: float, bytes_per_original: int, n_originals: int = 100_000) -> list[dict]:
    """Hours for ``n_originals`` on M machines of CORES_PER_MACHINE cores: the larger of the compute time
    (CPU-s per original / all cores) and the I/O time (bytes read and written / the file system's bandwidth)."""
    rows = []
    for machines in MACHINES:
        for mb_s in FS_MB_S:
            compute = n_originals * task_cpu_s / (machines * CORES_PER_MACHINE)
            io = n_originals * bytes_per_original / (mb_s * 1e6)
            rows.append({"machines": machines, "cores": machines * CORES_PER_MACHINE, "fs_mb_s": mb_s,
                         "compute_h": round(compute / 3600, 2), "io_h": round(io / 3600, 2),
                         "hours": round(max(compute, io) / 3600, 2),
                         "bound_by": "file system" if io > compute else "compute"})
    return rows


def _bytes_per_original(out: Path, sessions: list[Path], originals: int) -> int:
    written = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    read = sum(p.stat().st_size for s in sessions for p in s.glob("*.dng"))
    return int((written + read) / originals)


DIGITISE_24MP = Path(__file__).resolve().parents[1] / "docs" / "notes" / "issue-31" / "digitise-24mp-quiet.json"
D610_FRAME_BYTES = 6080 * 4028 * 2            # one 14-bit frame stored in 16 bits (the session's raw file)


def _paper_model_24mp() -> dict:
    """The paper model for D610 originals: the CPU of re-delivering one 24 MP original from its 4 frames on disk
    (bench/digitise_bench.py's full_all_frames, the committed quiet run) and its bytes (4 frames read, the five
    masters written)."""
    doc = json.loads(DIGITISE_24MP.read_text())
    run = doc["full_all_frames"]
    moved = 4 * D610_FRAME_BYTES + sum(run["deliverables_bytes"].values())
    return {"source": str(DIGITISE_24MP.relative_to(DIGITISE_24MP.parents[3])), "task_cpu_s": run["cpu_s"],
            "bytes_per_original": moved, "originals": 100_000, "cores_per_machine": CORES_PER_MACHINE,
            "rows": paper_model(run["cpu_s"], moved)}


def bench_process(sessions: int = 3, originals: int = 4, frame: str = "600x400") -> dict:
    root = Path(tempfile.mkdtemp(prefix="dualrgb_bench_process_"))
    try:
        t0 = time.perf_counter()
        made, cal = make_sessions(root, sessions, originals, frame)
        prepare_s = time.perf_counter() - t0
        serial = _timed_process(made, cal, root / "serial")
        jobs = _timed_process(made, cal, root / "jobs2", "--jobs", "2")
        address, procs, start_s = _dask_cluster(2)
        try:
            c0 = _children_cpu()
            dask = _timed_process(made, cal, root / "dask", "--scheduler", address)
        finally:
            _stop(procs)
        dask["cpu_s_with_workers"] = round(_children_cpu() - c0, 2)    # the workers' CPU, counted once they exit
        dask["cluster_start_s"] = round(start_s, 2)
        n = sessions * originals
        per_original_bytes = _bytes_per_original(root / "serial", made, n)
        for run, workers in ((jobs, 2), (dask, 2)):
            run["speed_up"] = round(serial["wall_s"] / run["wall_s"], 2)
            run["efficiency"] = round(serial["wall_s"] / (run["wall_s"] * workers), 2)
            run["same_bytes_as_serial"] = run["digest"] == serial["digest"]
            # the tasks alone (start-up and hand-overs left out): serial task time over the parallel tasks' time
            run["task_efficiency"] = round(serial["task_s_sum"] / run["task_s_sum"], 2)
            run["start_up_and_overhead_s"] = round(run["wall_s"] - run["task_s_sum"] / workers, 2)
        return {"sessions": sessions, "originals_per_session": originals, "frame": frame, "prepare_s":
                round(prepare_s, 1), "serial": serial, "jobs_2": jobs, "dask_2_workers": dask,
                "bytes_per_original": per_original_bytes, "local_disk_gb_s": _disk_gb_s(root),
                "paper_model": {"originals": 100_000, "cores_per_machine": CORES_PER_MACHINE,
                                "task_cpu_s": serial["task_cpu_s_mean"],
                                "rows": paper_model(serial["task_cpu_s_mean"], per_original_bytes)},
                "paper_model_24mp": _paper_model_24mp(),
                "cpus": os.cpu_count()}
    finally:
        shutil.rmtree(root, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--sessions", type=int, default=3)
    p.add_argument("--originals", type=int, default=4)
    p.add_argument("--frame", default="600x400")
    p.add_argument("--json", type=Path)
    args = p.parse_args(argv)
    result = bench_process(args.sessions, args.originals, args.frame)
    text = json.dumps(result, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
