"""Figures in the docs read from the committed JSON that the benchmarks, studies and the demo wrote.

The ``json`` role puts one value of a JSON file into the text at build time, so a page never holds a
hand-copied number::

    {json}`notes/issue-31/demo-reflective-report.json#original.xyz.mean:.2f`

The path is relative to the docs folder (docs/); after ``#`` a dotted path into the document (a list index
is a number, or ``key=value&key=value`` for the one element of a list of objects with those fields, e.g.
``configurations.label=halving.train.median``; no ``.`` in such a value); after the last ``:`` a Python format
spec (default: the value as it is; a key may hold ``:``, as ``lights.re-optimised: world.captured.train:.4f``
does, when what follows the last ``:`` is no format spec).
(Not ``|``: the role is used inside Markdown tables.) A missing file, key or a value
the format does not take is a build error (``make docs`` turns warnings into errors), naming the file and key.
A page that uses a file is rebuilt when the file changes.

The ``demo-table`` directive writes the condition table of a ``dualrgb demo`` report (``report.json``,
``dualrgb-demo-report/1``): per condition its lights, matrix, captured, predicted and noise-free mean dE00::

    ```{demo-table} data/demo-reflective-hdr.json
    ```
"""
from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective, SphinxRole

logger = logging.getLogger(__name__)


def _select(items: list[Any], part: str, dotted: str) -> Any:
    """The one element of ``items`` (dicts) whose fields match ``part`` (``key=value&key=value``, compared as text);
    KeyError when none or several do, so a list that gains a look-alike row is an error, not another figure."""
    wanted = {key: text for key, _, text in (cond.partition("=") for cond in part.split("&"))}
    found = [item for item in items if isinstance(item, dict)
             and all(k in item and str(item[k]) == v for k, v in wanted.items())]
    if len(found) != 1:
        raise KeyError(f"{len(found)} elements match {part!r} (in {dotted!r}); expected exactly one")
    return found[0]


def lookup(document: Any, dotted: str) -> Any:
    """The value at ``dotted`` (``a.b.0.c``; in a list, ``key=value[&key=value]`` picks the one element with those
    fields) inside ``document``; KeyError naming the first missing part."""
    value = document
    for part in dotted.split(".") if dotted else []:
        if isinstance(value, list) and part.lstrip("-").isdigit():
            value = value[int(part)]
        elif isinstance(value, list) and "=" in part:
            value = _select(value, part, dotted)
        elif isinstance(value, dict) and part in value:
            value = value[part]
        else:
            raise KeyError(f"no {part!r} (in {dotted!r})")
    return value


FORMAT_SPEC = re.compile(r"(.?[<>=^])?[+\- ]?z?#?0?\d*[,_]?(\.\d+)?[bcdeEfFgGnosxX%]?")


def split_spec(rest: str) -> tuple[str, str]:
    """(dotted path, format spec) of the text after ``#``: the spec follows the last ``:`` when it is one."""
    dotted, colon, spec = rest.rpartition(":")
    if colon and FORMAT_SPEC.fullmatch(spec.strip()):
        return dotted, spec
    return rest, ""


def render(text: str, docs_dir: Path) -> tuple[str, Path]:
    """The formatted value the role text names, and the file it came from (ValueError on any problem)."""
    file, _, rest = text.strip().partition("#")
    dotted, spec = split_spec(rest)
    path = (docs_dir / file).resolve()
    try:
        value = lookup(json.loads(path.read_text(encoding="utf-8")), dotted.strip())
        return format(value, spec.strip()), path
    except (OSError, json.JSONDecodeError, KeyError, IndexError, TypeError, ValueError) as exc:
        raise ValueError(f"{file}#{dotted}: {exc}") from None


class JsonRole(SphinxRole):
    def run(self) -> tuple[list[nodes.Node], list[nodes.system_message]]:
        srcdir = Path(self.env.srcdir)
        self.env.note_dependency(str((srcdir / self.text.partition("#")[0].strip()).resolve()))   # also when missing
        try:
            value, _ = render(self.text, srcdir)
        except ValueError as exc:
            logger.warning("json role: %s", exc, location=self.get_location())
            return [nodes.problematic(self.rawtext, self.rawtext)], []
        return [nodes.Text(value)], []


def _levels(light: dict[str, Any]) -> str:
    leds = ", ".join(str(n) for n in light["leds"])
    levels = light.get("levels") or []
    if not levels or all(v == 1 for v in levels):
        return f"({leds})"
    return f"({leds}) @ ({', '.join(format(v, '.4g') for v in levels)})"


def _cell(value: Any) -> str:
    return "" if value is None else format(value, ".3f")


def _pixel(figures: dict[str, Any] | None) -> str:
    """Per-pixel mean (p90), issue 40; empty for a report made before."""
    return "" if not figures else f"{figures['mean']:.3f} ({figures['p90']:.3f})"


def demo_rows(report: dict[str, Any]) -> list[str]:
    """The Markdown table of a demo report's conditions (the report's own order); the predicted and noise-free
    columns only for the plain charts the prediction is made for."""
    rows = ["| Condition | Lights (LEDs @ levels) | Matrix | Train captured | Test captured | Train predicted | "
            "Test predicted | Train noise-free | Test noise-free | Test per pixel captured (p90) | Test per pixel "
            "predicted (p90) |", "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for name in report["conditions"]:
        c = report[name]
        # the ND-covered scene (hdr_*, single_*) has no prediction: its "simulated" is the lights' plain chart's
        sim = {} if name.startswith(("hdr_", "single_")) else c.get("simulated") or {}
        lights = " + ".join(_levels(light) for light in c.get("lights") or [])
        rows.append(f"| {name} | {lights} | {c.get('matrix_method', '')} | {_cell(c['train']['mean'])} | "
                    f"{_cell(c['test']['mean'])} | {_cell(sim.get('train'))} | {_cell(sim.get('test'))} | "
                    f"{_cell(sim.get('noise_free_train'))} | {_cell(sim.get('noise_free_test'))} | "
                    f"{_pixel((c.get('per_pixel') or {}).get('test'))} | "
                    f"{_pixel(((sim.get('per_matrix') or {}).get('per_pixel') or {}).get('test'))} |")
    return rows


class DemoTable(SphinxDirective):
    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        path = (Path(self.env.srcdir) / self.arguments[0]).resolve()
        self.env.note_dependency(str(path))                     # also when missing: rebuilt once it is there
        try:
            rows = demo_rows(json.loads(path.read_text(encoding="utf-8")))
        except (OSError, json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
            logger.warning("demo-table: %s: %s", self.arguments[0], exc, location=self.get_location())
            return []
        container = nodes.container()
        self.state.nested_parse(StringList(rows, source=str(path)), self.content_offset, container)
        return container.children


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_role("json", JsonRole())
    app.add_directive("demo-table", DemoTable)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
