"""``dualrgb lab``: the virtual lab as devices of their own, and its truth as a separate step.

    dualrgb lab serve [--mode M] [--frame-size WxH] [--seed N] [--world NAME|FILE] [--original NAME]
                      [--train-target FILE ...] [--light-record FILE] [--with-parent]
    dualrgb lab score SESSION [--original ID=NAME ...] [--json PATH]

``serve`` starts the virtual sphere, camera, sample changer, monochromator and spectroradiometer in this process and
prints one line per instrument, ``<name> <address>`` (``sphere socket://127.0.0.1:40123``, ``camera
tcp://127.0.0.1:40125``, ``stand socket://...``, ``monochromator socket://...``, ``spectroradiometer
socket://...``), then serves until it is killed (SIGTERM or Ctrl-C: the sphere is powered off). `dualrgb
calibrate|capture --port SPHERE --camera CAMERA --stand STAND` then drive them exactly as a physical stand
(drivers/virtual/lab_server.py; ``--virtual-lab`` is the shorthand that starts one as a child process:
app.lab.process). ``score`` compares a session's deliverables with the lab's virtual originals
(app.lab.score): per-pixel dE00 and spectral RMSE.
"""
from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
import time
from pathlib import Path

from dualrgb.app.commands.options import add_chart_options, add_world_option, frame_size, number, seed
from dualrgb.app.json_output import add_json_option

log = logging.getLogger(__name__)

SCORE_FORMAT = "dualrgb-lab-score/1"
LIGHT_RECORD_ENV = "DUALRGB_LAB_LIGHT_RECORD"     # a lab started by a window or --virtual-lab writes its record there
MODES = ("reflective", "transmissive")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("lab", help="the virtual lab: serve its instruments, score a session against its truth",
                       description="The virtual lab's instruments in a process of their own (serve), and a "
                                   "session's deliverables against the lab's virtual originals (score).")
    verbs = p.add_subparsers(dest="verb", metavar="VERB")
    verbs.required = True
    serve = verbs.add_parser("serve", help="serve the virtual sphere, camera, sample changer, monochromator and "
                                           "spectroradiometer",
                             description="Prints one line per instrument, '<name> <address>', then serves until "
                                         "killed.")
    serve.add_argument("--mode", choices=MODES, default="reflective", help="the targets it holds (reflective)")
    serve.add_argument("--frame-size", type=frame_size, default=(600, 400), help="camera frames WxH (600x400)")
    serve.add_argument("--seed", type=seed, default=0, help="noise seed")
    add_world_option(serve)
    serve.add_argument("--original", default="", metavar="NAME",
                       help="what an original is shown as: a virtual original (painting, film, shadow, ...) or a "
                            "chart (test, train, test+nd); default the mode's (painting / film)")
    serve.add_argument("--bumps", action="store_true", help="the D610 shutter's exposure-time bumps (appendix A)")
    serve.add_argument("--watchdog-s", type=number(0.1, 3600, unit=" s"), default=30.0,
                       help="the sphere's watchdog (30 s)")
    serve.add_argument("--light-record", type=Path, metavar="FILE",
                       default=os.environ.get(LIGHT_RECORD_ENV) or None,
                       help="write every lit period of the sphere to FILE as it begins and ends (JSON lines; "
                            f"default ${LIGHT_RECORD_ENV})")
    serve.add_argument("--with-parent", action="store_true",
                       help="stop when standard input closes (the program that started it ended), once the "
                            "sphere is dark")
    add_chart_options(serve)
    serve.set_defaults(func=serve_main)
    score = verbs.add_parser("score", help="a session's deliverables against the lab's virtual originals",
                             description="Per delivered original: per-pixel dE00 of the XYZ TIFF and spectral RMSE "
                                         "of the delivered spectra against the virtual original it was shown as.")
    score.add_argument("session", type=Path, help="the session folder")
    score.add_argument("--original", action="append", default=[], metavar="ID=NAME",
                       help="original ID was shown as virtual original NAME (default: the mode's, painting / "
                            "film); repeat for several")
    add_json_option(score)
    score.set_defaults(func=score_main)


def serve_main(args: argparse.Namespace) -> int:
    from dualrgb.app.commands.options import chart_choices
    from dualrgb.app.lab.targets import chart_reader
    from dualrgb.app.workflow.charts import load_charts
    from dualrgb.drivers.virtual.lab_server import LabServer, LabSettings

    charts = load_charts(chart_choices(args), args.mode)                # read before anything starts
    settings = LabSettings(mode=args.mode, frame_size=args.frame_size, seed=args.seed, world=args.world,
                           watchdog_s=args.watchdog_s, bumps=args.bumps, stand_in=args.original,
                           charts={role: c.render_target() for role, c in charts.items()})
    server = LabServer(settings, light_record=args.light_record, read_chart=chart_reader(args.mode))
    stop = threading.Event()
    if args.with_parent:
        threading.Thread(target=_until_stdin_closes, args=(server, stop), name="parent", daemon=True).start()
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, lambda _s, _f: stop.set()) if in_main else None
    try:
        for name, address in server.start().items():
            print(f"{name} {address}", flush=True)
        while not stop.wait(0.2):
            pass
        return 0
    except KeyboardInterrupt:
        return 0
    finally:
        server.stop()
        if in_main:
            signal.signal(signal.SIGTERM, previous)


def _until_stdin_closes(server, stop: threading.Event) -> None:
    """Set ``stop`` once standard input has closed and the sphere is dark (its watchdog and on-time limit switch it
    off when its client is gone: a sphere's own firmware does, and nothing else here will)."""
    try:
        while sys.stdin.buffer.read(4096):
            pass
    except (OSError, ValueError):
        pass
    log.info("lab: its parent is gone; stopping once the sphere is dark")
    while not server.dark():
        time.sleep(0.02)
    stop.set()


def score_main(args: argparse.Namespace) -> int:
    from dualrgb.app.json_output import text_stream, write_json
    from dualrgb.app.lab.score import score_session, stand_ins

    scores = score_session(args.session, stand_ins(args.original))
    out = text_stream(args.json)
    for s in scores:
        print(s.line(), file=out)
    if not scores:
        print(f"{args.session}: no delivered original to score", file=out)
    write_json(args.json, SCORE_FORMAT, {"session": str(args.session), "originals": [s.to_dict() for s in scores]})
    return 0
