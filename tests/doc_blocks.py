"""Run the command blocks of the user docs as they are written: the docs are executed, not trusted.

A block to run is a fenced code block that follows an HTML comment naming it, in any Markdown file (the docs site's
pages: docs/tutorial/first-day.md, docs/how-to/own-charts.md):

    <!-- test: copy-stand-day -->
    ```sh
    dualrgb calibrate --session day1 --virtual-lab
    ```

:func:`run_block` runs its commands one by one with bash (a ``\\`` at a line's end continues it; ``#`` comments
and shell globs work as in a terminal), in ``cwd``, stopping at the first that fails. ``prelude`` is bash run
before each command: the tests use it to make ``dualrgb`` the interpreter under test and to add what the doc's
text allows (``--frame-size 240x160`` to a ``--virtual-lab`` command), never to change a command.
"""
from __future__ import annotations

import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

MARKER = "<!-- test: {name} -->"
_FENCE = re.compile(r"^(```|~~~)")


class DocBlockError(AssertionError):
    """A block that is missing, or a command of it that failed."""


def block_names(markdown: Path) -> list[str]:
    """The names of every runnable block in ``markdown``."""
    return re.findall(r"<!-- test: ([\w.-]+) -->", Path(markdown).read_text(encoding="utf-8"))


def fenced_block(markdown: Path, name: str) -> str:
    """The text of the fenced code block right after ``<!-- test: name -->`` (blank lines between allowed)."""
    lines = Path(markdown).read_text(encoding="utf-8").splitlines()
    marker = MARKER.format(name=name)
    starts = [i for i, line in enumerate(lines) if line.strip() == marker]
    if len(starts) != 1:
        raise DocBlockError(f"{markdown}: {len(starts)} blocks marked {marker!r}, expected 1")
    i = starts[0] + 1
    while i < len(lines) and not lines[i].strip():
        i += 1
    opening = _FENCE.match(lines[i].strip()) if i < len(lines) else None
    if opening is None:
        raise DocBlockError(f"{markdown}:{starts[0] + 1}: {marker} is not followed by a fenced code block")
    fence = opening.group(1)
    body = []
    for line in lines[i + 1:]:
        if line.strip().startswith(fence):
            return "\n".join(body)
        body.append(line)
    raise DocBlockError(f"{markdown}:{i + 1}: the code block after {marker} is not closed")


def commands(block: str) -> list[str]:
    """The block's commands: continued lines joined, blank and comment-only lines left out."""
    out, current = [], ""
    for line in block.splitlines():
        text = line.rstrip()
        if text.endswith("\\"):
            current += text[:-1] + " "
            continue
        current += text
        if current.strip() and not current.strip().startswith("#"):
            out.append(current.strip())
        current = ""
    if current.strip():
        out.append(current.strip())
    return out


@dataclass
class Ran:
    command: str
    returncode: int
    stdout: str
    stderr: str


def run_block(markdown: Path, name: str, cwd: Path, *, env: dict[str, str] | None = None, prelude: str = "",
              timeout_s: float = 1800.0) -> list[Ran]:
    """Run block ``name`` of ``markdown`` in ``cwd`` (module docstring); DocBlockError names the first command
    that fails, with the end of its stderr."""
    ran = []
    for command in commands(fenced_block(markdown, name)):
        r = subprocess.run(["bash", "-c", f"{prelude}\n{command}"], cwd=cwd, env=env, capture_output=True,
                           text=True, timeout=timeout_s)
        ran.append(Ran(command, r.returncode, r.stdout, r.stderr))
        if r.returncode != 0:
            raise DocBlockError(f"{Path(markdown).name} block {name!r}: `{command}` exited {r.returncode}:\n"
                                f"{r.stderr[-3000:]}")
    return ran


def dualrgb_prelude(frame_size: str | None = None) -> str:
    """bash that makes ``dualrgb`` this interpreter's (``python -m dualrgb``), adding ``--frame-size`` to a
    command that uses the virtual lab when ``frame_size`` is given."""
    python = shlex.quote(sys.executable)
    extra = f" --frame-size {shlex.quote(frame_size)}" if frame_size else ""
    return (f'dualrgb() {{ case " $* " in *" --virtual-lab "*) {python} -m dualrgb "$@"{extra};; '
            f'*) {python} -m dualrgb "$@";; esac; }}')
