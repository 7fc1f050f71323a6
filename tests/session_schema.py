"""The session's JSON Schema (resources/schemas/dualrgb-session-1.schema.json, packaged), for the tests that check
the session.json files the product writes."""
from __future__ import annotations

import json
from pathlib import Path

import jsonschema

from dualrgb import resources

SCHEMA_FILE = "dualrgb-session-1.schema.json"


def session_schema() -> dict:
    return json.loads(resources.path("schemas", SCHEMA_FILE).read_text(encoding="utf-8"))


def problems(doc: object) -> list[str]:
    """Each place ``doc`` breaks the schema, as '<where>: <message>'."""
    validator = jsonschema.Draft202012Validator(session_schema(), format_checker=jsonschema.FormatChecker())
    return [f"{'/'.join(map(str, e.absolute_path)) or '(top)'}: {e.message}"
            for e in sorted(validator.iter_errors(doc), key=lambda e: list(e.absolute_path))]


def session_problems(folder: Path) -> list[str]:
    """The schema's findings in ``folder/session.json`` (NaN and Infinity refused as not JSON)."""
    def refuse(token: str) -> float:
        raise ValueError(f"{token} in {folder}/session.json")
    return problems(json.loads((Path(folder) / "session.json").read_text(encoding="utf-8"), parse_constant=refuse))
