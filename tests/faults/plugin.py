"""The fault-injection suite's pytest plugin (loaded by tests/conftest.py).

* ``@pytest.mark.fault("<category>")`` marks one fault-injection case (parametrize for many cases):
  "light safety", "session integrity", "input" (issue 9), "camera", "device errors", "edited files" (issue 28),
  "firmware" (issue 38: the reference firmware on a simulated ATmega2560, tests/sphere_backends.py).
  The mark takes exactly one category string.
* ``pytest -m fault --reliability-table docs/explanation/reliability.md`` (``make reliability``) runs the cases and
  writes the table category | cases tried | clean between ``<!-- reliability:start -->`` and
  ``<!-- reliability:end -->``:
  a case is *tried* when it ran (setup and call; skips are not counted) and *clean* when it passed, i.e.
  the fault was handled the way the issue requires. The table is produced by the suite, never typed.
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

START, END = "<!-- reliability:start -->", "<!-- reliability:end -->"
PAGE = "docs/explanation/reliability.md"          # the docs page holding the table (make reliability)
CLEAN_MEANS = (
    "a case is clean when its test passed, i.e. the injected fault was handled: light safety (lost or garbled "
    "replies, a slow or hung camera, a dead host, GUI errors) with the light off within its cap on the emulator's "
    "clock, and the monochromator's shutter closed (or, where it cannot answer, the message saying its state is "
    "unknown); session integrity (kill -9, resume with other options, full disk, torn manifests, damaged frames) "
    "with every frame intact and none mixed; input (bad values, fuzzed raw files and CSVs) with a one-line error; "
    "camera (libgphoto2 behaviours replayed by a scripted stand-in) with the right frame or a one-line error and the "
    "light off; device errors (every command that opens devices against a silent, garbage-speaking, disconnecting "
    "or switch-off-ignoring sphere and a missing, failing or hanging camera) with one line naming the device and "
    "the light off, or the line saying truthfully that it could not be confirmed off; edited files (calibration "
    "profiles changed by hand or damaged, oversized inputs) refused in one line naming the field before any "
    "device acts; firmware (the reference firmware run on a simulated ATmega2560: the emulator's light-safety "
    "cases, cable faults, LED faults, over-temperature, a killed host, resets and brown-out) with the light off at "
    "the PWM pins within its limit on the chip's clock.")
CATEGORIES = ("light safety", "session integrity", "input", "camera", "device errors", "edited files", "firmware")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--reliability-table", metavar="PAGE", default=None,
                     help="write the fault-injection table (category, cases tried, clean) into this file "
                          f"between {START} and {END}")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "fault(category): a fault-injection case counted in the docs' reliability "
                                       f"table; category is one of {', '.join(CATEGORIES)}")
    config._fault_tried = Counter()      # type: ignore[attr-defined]
    config._fault_clean = Counter()      # type: ignore[attr-defined]


def fault_category(item: pytest.Item) -> str | None:
    marks = list(item.iter_markers("fault"))
    if not marks:
        return None
    mark = marks[0]
    if len(mark.args) != 1 or not isinstance(mark.args[0], str) or mark.kwargs or not mark.args[0].strip():
        raise pytest.UsageError(f"{item.nodeid}: @pytest.mark.fault takes one category string, e.g. "
                                f"@pytest.mark.fault(\"input\")")
    return mark.args[0].strip()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        fault_category(item)             # a malformed mark fails the run at collection


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    outcome = yield
    report = outcome.get_result()
    category = fault_category(item)
    if category is None or report.skipped:
        return
    if report.when == "call" or (report.when == "setup" and report.failed):
        item.config._fault_tried[category] += 1          # type: ignore[attr-defined]
        if report.passed:
            item.config._fault_clean[category] += 1      # type: ignore[attr-defined]


def render_table(tried: Counter, clean: Counter) -> str:
    order = [c for c in CATEGORIES if c in tried] + sorted(c for c in tried if c not in CATEGORIES)
    lines = ["| Category | Cases tried | Clean |", "| --- | ---: | ---: |"]
    lines += [f"| {c} | {tried[c]} | {clean[c]} |" for c in order]
    lines.append(f"| **all** | **{sum(tried.values())}** | **{sum(clean.values())}** |")
    return "\n".join(lines)


def replace_between_markers(text: str, table: str, path: str = PAGE) -> str:
    if text.count(START) != 1 or text.count(END) != 1 or text.index(START) > text.index(END):
        raise pytest.UsageError(f"{path}: needs one {START} line before one {END} line")
    head, rest = text.split(START)
    _, tail = rest.split(END)
    note = (f"Produced by `make reliability` (`pytest -m fault --reliability-table {PAGE}`): every "
            "`@pytest.mark.fault` case in tests/; " + CLEAN_MEANS)
    return f"{head}{START}\n{table}\n\n{note}\n{END}{tail}"


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    target = session.config.getoption("--reliability-table")
    tried = session.config._fault_tried                # type: ignore[attr-defined]
    if not target or not tried:
        return
    from dualrgb.common.atomic_files import atomic_write

    path = Path(target)
    text = replace_between_markers(path.read_text(encoding="utf-8"), render_table(tried, session.config._fault_clean),
                                   str(path))
    atomic_write(path, text)
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write_line(f"reliability table written to {path}: {sum(tried.values())} cases, "
                            f"{sum(session.config._fault_clean.values())} clean")
