"""Identifier templates (issue 42), Qt-free: ``{collection}-{date}-{counter:04}`` -> ``GEM-20261128-0007``.

Tokens: ``{counter}`` (the next number, remembered; a format such as ``:04`` pads it), ``{date}`` (today; a
strftime format such as ``:%Y-%m-%d``, default ``%Y%m%d``), ``{operator}`` and ``{collection}`` (the Operator and
Collection fields). The result is an identifier like any typed one: core.metadata checks it when the
original is added.
"""
from __future__ import annotations

import datetime as _dt
import re

TOKEN = re.compile(r"\{(\w+)(?::([^}]*))?\}")
TOKENS = ("counter", "date", "operator", "collection")


class TemplateError(ValueError):
    """A template naming an unknown token or a bad format (one line)."""


def expand(template: str, *, counter: int, operator: str = "", collection: str = "",
           today: _dt.date | None = None) -> str:
    """``template`` with its tokens replaced (see the module docstring)."""
    day = today or _dt.date.today()

    def one(match: re.Match[str]) -> str:
        name, spec = match.group(1), match.group(2)
        try:
            if name == "counter":
                return format(counter, f"{spec}d" if spec else "d")
            if name == "date":
                return day.strftime(spec or "%Y%m%d")
        except ValueError as exc:
            raise TemplateError(f"identifier template: {{{name}:{spec}}}: {exc}") from None
        if name in ("operator", "collection"):
            return operator if name == "operator" else collection
        raise TemplateError(f"identifier template: unknown token {{{name}}}; known: "
                            + ", ".join(f"{{{t}}}" for t in TOKENS))

    return TOKEN.sub(one, template).strip()
