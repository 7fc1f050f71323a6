"""JSON as every file the product writes is made: ``json.dumps`` with ``allow_nan=False``, because NaN and
Infinity are not JSON (Python writes them, most other readers refuse the file). A value that holds one is a
ValueError naming the first key path that does (``at stand.leds[3].fwhm_nm``), so the writer that produced it
is found, and the unknown value can be written as ``null`` where it is made.

    text = dumps(data, indent=2)          # ValueError: Out of range float values ...: at a.b[2] (not JSON; ...)
"""
from __future__ import annotations

import json
import logging
import math
from typing import Any

log = logging.getLogger(__name__)


def non_finite_path(data: Any, path: str = "") -> str:
    """The key path ('a.b[2]') of the first NaN or infinite float in ``data``; '' when there is none."""
    if isinstance(data, float):
        return "" if math.isfinite(data) else (path or "(top)")
    items: Any = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list | tuple) else ()
    for k, v in items:
        found = non_finite_path(v, f"{path}.{k}" if isinstance(k, str) else f"{path}[{k}]")
        if found:
            return found.lstrip(".")
    return ""


def dumps(data: Any, **kw: Any) -> str:
    """``json.dumps(data, allow_nan=False, **kw)``; a NaN or Infinity is a ValueError naming where it is."""
    try:
        return json.dumps(data, allow_nan=False, **kw)
    except ValueError as exc:
        if "Out of range float" not in str(exc):
            raise
        raise ValueError(f"{exc}: at {non_finite_path(data) or '?'} (not JSON: a number must be finite)") from None


def finite_or_none(value: float | None) -> float | None:
    """``value`` as a JSON number, or None (null) when it is unknown (NaN) or infinite."""
    return None if value is None or not math.isfinite(float(value)) else float(value)
