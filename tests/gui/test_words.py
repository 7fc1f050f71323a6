"""Issue 42, the words of the window: no CLI flag in any string the window shows (every string of app/gui but
docstrings and comments), every message the workflow can raise said in the window's words, one message box per
error, and no stale time left or error after a run ends."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from dualrgb.app.gui.wording import has_cli_flag, in_window_words

ROOT = Path(__file__).resolve().parents[2]
SHELL_COMMAND = re.compile(r"\bdualrgb (?:calibrate|capture|process|measure|simulate|cube|verify|bag|study)\b|"
                           r"\bls /dev")


def _texts(path: Path) -> list[tuple[int, str]]:
    """Every string a module can show: constants and f-strings ('X' for what is formatted in), docstrings out."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docs = {id(n.body[0].value) for n in ast.walk(tree)
            if isinstance(n, ast.Module | ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef) and n.body
            and isinstance(n.body[0], ast.Expr)}
    parts = {id(v) for n in ast.walk(tree) if isinstance(n, ast.JoinedStr) for v in n.values}
    out = []
    for node in ast.walk(tree):
        if id(node) in docs or id(node) in parts:
            continue
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            out.append((node.lineno, node.value))
        elif isinstance(node, ast.JoinedStr):
            out.append((node.lineno, "".join(v.value if isinstance(v, ast.Constant) else "X" for v in node.values)))
    return out


def _strings(folder: str) -> list[tuple[str, str]]:
    return [(f"{p.relative_to(ROOT)}:{line}", text) for p in sorted((ROOT / folder).rglob("*.py"))
            for line, text in _texts(p)]


def test_no_window_string_names_a_cli_flag_or_a_shell_command():
    found = [f"{where}: {text[:100]!r}" for where, text in _strings("app/gui")
             if (has_cli_flag(text) or SHELL_COMMAND.search(text)) and not where.startswith("app/gui/wording.py")]
    assert found == []


def test_every_workflow_message_is_said_without_a_flag():
    """The workflow's messages (and the drivers' port errors) through the window's wording: no flag is left."""
    found = []
    for folder in ("app/workflow", "drivers/led_sphere", "core"):
        for where, text in _strings(folder):
            if has_cli_flag(text) and has_cli_flag(in_window_words(text)):
                found.append(f"{where}: {in_window_words(text)[:120]!r}")
    assert found == []


@pytest.mark.parametrize("message, said", [
    ("transmissive original, reflective calibration c1: capture it with a transmissive calibration (dualrgb "
     "calibrate --mode transmissive), or --force to use this one",
     "transmissive original, reflective calibration c1: capture it with a transmissive calibration, or choose "
     "Capture anyway"),
    ("no LED sphere is connected (connect it: Devices, or --port)", "no LED sphere is connected (connect it: "
                                                                    "Devices)"),
    ("cannot open LED sphere port /dev/ttyACM9: [Errno 2] could not open port /dev/ttyACM9: [Errno 2] No such file "
     "or directory: '/dev/ttyACM9'; check the cable and the port name (ls /dev/ttyACM* /dev/ttyUSB*) and that no "
     "other program uses it",
     "cannot open LED sphere port /dev/ttyACM9: No such file or directory; check the cable and the port name "
     "(Refresh lists the ports) and that no other program uses it"),
    ("--jobs 0: expected 1 or more", "the 'jobs' option 0: expected 1 or more"),
    ("port A: port A: gone", "port A: gone"),
])
def test_messages_in_the_window_words(message, said):
    assert in_window_words(message) == said


def test_the_real_mode_refusal_is_worded():
    from dualrgb.app.workflow.stand.mode_rule import mode_problem, override_text

    for text in (mode_problem("transmissive", "reflective", "c1"), override_text("transmissive", "reflective", "c1")):
        assert has_cli_flag(text)                          # the CLI's words stay the CLI's
        assert not has_cli_flag(in_window_words(text)) and "Capture anyway" in in_window_words(text)


def test_one_box_per_error(make_window):
    w = make_window()
    w.errors.show_dialogs = True
    try:
        w.errors.report("Connect the LED sphere", "no LED sphere is connected (connect it: Devices, or --port)")
        w.errors.report("Connect the LED sphere", "still not connected")
        assert len(w.errors.dialogs) == 1 and w.errors.dialogs[0].text() == "still not connected"
        assert w.errors.history[0][1] == "no LED sphere is connected (connect it: Devices)"
        assert "--port" not in w.error_state.text() + w.error_state.toolTip()
    finally:
        w.errors.close_all()


def test_no_stale_time_left_or_error_after_a_run(qtbot, make_window):
    """A run that fails leaves no time left; the next run starts without the old error in the status bar."""
    from dualrgb.core.engine import Run

    def fail(_hooks):
        raise ValueError("the camera went away")

    w = make_window()
    view = w.capture.view
    view.time_left.setText("time left 31 s")
    w.errors.report("Dark series stopped", "an old error")
    assert w.error_state.text()
    view.start(Run("dark series", [], fail))
    assert w.error_state.text() == ""                      # the old error went when the new run started
    qtbot.waitUntil(lambda: not view.running, timeout=60_000)
    assert view.time_left.text() == ""
    assert "the camera went away" in w.error_state.text()          # this run's error, said once
