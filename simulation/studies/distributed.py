"""Running study tasks serially or through Dask (``dask.distributed``), with the same results either way.

A study splits its work into tasks: a top-level function and a list of picklable arguments (a
:class:`~simulation.studies.common.SetupSpec`, seeds, index ranges). :class:`SerialRunner` calls them in
order in this process; :class:`DaskRunner` submits them to a scheduler (``address``) or to a
``LocalCluster`` of worker processes it starts (2 workers, 1 thread each by default), and gathers the
results in task order. Tasks never depend on which worker runs them, so both give the same numbers.

Numba's kernels are parallel; in a Dask worker they are limited to ``threads`` threads so two workers on two
cores do not oversubscribe them.
"""
from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator, Sequence
from typing import Any, Protocol

log = logging.getLogger(__name__)


class Runner(Protocol):
    name: str

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]: ...


class SerialRunner:
    """Runs every task in this process, in order."""

    name = "serial"

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
        return [fn(item) for item in items]

    def describe(self) -> dict:
        return {"runner": "serial"}


def _limited(args: tuple[Callable[[Any], Any], Any, int]) -> Any:
    fn, item, threads = args
    import numba

    most = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]  # set from the environment at import
    numba.set_num_threads(max(1, min(threads, most)))
    return fn(item)


class DaskRunner:
    """Submits tasks to a Dask scheduler; with no address, starts a ``LocalCluster`` of worker processes."""

    name = "dask"

    def __init__(self, address: str | None = None, workers: int = 2, threads: int = 1) -> None:
        from dask.distributed import Client, LocalCluster

        if log.getEffectiveLevel() > logging.INFO:
            logging.getLogger("distributed").setLevel(logging.WARNING)   # its INFO lines on every start/stop
        self.address = address
        self.threads = threads
        self.cluster = None
        if address:
            try:
                self.client = Client(address, timeout="20s")
            except (OSError, TimeoutError) as exc:
                raise OSError(f"Dask scheduler {address}: cannot connect ({exc})") from exc
        else:
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=threads, processes=True,
                                        dashboard_address=None)
            self.client = Client(self.cluster)
        log.info("Dask runner: %s", self.client)

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
        futures = self.client.map(_limited, [(fn, item, self.threads) for item in items], pure=False)
        return self.client.gather(futures)

    def describe(self) -> dict:
        info = self.client.scheduler_info()
        return {"runner": "dask", "scheduler": self.address or "LocalCluster",
                "workers": len(info.get("workers", {})), "threads_per_worker": self.threads}

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


@contextlib.contextmanager
def open_runner(scheduler: str | None = None, *, workers: int = 2, threads: int = 1) -> Iterator[Runner]:
    """``None`` or ``'serial'``: this process; ``'local'``: a LocalCluster of ``workers`` processes;
    anything else: the address of a running scheduler (``tcp://host:8786``)."""
    if scheduler in (None, "", "serial"):
        yield SerialRunner()
        return
    runner = DaskRunner(None if scheduler == "local" else scheduler, workers=workers, threads=threads)
    try:
        yield runner
    finally:
        runner.close()
