"""Stop the Dask scheduler and workers a docs block started in the background (``dask scheduler ... &``)."""
from __future__ import annotations

import psutil


def stop_dask_on_port(port: int, timeout_s: float = 60.0) -> int:
    """Terminate (then kill) every ``dask scheduler`` / ``dask worker`` process whose command line names ``port``;
    returns how many there were."""
    found = []
    for proc in psutil.process_iter(["cmdline"]):
        cmd = " ".join(proc.info.get("cmdline") or [])
        if "dask" in cmd and ("scheduler" in cmd or "worker" in cmd) and str(port) in cmd:
            found.append(proc)
    for proc in found:
        try:
            for child in proc.children(recursive=True):
                child.terminate()
            proc.terminate()
        except psutil.NoSuchProcess:
            continue
    _gone, alive = psutil.wait_procs(found, timeout=timeout_s)
    for proc in alive:
        proc.kill()
    return len(found)
