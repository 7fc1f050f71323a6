"""The delivery sidecar's JSON Schema (resources/schemas/dualrgb-delivery-1.schema.json, the packaged copy) applied
to the sidecars the tests write, with jsonschema: :func:`assert_valid_sidecar`. The JSON is also parsed strictly
(NaN and Infinity are not JSON)."""
from __future__ import annotations

import json
from pathlib import Path

import jsonschema

from dualrgb.app.workflow.delivery.fixity import sidecar_schema


def _no_constant(name: str):
    raise ValueError(f"{name} is not JSON")


def assert_valid_sidecar(path: Path) -> dict:
    """The sidecar at ``path``, checked against its schema (every finding listed on failure)."""
    doc = json.loads(Path(path).read_text(encoding="utf-8"), parse_constant=_no_constant)
    validator = jsonschema.Draft202012Validator(sidecar_schema())
    errors = [f"{'/'.join(map(str, e.absolute_path)) or '(top)'}: {e.message}" for e in validator.iter_errors(doc)]
    assert not errors, f"{path}: " + "; ".join(errors)
    return doc
