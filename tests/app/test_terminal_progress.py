"""Progress of long commands: monotonic bar on a terminal, lines in a log, the compile notice always shown;
simulation.warmup reports the compile and keeps it out of the run's time."""
from __future__ import annotations

import io
import logging
import time

import numpy as np

from dualrgb.app.terminal_progress import STEPS, TerminalProgress
from dualrgb.common.progress import COMPILING, scaled


def test_bar_never_goes_back_but_follows_the_message():
    stream = io.StringIO()
    with TerminalProgress("demo", stream=stream, terminal=True) as bar:
        for f, msg in ((0.54, "train"), (0.52, "hdr"), (0.54, "test"), (0.60, "processing")):
            bar(f, msg)
            assert bar.message == msg
        assert bar.shown == int(0.60 * STEPS)
        bar(0.1, "late report of an earlier step")
        assert bar.shown == int(0.60 * STEPS)
    text = stream.getvalue()
    assert "demo:" in text and "processing" in text and "%|" in text          # tqdm drew on the stream


def test_lines_when_not_a_terminal_are_monotonic_and_once_per_percent():
    stream = io.StringIO()
    bar = TerminalProgress("demo", lines=True, stream=stream, terminal=False)
    for f, msg in ((0.0, "start"), (0.001, "same percent"), (0.54, "a"), (0.52, "b"), (0.55, "c")):
        bar(f, msg)
    assert stream.getvalue().splitlines() == ["[  0%] start", "[ 54%] a", "[ 55%] c"]


def test_compile_notice_is_shown_even_when_quiet(caplog):
    stream = io.StringIO()
    bar = TerminalProgress("simulate pso", stream=stream, terminal=False)
    with caplog.at_level(logging.INFO, logger="dualrgb.app.terminal_progress"):
        bar(0.0, COMPILING)
        bar(0.0, COMPILING)
        bar(0.5, "iteration 5")
    assert stream.getvalue() == f"simulate pso: {COMPILING}\n"
    assert "iteration 5" in caplog.text


def test_scaled_maps_a_sub_task_into_its_range():
    seen = []
    sub = scaled(lambda f, m: seen.append((round(f, 6), m)), 0.02, 0.1)
    sub(0.0, "a")
    sub(0.5, "b")
    sub(1.0, "c")
    assert seen == [(0.02, "a"), (0.06, "b"), (0.1, "c")] and scaled(None, 0, 1) is None


class _SlowEvaluator:
    """Stands in for an Evaluator whose first call compiles (0.3 s)."""

    evaluations = 7

    def cost_indexed(self, idx, w):       # what Evaluator.cost_indexed would do, slowly
        time.sleep(0.3)
        self.evaluations += len(idx)
        return np.zeros(len(idx))


def test_warm_up_reports_a_compile_and_leaves_the_count(monkeypatch):
    from dualrgb.simulation import objective, warmup

    monkeypatch.setattr(objective.Evaluator, "cost_indexed", _SlowEvaluator.cost_indexed)
    ev = _SlowEvaluator()
    for cached, notice_after_s, expected in ((False, 5.0, [(0.0, COMPILING)]),   # no cache index: at once
                                             (True, 0.05, []),                   # a cache load: quiet, even slow
                                             (None, 0.05, [(0.0, COMPILING)]),   # can't tell: after a while
                                             (None, 5.0, [])):
        monkeypatch.setattr(warmup, "kernels_cached", lambda cached=cached: cached)
        seen = []
        seconds = warmup.warm_up(ev, lambda f, m, seen=seen: seen.append((f, m)), notice_after_s=notice_after_s)
        assert seen == expected and seconds >= 0.3 and ev.evaluations == 7, (cached, notice_after_s)


def test_kernels_cache_index_is_readable_on_this_numba():
    """numba's cache internals that warm_up reads exist in the installed numba (None would mean they moved)."""
    from dualrgb.simulation import warmup
    from dualrgb.simulation.datasets import default_setup
    from dualrgb.simulation.objective import Evaluator

    warmup.warm_up(Evaluator(default_setup("reflective")))               # compiled or loaded: now on disk
    assert warmup.kernels_cached() is True


def test_run_time_excludes_the_warm_up(monkeypatch):
    from dualrgb.simulation import runner
    from dualrgb.simulation.datasets import default_setup

    clock = [1000.0]                                   # the runner's clock moves only while "compiling"

    def compile_for_100_s(ev, progress=None):
        clock[0] += 100.0
        return 100.0

    monkeypatch.setattr(runner, "warm_up", compile_for_100_s)
    monkeypatch.setattr(runner.time, "perf_counter", lambda: clock[0])
    result = runner.run(default_setup("reflective"), "exhaustive", top=1)
    assert result.elapsed_s == 0.0 and result.to_json()["kernel_warm_up_s"] == 100.0
