"""``dualrgb process``: deliver sessions' originals again, e.g. with a newer calibration, on one machine or many.

    dualrgb process SESSION [SESSION ...] [--calibration FILE|SESSION] [--force] [--out DIR] [--spectral]
                    [--render-illuminant A] [--resolution full|half] [--delivery-settings FILE]
                    [--jobs N | --scheduler ADDRESS] [--json J]

The mode rule (app.workflow.stand.mode_rule) as for ``capture``: without ``--calibration`` each original is delivered
with its session's newest calibration of its own mode; with one, originals of the other mode are refused (listed,
exit 1) unless ``--force``. Every original is one task (app.workflow.delivery.redelivery_jobs): in this process, on
``--jobs
N`` local worker processes or on a Dask cluster (``--scheduler``); a line per original as it ends. Every original
that can be is delivered; those that cannot (a missing or damaged frame, a folder holding another original's
files, a refused QA) are listed one per line, and the command ends with exit 1 (issue 28). Re-running a killed run
keeps what it finished (the sidecar records each task's key) and does the rest.
"""
from __future__ import annotations

import argparse
import contextlib
import logging
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from dualrgb.app.cli import UserError
from dualrgb.app.commands.options import (
    add_render_option,
    add_resolution_option,
    calibration_source,
    count,
    delivery_request,
    number,
)
from dualrgb.app.json_output import add_json_option, text_stream, write_json

if TYPE_CHECKING:
    from dualrgb.app.workflow.delivery.redelivery_jobs import Executor, RedeliveryTask, TaskResult

log = logging.getLogger(__name__)

PROCESS_FORMAT = "dualrgb-process/1"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("process", help="re-process sessions' originals (optionally with another calibration)",
                       description="Delivers every original in each SESSION again from its raw frames (latest takes), "
                                   "with --calibration or each session's newest calibration; what --delivery-settings, "
                                   "--spectral and --ppi do not name is as each original's last delivery asked (its "
                                   "extra masters, access copies, creator, rights and ppi).")
    p.add_argument("sessions", type=Path, nargs="+", metavar="SESSION")
    p.add_argument("--calibration", type=calibration_source, metavar="FILE|SESSION",
                   help="calibration profile (.json), or a session folder: its newest; default: each session's newest")
    p.add_argument("--out", type=Path, help="deliverables folder (default <session>/deliverables; with several "
                                             "sessions, one folder per session below it)")
    p.add_argument("--ppi", type=number(above=0.0),
                   help="sampling of the deliverables (pixels per inch; default: the original's last delivery's, "
                        "else the calibration's)")
    p.add_argument("--force", action="store_true",
                   help="with --calibration: deliver originals of the other mode with it too (said in the sidecar "
                        "and QA line)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--jobs", type=count(1, 512), metavar="N",
                       help="deliver N originals at once on worker processes of this machine (default 1: here)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="send the originals to a Dask distributed scheduler (e.g. tcp://10.0.0.5:8786) whose "
                            "workers see the same files (pip install 'dualrgb[cluster]')")
    add_json_option(p)
    add_render_option(p)
    add_resolution_option(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.cli_refusals import check_sessions, newest_calibration

    calibration = Path(args.calibration) if args.calibration else None
    check_sessions(args.sessions, calibration)          # a missing session or calibration: refused at once
    if calibration is not None and calibration.is_dir():
        calibration = newest_calibration(calibration)
    _check_render(args)
    from dualrgb.app.warm_kernels import ensure_ready
    from dualrgb.app.workflow.delivery.redelivery_jobs import RedeliveryOptions, plan_tasks, run_tasks, run_time
    from dualrgb.core.session.log import SESSION_ONLY

    options = RedeliveryOptions(
        calibration=str(calibration) if calibration else None, out=str(args.out) if args.out else None,
        ppi=args.ppi, render_illuminant=args.render_illuminant, resolution=args.resolution, force=args.force,
        delivered_at=run_time(), out_per_session=len(args.sessions) > 1)
    tasks, profiles = plan_tasks(args.sessions, options)   # every session read and checked before any delivery
    delivery = delivery_request(args, dict(enumerate(profiles)))     # what is asked for, checked before too
    if args.delivery_settings is None and args.spectral is None:
        delivery = None                                 # each original as its last delivery asked (or the file's)
    tasks = [replace(t, options=replace(options, delivery=delivery)) for t in tasks]
    if not (args.scheduler or (args.jobs or 1) > 1):
        ensure_ready()                                  # first run: compiled once here (workers warm up their own)
    executor = _executor(args)
    out = text_stream(args.json)

    def said(result: TaskResult) -> None:          # a line per original as it ends: the run's progress
        line = result.line(len(args.sessions))
        print(line, file=sys.stderr if result.status in ("refused", "failed") else out, flush=True)
        log.info("%s", line, extra={SESSION_ONLY: True})        # and in the sessions' logs, not twice on screen

    with _session_logs(tasks):
        log.info("process: %d originals of %d sessions on %s", len(tasks), len(args.sessions), executor.name)
        results = run_tasks(tasks, executor, on_result=said)
    write_json(args.json, PROCESS_FORMAT, _document(results), default=str)
    return _exit_code(results, len(args.sessions))


def _check_render(args: argparse.Namespace) -> None:
    """A rendering asked for where none is written (at full resolution without --spectral): refused before the
    sessions are read (app.workflow.delivery.delivery_settings.check_render_request)."""
    from dualrgb.app.workflow.delivery.delivery_settings import check_render_request, load

    check_render_request(load(args.delivery_settings).with_spectral(args.spectral), args.resolution,
                         args.render_illuminant)


def _executor(args: argparse.Namespace) -> Executor:
    from dualrgb.app.workflow.delivery.redelivery_jobs import DaskCluster, LocalProcesses, Serial

    if args.scheduler:
        return DaskCluster(args.scheduler)
    if args.jobs and args.jobs > 1:
        return LocalProcesses(args.jobs)
    return Serial()


def _document(results: list[TaskResult]) -> dict:
    used = {r.mode: r.calibration for r in results if r.calibration}
    ids = set(used.values())
    return {"calibration": next(iter(ids)) if len(ids) == 1 else None, "calibrations": used,
            "refused": [r.reason for r in results if r.status == "refused"],
            "not_delivered": [{"session": r.task.session, "identifier": r.task.identifier, "reason": r.reason}
                              for r in results if r.status == "failed"],
            "kept": [{"session": r.task.session, "identifier": r.task.identifier, "sidecar": r.sidecar}
                     for r in results if r.status == "kept"],
            "originals": [{"session": r.task.session, "identifier": r.task.identifier, "qa": r.qa_record,
                           "files": r.files, "sidecar": r.sidecar, "sha256": r.sha256, "seconds": r.seconds,
                           "cpu_s": r.cpu_s, "worker": r.worker, "attempts": r.attempts}
                          for r in results if r.status == "delivered"]}


@contextlib.contextmanager
def _session_logs(tasks: list[RedeliveryTask]) -> Iterator[None]:
    """Each session a task delivers from gets the run in its ``session.log`` (core.session.log), as calibrate,
    capture and import do; opened once every check has passed, so a refused run writes nothing. A run over several
    sessions logs its lines (each naming its session) in each of them."""
    from dualrgb.core.session.log import SessionLog

    with contextlib.ExitStack() as stack:
        for folder in dict.fromkeys(str(t.session) for t in tasks):
            stack.enter_context(SessionLog(folder))
        yield


def _exit_code(results: list[TaskResult], sessions: int) -> int:
    failed = [r for r in results if r.status == "failed"]
    if failed:
        delivered = sum(r.status == "delivered" for r in results)
        names = [r.task.label if sessions > 1 else r.task.identifier for r in failed[:5]]
        raise UserError(f"{len(failed)} of {len(failed) + delivered} originals not delivered (listed above: "
                        f"{', '.join(names)}{' ...' if len(failed) > 5 else ''}); the "
                        "others were delivered")
    return 1 if any(r.status == "refused" for r in results) else 0
