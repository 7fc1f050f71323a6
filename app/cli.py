"""The ``dualrgb`` command line. Each subcommand lives in its own module under app/commands/ and exposes
``register(subparsers)``; the module list below is the one place that names them.

Errors a user can cause (bad file, no device, bad value) and every device error print one line
``dualrgb: error: ...`` and exit 1: :class:`UserError`, ``ValueError``, ``OSError`` and every error marked
:class:`common.errors.ReportedError` (the sphere's, the camera's, the monochromator's, the light-safety refusals),
with the notes the devices added on the way out (what state the light was left in). Anything else is a bug: one
line names it and the crash report holding its traceback (``<per-user data folder>/crash/``), exit 1. No traceback
reaches the terminal (``-vv`` logs it as well).

Start-up: building the parser imports every command module, so a command module imports at its top only what
``register`` needs (argparse, the standard library, simulation.choices); numpy, colour-science, numba, rawpy,
matplotlib and Qt are imported inside the functions that run the command. ``--help``, ``--version``,
``sphere``, ``devices`` and ``raw-info`` then start in well under 0.5 s (``make bench`` measures it).
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import os
import sys
from collections.abc import Sequence

from dualrgb.app import interrupts
from dualrgb.common.errors import ReportedError, one_line, write_crash_report
from dualrgb.simulation.versions import dualrgb_version

# One BLAS thread unless the user set one (before numpy loads; the commands import it later): the product's linear
# algebra is small (the stand fit's 1190 x 22 SVD: 0.31 ms on one thread, 13.5 ms on two busy cores,
# docs/notes/issue-26-suite.md); the pixel work runs in its own numba threads.
for _blas in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_blas, "1")

log = logging.getLogger(__name__)

COMMAND_MODULES = (
    "dualrgb.app.commands.simulate",
    "dualrgb.app.commands.sphere",
    "dualrgb.app.commands.raw_info",
    "dualrgb.app.commands.devices",
    "dualrgb.app.commands.gui",
    "dualrgb.app.commands.demo",
    "dualrgb.app.commands.calibrate",
    "dualrgb.app.commands.capture",
    "dualrgb.app.commands.collection",
    "dualrgb.app.commands.process",
    "dualrgb.app.commands.import_raw",
    "dualrgb.app.commands.cube",
    "dualrgb.app.commands.verify",
    "dualrgb.app.commands.bag",
    "dualrgb.app.commands.report",
    "dualrgb.app.commands.calibration",
    "dualrgb.app.commands.study",
    "dualrgb.app.commands.measure",
    "dualrgb.app.commands.lab",
)


class UserError(Exception):
    """An error with a one-line message meant for the user (no traceback)."""


class _VersionAction(argparse.Action):
    """``--version``: like argparse's, but the version is looked up only when asked for (start-up time)."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        print(f"{parser.prog} {dualrgb_version()}")
        parser.exit()


class Parser(argparse.ArgumentParser):
    """argparse's parser, but an unknown option is refused by the subcommand that was given (its usage, not the
    top level's) with the closest of that subcommand's options: ``--sesion`` -> "did you mean --session?"
    (app.cli_refusals.unrecognised)."""

    def parse_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                   namespace: argparse.Namespace | None = None) -> argparse.Namespace:
        from dualrgb.app.cli_refusals import innermost_parser, unrecognised

        found, extras = self.parse_known_args(args, namespace)
        if extras:
            given = innermost_parser(self, found)
            given.error(unrecognised(given, extras))
        return found


class _ConsoleFormat(logging.Formatter):
    """The terminal's log lines: without -v a warning reads as the commands' own do (``warning: ...``, one
    style); with -v every record names its level and logger."""

    def __init__(self, verbose: int) -> None:
        super().__init__("%(levelname)s %(name)s: %(message)s")
        self.verbose = verbose

    def format(self, record: logging.LogRecord) -> str:
        if self.verbose or record.levelno < logging.WARNING:
            return super().format(record)
        return f"{'warning' if record.levelno == logging.WARNING else 'error'}: {record.getMessage()}"


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="dualrgb", description="Dual-RGB multispectral capture and simulation")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    parser.add_argument("--version", action=_VersionAction, nargs=0, help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def _printable_streams() -> None:
    """Paths with bytes that are not UTF-8 (a folder named in another encoding) print as escapes, never fail."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if callable(reconfigure):
            try:
                reconfigure(errors="backslashreplace")
            except (ValueError, OSError) as exc:       # a stream that cannot change: leave it
                log.debug("stream %r: %s", stream, exc)


def main(argv: Sequence[str] | None = None) -> int:
    _printable_streams()
    with interrupts.handled():          # SIGINT, SIGTERM, SIGHUP: every open sphere off, read back (app.interrupts)
        parser = build_parser()
        args = parser.parse_args(argv)
        if not logging.getLogger().handlers:            # the terminal's handler (not one a host set up)
            console = logging.StreamHandler()
            console.setFormatter(_ConsoleFormat(args.verbose))
            console.addFilter(lambda record: not getattr(record, "session_only", False))   # core.session.log
            logging.getLogger().addHandler(console)
            logging.getLogger().setLevel([logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)])
        try:
            return int(args.func(args) or 0)
        except KeyboardInterrupt as exc:
            return _signalled(exc if isinstance(exc, interrupts.Interrupted) else None)
        except (UserError, ReportedError, OSError, ValueError) as exc:
            if args.verbose >= 2:
                log.exception("command failed")
            print(f"dualrgb: error: {one_line(exc)}", file=sys.stderr)
            return _signalled(interrupts.received(), 1)
        except Exception as exc:  # noqa: BLE001 - the last resort: a bug, reported in one line and a crash file
            rc = _crashed(exc, list(sys.argv if argv is None else ["dualrgb", *argv]), args.verbose)
            return _signalled(interrupts.received(), rc)


def _signalled(exc: interrupts.Interrupted | None, rc: int | None = None) -> int:
    """After a signal (or Ctrl-C), the last line: the light's state as read back and how to resume."""
    if rc is not None and exc is None:
        return rc
    with contextlib.suppress(OSError):             # SIGHUP: the terminal may be gone
        print(interrupts.interrupted_line(exc), file=sys.stderr, flush=True)
    return interrupts.exit_code(exc) if exc is not None else 130


def _crashed(exc: Exception, argv: list[str], verbose: int) -> int:
    """One line for a bug (an error no check foresaw), its traceback in a crash report; exit 1."""
    from dualrgb import resources

    if verbose >= 2:
        log.error("command failed", exc_info=exc)
    report = write_crash_report(exc, resources.user_path("crash"), argv)
    where = f"the traceback is in {report}" if report is not None else "the traceback could not be written"
    print(f"dualrgb: error: unexpected {type(exc).__name__}: {one_line(exc)} (a bug in dualrgb: {where}; please "
          "report it with that file)", file=sys.stderr)
    return 1


if __name__ == "__main__":  # pragma: no cover
    # `python -m dualrgb.app.cli`: run the imported module's main, so commands' `UserError` is the one caught here
    from dualrgb.app.cli import main as _main
    sys.exit(_main())
