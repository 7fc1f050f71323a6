"""Progress of long commands (simulate, study, demo) on stderr: a tqdm bar when stderr is a terminal.

:class:`TerminalProgress` is a :data:`common.progress.ProgressCallback`. It never goes backwards (a
fraction below one already shown keeps the bar where it is; the message still updates), so callers that
restart a sub-range cannot make the percentage jump back. When stderr is not a terminal (a pipe, a CI log) it
writes one line per new percent (``lines=True``, what the demo's log needs) or only logs the messages at INFO;
either way the kernels' one-off compile notice (common.progress.COMPILING) is printed, so a first run is
never silent.
"""
from __future__ import annotations

import logging
import sys
import threading
from types import TracebackType
from typing import Any, TextIO

from dualrgb.common.progress import COMPILING

log = logging.getLogger(__name__)

STEPS = 1000                      # bar resolution: 0.1 %


def _is_terminal(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):       # a closed or replaced stream (pytest capture)
        return False


class TerminalProgress:
    """A monotonic progress callback for one command; use it as a context manager so the bar is closed."""

    def __init__(self, title: str, *, lines: bool = False, stream: TextIO | None = None,
                 terminal: bool | None = None) -> None:
        self.title = title
        self.lines = lines
        self.stream = stream if stream is not None else sys.stderr
        self.terminal = _is_terminal(self.stream) if terminal is None else terminal
        self.shown = 0                          # steps of STEPS shown so far
        self.message = ""
        self._last_pct = -1
        self._said: set[str] = set()
        self._bar: Any = None
        self._redirect: Any = None
        self._lock = threading.Lock()

    def __enter__(self) -> TerminalProgress:
        if self.terminal:                       # log lines print above the bar instead of through it
            from tqdm.contrib.logging import logging_redirect_tqdm

            self._redirect = logging_redirect_tqdm()
            self._redirect.__enter__()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def __call__(self, fraction: float, message: str) -> None:
        with self._lock:
            step = int(min(max(fraction, 0.0), 1.0) * STEPS)
            advance = max(step - self.shown, 0)
            self.shown += advance
            self.message = message
            if self.terminal:
                self._draw(advance, message)
            else:
                self._write_line(message)

    def _draw(self, advance: int, message: str) -> None:
        if self._bar is None:
            from tqdm import tqdm

            self._bar = tqdm(total=STEPS, desc=self.title, file=self.stream, leave=False, dynamic_ncols=True,
                             bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed}<{remaining} {postfix}")
        self._bar.set_postfix_str(message[:60], refresh=False)
        self._bar.update(advance)
        self._bar.refresh()

    def _write_line(self, message: str) -> None:
        pct = self.shown * 100 // STEPS
        if message == COMPILING and message not in self._said:
            self._said.add(message)
            print(f"{self.title}: {message}", file=self.stream, flush=True)
        elif self.lines and pct != self._last_pct:
            print(f"[{pct:3d}%] {message}", file=self.stream, flush=True)
        else:
            log.info("%3d%% %s", pct, message)
        self._last_pct = pct

    def close(self) -> None:
        with self._lock:
            if self._bar is not None:
                self._bar.close()
                self._bar = None
            if self._redirect is not None:
                self._redirect.__exit__(None, None, None)
                self._redirect = None
