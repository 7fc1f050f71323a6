"""Re-delivery at archive scale: every original of many sessions is one task, run serially, on local worker
processes (``--jobs N``) or on a Dask distributed cluster (``--scheduler ADDRESS``).

    tasks = plan_tasks([Path("day1"), Path("day2")], calibration=None, out=None)
    for result in run_tasks(tasks, executor=LocalProcesses(2)):      # or Serial(), DaskCluster("tcp://host:8786")
        print(result.line())

A task names its session, its original and the options as plain strings (it travels to a worker by pickle); the
worker opens the session read-only, loads the calibration once per worker (:func:`_profile`), and delivers the
original exactly as ``dualrgb process`` does serially (app.workflow.delivery.redelivery). The bytes are the same
whichever
executor ran it: the run's one delivery time goes with every task (:func:`run_time`; ``SOURCE_DATE_EPOCH`` fixes it,
the reproducible-builds convention), never a worker's clock.

Resume: a delivered original's sidecar records the task's key (the calibration, the frames' SHA-256 and the
options); a task whose deliverables already carry its key and whose files still match their recorded SHA-256 is
kept, not delivered again, so re-running a killed run does only what is left. A task that fails is tried once
more (a worker lost, a file system hiccup), then reported with its reason; the others go on.
"""
from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, Protocol

from dualrgb.common.errors import ReportedError, one_line

log = logging.getLogger(__name__)

KEY_FIELD = "redelivery_key"          # the sidecar's record of the task that made it (resume)
ATTEMPTS = 2                          # a failed task is tried once more, then reported


@dataclass(frozen=True)
class RedeliveryOptions:
    """What every task of a run shares (plain values: they travel to the workers)."""

    calibration: str | None = None        # a profile's path; None: each session's newest of the original's mode
    out: str | None = None                # deliverables root; None: each session's own deliverables/
    ppi: float | None = None
    render_illuminant: str | None = None  # None: the delivery settings', else the default light
    resolution: str = "full"
    force: bool = False
    delivered_at: str = ""                # ISO time written into every file of the run (run_time())
    out_per_session: bool = False         # several sessions: <out>/<session folder name>/<original>/
    delivery: Any = None                  # app.workflow.delivery.delivery_settings.DeliverySettings (None: the file's)


@dataclass(frozen=True)
class RedeliveryTask:
    session: str                          # the session folder
    identifier: str                       # the original
    options: RedeliveryOptions

    @property
    def label(self) -> str:
        return f"{Path(self.session).name}/{self.identifier}"


@dataclass
class TaskResult:
    """What became of one task: 'delivered', 'kept' (already delivered with the same key), 'refused' (the mode
    rule) or 'failed' (after :data:`ATTEMPTS` tries), with the QA line and the delivered files' SHA-256."""

    task: RedeliveryTask
    status: str
    qa: str = ""
    reason: str = ""
    sidecar: str = ""
    calibration: str = ""                 # the calibration's id (delivered, kept)
    mode: str = ""
    qa_record: dict[str, Any] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)
    sha256: dict[str, str] = field(default_factory=dict)
    attempts: int = 1
    transient: bool = False               # failed in a way another try may not (a worker lost, an OSError)
    seconds: float = 0.0
    cpu_s: float = 0.0
    worker: str = ""

    def line(self, sessions: int = 1) -> str:
        """One line for the user: the QA line (which starts with the identifier), or the identifier and what
        became of it; with several ``sessions``, the session folder's name first."""
        ident = self.task.identifier
        what = {"delivered": self.qa, "kept": f"{ident}: already delivered with this calibration and options, kept",
                "refused": f"refused: {self.reason}", "failed": f"{ident}: not delivered: {self.reason}"}[self.status]
        retried = f" (after {self.attempts} tries)" if self.attempts > 1 else ""
        where = f"{Path(self.task.session).name}: " if sessions > 1 else ""
        return f"{where}{what}{retried}"

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["task"] = {"session": self.task.session, "identifier": self.task.identifier}
        return out


def run_time() -> str:
    """The one delivery time of a run (common.clock.output_time: ``SOURCE_DATE_EPOCH`` when set, else now)."""
    from dualrgb.common.clock import output_time

    return output_time().isoformat(timespec="seconds")


# ---------------------------------------------------------------------------------------------- planning
def plan_tasks(sessions: Sequence[Path], options: RedeliveryOptions) -> tuple[list[RedeliveryTask], list[Any]]:
    """One task per original of each session (in the session's order), and the calibrations they will use; a
    session or calibration that cannot be read is refused in one line naming it, before any task runs."""
    from dualrgb.app.workflow.calibration.profile import load_profile
    from dualrgb.app.workflow.calibration.session_processing import session_frames
    from dualrgb.app.workflow.delivery.redelivery import newest_by_mode
    from dualrgb.app.workflow.stand.folders import open_session
    from dualrgb.core.vocabulary import Role

    profiles = [load_profile(Path(options.calibration))] if options.calibration else []   # a bad one: refused now
    tasks: list[RedeliveryTask] = []
    seen: set[Path] = set()
    for path in sessions:
        resolved = Path(path).resolve()
        if resolved in seen:
            raise ValueError(f"{path}: named twice")
        seen.add(resolved)
        session = open_session(path, readonly=True)
        if not options.calibration:
            profiles += newest_by_mode(session).values()    # loaded and checked here: refused before any delivery
        subjects = [s for s in session_frames(session, intact=False).subjects if s.role is Role.ORIGINAL]
        if not subjects:
            raise ValueError(f"{path}: no originals to process")
        tasks += [RedeliveryTask(str(path), s.name, options) for s in subjects]
    return tasks, profiles


# ---------------------------------------------------------------------------------------------- one task
@functools.lru_cache(maxsize=16)
def _profile(path: str, mtime_ns: int) -> Any:
    """A calibration, loaded once per worker (the key holds the file's mtime: an edited file is read again)."""
    from dualrgb.app.workflow.calibration.profile import load_profile

    return load_profile(Path(path))


def _profiles(task: RedeliveryTask) -> Any:
    """The calibration(s) of a task: the one named, else the session's newest per mode."""
    from dualrgb.app.workflow.delivery.redelivery import session_calibrations

    if task.options.calibration:
        path = Path(task.options.calibration)
        return _profile(str(path), path.stat().st_mtime_ns)
    from dualrgb.app.workflow.calibration.profile import load_profile
    from dualrgb.app.workflow.stand.folders import open_session

    newest: dict[str, Path] = {}
    for path in session_calibrations(open_session(Path(task.session), readonly=True)):
        newest[load_profile(path, arrays=False).mode] = path
    if not newest:
        raise ValueError(f"{task.session}: no calibration in it or named by its originals; pass --calibration FILE")
    return {mode: _profile(str(p), p.stat().st_mtime_ns) for mode, p in newest.items()}


def task_key(task: RedeliveryTask, calibration_id: str, frames: Iterable[str], original: dict[str, Any]) -> str:
    """The SHA-256 of what decides a task's bytes: the software, the calibration, the frames' SHA-256, the
    original's metadata and the options."""
    from dualrgb.simulation.versions import dualrgb_version

    opts = {k: v for k, v in asdict(task.options).items() if k not in ("delivered_at", "calibration", "out")}
    doc = {"software": dualrgb_version(), "calibration": calibration_id, "frames": sorted(frames),
           "original": original, "options": opts}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def run_task(task: RedeliveryTask) -> TaskResult:
    """Deliver one original (in whatever process runs it); never raises for the original's own problems."""
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        result = _deliver_task(task)
    except (ValueError, OSError, ReportedError) as exc:
        log.warning("%s: not delivered: %s", task.label, exc)
        result = TaskResult(task, "failed", reason=one_line(exc), transient=_transient(exc))
    result.seconds, result.cpu_s = time.perf_counter() - t0, time.process_time() - c0
    result.worker = f"{os.uname().nodename}:{os.getpid()}"
    return result


def _transient(exc: BaseException) -> bool:
    """Whether another try may succeed: an OS-level failure (a file system hiccup, a full disk freed meanwhile),
    not the original's own problem (damaged frames, another original's folder, the mode rule, bad metadata)."""
    from dualrgb.core.session.manifest import DamagedFramesError

    return isinstance(exc, OSError) and not isinstance(exc, (DamagedFramesError, FileNotFoundError))


def _deliver_task(task: RedeliveryTask) -> TaskResult:
    from dualrgb.app.workflow.calibration.session_processing import select_lights, session_frames
    from dualrgb.app.workflow.delivery.redelivery import _known_original, _profile_for, _redeliver_one
    from dualrgb.app.workflow.stand.folders import open_session
    from dualrgb.core.vocabulary import Subject

    session = open_session(Path(task.session), readonly=True)
    original = _known_original(session, session.settings.get("originals", {}), task.identifier)
    profile, override = _profile_for(original, _profiles(task), task.options.force)
    if profile is None:
        return TaskResult(task, "refused", reason=override)
    frames = session_frames(session, intact=False)
    subject = Subject.original(task.identifier)
    used = select_lights(frames.subject(subject), [nl.name for nl in profile.lights])
    sums = {e.file: e.sha256 for e in session.entries()}
    key = task_key(task, profile.id, (sums.get(r.label, r.label) for refs in used.values() for r in refs),
                   original.to_dict())
    kept = _already(out_folder(task), original, key)
    if kept is not None:
        return TaskResult(task, "kept", sidecar=str(kept), calibration=profile.id, mode=profile.mode)
    damaged = {e.file: problem for e, problem in session.damaged()}
    delivery = _redeliver_one(session, frames, subject, original, profile, damaged, out_folder(task),
                              task.options.ppi, None,
                              task.options.render_illuminant, override, task.options.resolution,
                              task.options.delivery, extra={KEY_FIELD: key},
                              now=datetime.fromisoformat(task.options.delivered_at) if task.options.delivered_at
                              else None)
    return TaskResult(task, "delivered", qa=delivery.qa.text(), sidecar=str(delivery.sidecar),
                      calibration=profile.id, mode=profile.mode, qa_record=delivery.qa.to_dict(),
                      files={k: str(v) for k, v in delivery.files.items()}, sha256=_sha256_of(delivery.sidecar))


def out_folder(task: RedeliveryTask) -> Path:
    """Where a task's original is delivered: ``--out`` (per session below it when several), else the session's
    own deliverables folder."""
    if not task.options.out:
        return Path(task.session) / "deliverables"
    out = Path(task.options.out)
    return out / Path(task.session).name if task.options.out_per_session else out


def _already(out: Path, original: Any, key: str) -> Path | None:
    """The sidecar of ``original``'s delivery in ``out`` when it carries ``key`` and its files still match their
    recorded SHA-256 (a killed run's finished originals); None otherwise."""
    from dualrgb.app.workflow.delivery.delivery_folder import sidecar_of
    from dualrgb.app.workflow.delivery.fixity import VerifyReport, verify_sidecar

    sidecar = sidecar_of(out, original)
    try:
        doc = json.loads(sidecar.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if doc.get(KEY_FIELD) != key:
        return None
    report = VerifyReport()
    verify_sidecar(sidecar, report)
    if report.problems:
        log.info("%s: delivered before but not intact (%s): delivering again", original.identifier,
                 report.problems[0])
        return None
    return sidecar


def _sha256_of(sidecar: Path) -> dict[str, str]:
    """File name -> SHA-256 of every file the sidecar lists, and of the sidecar itself."""
    doc = json.loads(sidecar.read_text(encoding="utf-8"))
    out = {name: rec.get("sha256", "") for name, rec in (doc.get("fixity", {}).get("files") or {}).items()}
    out[sidecar.name] = hashlib.sha256(sidecar.read_bytes()).hexdigest()
    return out


# ---------------------------------------------------------------------------------------------- executors
class Executor(Protocol):
    """Runs tasks and yields their results as they finish."""

    name: str

    def map(self, tasks: Sequence[RedeliveryTask]) -> Iterator[TaskResult]: ...


class Serial:
    """Every task in this process, in order."""

    name = "serial"

    def map(self, tasks: Sequence[RedeliveryTask]) -> Iterator[TaskResult]:
        return (run_task(t) for t in tasks)


def _worker_start() -> None:
    """Each worker's start-up, paid once per worker (not per session or original): the delivery's modules
    imported, and on a machine whose numba cache is cold (a new cluster node) the kernels compiled once, here."""
    from dualrgb.app.warm_kernels import ensure_ready
    from dualrgb.app.workflow.delivery import redelivery  # noqa: F401 - imported once per worker, not per task

    ensure_ready(say=lambda line: log.warning("%s", line))


class LocalProcesses:
    """``--jobs N``: N worker processes on this machine (their start-up paid once each)."""

    def __init__(self, jobs: int):
        if jobs < 1:
            raise ValueError(f"--jobs {jobs}: expected 1 or more")
        self.jobs = jobs
        self.name = f"{jobs} local processes"

    def map(self, tasks: Sequence[RedeliveryTask]) -> Iterator[TaskResult]:
        import multiprocessing

        # spawn, not fork: a forked child of a process with threads (numba, the progress printer) can deadlock
        with ProcessPoolExecutor(self.jobs, mp_context=multiprocessing.get_context("spawn"),
                                 initializer=_worker_start) as pool:
            futures: dict[Future[TaskResult], RedeliveryTask] = {pool.submit(run_task, t): t for t in tasks}
            for done in as_completed(futures):
                yield _result_of(done, futures[done])


class DaskCluster:
    """``--scheduler ADDRESS``: the tasks go to a Dask distributed scheduler (``dask scheduler`` + ``dask worker``
    on machines that share the archive's file system)."""

    def __init__(self, address: str):
        self.address = address
        self.name = f"Dask scheduler {address}"

    def map(self, tasks: Sequence[RedeliveryTask]) -> Iterator[TaskResult]:
        try:
            from distributed import Client
            from distributed import as_completed as dask_completed
        except ImportError:
            raise ValueError("--scheduler needs Dask distributed: pip install 'dualrgb[cluster]'") from None
        try:
            client = Client(self.address, timeout=30)
        except OSError as exc:
            raise OSError(f"--scheduler {self.address}: no Dask scheduler answers there ({exc})") from None
        with client:
            client.run(_worker_start)
            futures = {client.submit(run_task, t, pure=False): t for t in tasks}
            for done in dask_completed(list(futures)):
                yield _result_of(done, futures[done])


def _result_of(done: Any, task: RedeliveryTask) -> TaskResult:
    """A finished future's result (concurrent.futures or Dask); a lost worker is the task's transient failure."""
    try:
        return done.result()
    except Exception as exc:  # noqa: BLE001 - a worker killed or out of memory must not stop the other tasks
        return TaskResult(task, "failed", reason=f"worker lost: {one_line(exc)}", transient=True)


def run_tasks(tasks: Sequence[RedeliveryTask], executor: Executor,
              on_result: Callable[[TaskResult], None] | None = None) -> list[TaskResult]:
    """Every task through ``executor``; those that failed transiently once more (same executor); ``on_result`` per
    final result."""
    final: list[TaskResult] = []
    retry: list[RedeliveryTask] = []
    for result in executor.map(tasks):
        if result.status == "failed" and result.transient:
            log.info("%s failed (%s): trying once more", result.task.label, result.reason)
            retry.append(result.task)
            continue
        final.append(result)
        if on_result is not None:
            on_result(result)
    for result in executor.map(retry) if retry else ():
        result.attempts = ATTEMPTS
        final.append(result)
        if on_result is not None:
            on_result(result)
    return final
