"""Figures in the docs read from the committed JSON that the benchmarks, studies and the demo wrote.

The ``json`` role puts one value of a JSON file into the text at build time, so a page never holds a
hand-copied number::

    {json}`notes/issue-31/demo-reflective-report.json#original.xyz.mean|.2f`

The path is relative to the docs folder (docs/); after ``#`` a dotted path into the document (a list index
is a number); after ``|`` a Python format spec (default: the value as it is). A missing file, key or a value
the format does not take is a build error (``make docs`` turns warnings into errors), naming the file and key.
A page that uses a file is rebuilt when the file changes.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from docutils import nodes
from sphinx.application import Sphinx
from sphinx.util import logging
from sphinx.util.docutils import SphinxRole

logger = logging.getLogger(__name__)


def lookup(document: Any, dotted: str) -> Any:
    """The value at ``dotted`` (``a.b.0.c``) inside ``document``; KeyError naming the first missing part."""
    value = document
    for part in dotted.split(".") if dotted else []:
        if isinstance(value, list) and part.lstrip("-").isdigit():
            value = value[int(part)]
        elif isinstance(value, dict) and part in value:
            value = value[part]
        else:
            raise KeyError(f"no {part!r} (in {dotted!r})")
    return value


def render(text: str, docs_dir: Path) -> tuple[str, Path]:
    """The formatted value the role text names, and the file it came from (ValueError on any problem)."""
    ref, _, spec = text.partition("|")
    file, _, dotted = ref.strip().partition("#")
    path = (docs_dir / file).resolve()
    try:
        value = lookup(json.loads(path.read_text(encoding="utf-8")), dotted.strip())
        return format(value, spec.strip()), path
    except (OSError, json.JSONDecodeError, KeyError, IndexError, TypeError, ValueError) as exc:
        raise ValueError(f"{file}#{dotted}: {exc}") from None


class JsonRole(SphinxRole):
    def run(self) -> tuple[list[nodes.Node], list[nodes.system_message]]:
        try:
            value, path = render(self.text, Path(self.env.srcdir))
        except ValueError as exc:
            logger.warning("json role: %s", exc, location=self.get_location())
            return [nodes.problematic(self.rawtext, self.rawtext)], []
        self.env.note_dependency(str(path))
        return [nodes.Text(value)], []


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_role("json", JsonRole())
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
