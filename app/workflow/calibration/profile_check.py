"""A calibration profile is checked like a frame: its size before it is read, then every number finite, its JSON
Schema (``resources/schemas/dualrgb-calibration-1.schema.json``, shipped in the package so the docs publish it and
the tests validate what the product writes), the value ranges that relate fields, and the digest stored in it.

* **Finite**: NaN and Infinity (which Python's json reads) are refused wherever they are, naming the field
  (``matrix.matrix[0][1]``).
* **Schema**: types, required fields, shapes of the simple fields, value bounds (exposures > 0, white point > 0,
  ppi > 0, levels 0..1, at least one light, ...). The first error names its field.
* **Ranges**: what the schema cannot say: the matrix has one row per channel; every light has a name, exposures,
  a base exposure and a flat-field white; at least one LED level above 0 per light (a light that lights nothing
  would only show after its frames); every exposure within the light-on cap (:data:`MAX_EXPOSURE_S`; the session's
  settle time and the camera's latency are checked again before the light goes on); black < linear limit <=
  white level; the darks cover every planned exposure.
* **Digest**: ``digest`` holds the sha256 of the canonical JSON (keys sorted, no spaces, ASCII) of every other
  top-level field and of all of them together. A profile is made by ``dualrgb calibrate``, never edited: a
  changed field is refused, naming it (calibrate again; ``--ppi`` sets the sampling of a capture without editing).
* **Arrays**: the .npz is at most :func:`npz_cap` bytes (what its arrays need) and holds every array the JSON
  names.

Every refusal is a :class:`ProfileError` (one line: the file, the field, what was expected).
"""
from __future__ import annotations

import hashlib
import json
import logging
import math
from collections.abc import Iterator
from functools import cache
from pathlib import Path
from typing import Any

from dualrgb.simulation.colour_models import n_terms

log = logging.getLogger(__name__)

FORMAT = "dualrgb-calibration/1"

SCHEMA_FILE = "dualrgb-calibration-1.schema.json"
DIGEST_ALGORITHM = "sha256 of canonical JSON"
MAX_JSON_BYTES = 16 * 1024 * 1024      # a profile is ~40 kB (a spectral estimator and a stand model included)
MAX_EXPOSURE_S = 10.0                  # the light-on cap (thesis 4.3.2): no calibrated exposure can be longer
NPZ_SLACK_BYTES = 16 * 1024 * 1024     # zip headers and the stand model's observation arrays
DARK_RTOL = 0.02                       # app.processing.calibration.EXPOSURE_RTOL: a dark serves +-2 %
MAX_NPZ_BYTES = 8 * 1024 ** 3          # whatever the JSON says: never more than this


class ProfileError(ValueError):
    """A calibration profile is unreadable, damaged or does not fit the stand (one line)."""


@cache
def schema() -> dict[str, Any]:
    """The profile's JSON Schema, read from the installed package."""
    from dualrgb import resources

    return dict(json.loads(resources.path("schemas", SCHEMA_FILE).read_text(encoding="utf-8")))


def read_document(path: Path) -> dict[str, Any]:
    """The profile JSON at ``path`` as a dict, its size checked before it is read (:data:`MAX_JSON_BYTES`)."""
    from dualrgb.simulation.spectral_io import read_json_file

    doc = read_json_file(path, "calibration JSON", ProfileError, MAX_JSON_BYTES)
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else None
        raise ProfileError(f"{path}: not a dualrgb calibration (format {found!r}, expected {FORMAT!r})")
    return doc


def check_document(doc: dict[str, Any], where: str | Path, *, digest: bool = True) -> None:
    """Every check above but the arrays'; ``digest=False`` while the profile is being written (before sealing)."""
    for field, value in _numbers(doc, ""):
        if not math.isfinite(value):
            raise ProfileError(f"{where}: {field} is {value}, expected a finite number")
    _check_schema(doc, where)
    _check_ranges(doc, where)
    if digest:
        check_digest(doc, where)


@cache
def _validator() -> Any:
    import jsonschema

    return jsonschema.Draft202012Validator(schema())


def _check_schema(doc: dict[str, Any], where: str | Path) -> None:
    import jsonschema

    error = jsonschema.exceptions.best_match(_validator().iter_errors(doc))
    if error is not None:
        field = field_name(error.absolute_path) or "the calibration"
        raise ProfileError(f"{where}: {field}: {_short(error.message)} (resources/schemas/{SCHEMA_FILE})")


def _short(message: str, limit: int = 160) -> str:
    text = " ".join(message.split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def field_name(path: Any) -> str:
    """``["matrix", "matrix", 0, 1]`` -> ``matrix.matrix[0][1]``."""
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _numbers(value: Any, field: str) -> Iterator[tuple[str, float]]:
    if isinstance(value, float):
        yield field, value
    elif isinstance(value, dict):
        for key, item in value.items():
            yield from _numbers(item, f"{field}.{key}" if field else str(key))
    elif isinstance(value, list):
        for i, item in enumerate(value):
            yield from _numbers(item, f"{field}[{i}]")


def _check_ranges(doc: dict[str, Any], where: str | Path) -> None:
    def refuse(field: str, problem: str) -> None:
        raise ProfileError(f"{where}: {field}: {problem}")

    rows, channels = doc["matrix"]["matrix"], doc["matrix"]["channels"]
    degree = doc["matrix"].get("degree", 1)
    want = n_terms(len(channels), degree)             # a root-polynomial: one row per term (simulation.colour_models)
    if len(rows) != want:
        refuse("matrix.matrix", f"{len(rows)} rows for {len(channels)} channels ({', '.join(channels)})"
                                + (f" of degree {degree} ({want} terms)" if degree != 1 else ""))
    names = [light["name"] for light in doc["lights"]]
    if len(set(names)) != len(names):
        refuse("lights", f"two lights are named alike ({', '.join(names)})")
    for i, light in enumerate(doc["lights"]):
        if len(light["levels"]) != len(light["leds"]):
            refuse(f"lights[{i}].levels", f"{len(light['levels'])} levels for {len(light['leds'])} LEDs")
        if light["leds"] and not any(level > 0 for level in light["levels"]):    # no LEDs: unknown (imported)
            refuse(f"lights[{i}].levels", f"every level of {light['name']} is 0: it lights nothing")
    _check_plan(doc, names, refuse)
    _check_sections(doc, refuse)
    raw = doc["raw"]
    if not raw["black_level"] < raw["linear_limit"] <= raw["white_level"]:
        refuse("raw", f"expected black level < linear limit <= white level, got {raw['black_level']:g}, "
                      f"{raw['linear_limit']:g}, {raw['white_level']:g}")
    _check_created(doc["created_at"], refuse)


def _check_plan(doc: dict[str, Any], names: list[str], refuse: Any) -> None:
    for key in ("exposures", "base_exposures"):
        if sorted(doc[key]) != sorted(names):
            refuse(key, f"names lights {', '.join(sorted(doc[key]))}, the calibration has {', '.join(names)}")
    for name, times in doc["exposures"].items():
        for t in times:
            if t > MAX_EXPOSURE_S:
                refuse(f"exposures.{name}", f"{t:g} s is over the {MAX_EXPOSURE_S:g} s light-on cap")
        if doc["base_exposures"][name] not in times:
            refuse(f"base_exposures.{name}", f"{doc['base_exposures'][name]:g} s is not one of its exposures")
    whites = sorted(w["light"] for w in doc["arrays"]["whites"])
    if whites != sorted(names):
        refuse("arrays.whites", f"flat fields for {', '.join(whites)}, the calibration has {', '.join(names)}")
    darks = [d["exposure_s"] for d in doc["arrays"]["darks"]]
    missing = sorted(t for t in {t for ts in doc["exposures"].values() for t in ts}
                     if not any(abs(d - t) <= DARK_RTOL * max(d, t) for d in darks))
    if missing:
        refuse("arrays.darks", f"no master dark at {', '.join(f'{t:g}' for t in missing)} s")


def _check_sections(doc: dict[str, Any], refuse: Any) -> None:
    """What relates the fields of the figures' sections (the schema types each field): the matrix's channels
    three per light, the statistics' best method among its methods, the spectral estimator's matrix of one row
    per wavelength and one column per channel (the matrix's), the stand model's R^2 per channel alike before and
    after the fit, a chart's used patches among its patches."""
    channels, lights = doc["matrix"]["channels"], doc["lights"]
    if len(channels) != 3 * len(lights):
        refuse("matrix.channels", f"{len(channels)} channels for {len(lights)} light(s): expected 3 per light "
                                  f"(R, G, B under each)")
    _check_statistics(doc["statistics"], channels, refuse)
    gain = (doc.get("spectral") or {}).get("model_gain")
    if gain is not None and len(gain) != len(channels):
        refuse("spectral.model_gain", f"{len(gain)} values for {len(channels)} channels")
    estimator = (doc.get("spectral") or {}).get("estimator")
    if estimator is not None:
        _check_estimator(estimator, channels, refuse)
    r2 = [(f"stand_model.r2.{stage}.{target}", values) for stage, by_target in
          ((doc.get("stand_model") or {}).get("r2") or {}).items() for target, values in by_target.items()]
    for field, values in r2[1:]:
        if len(values) != len(r2[0][1]):
            refuse(field, f"{len(values)} channels, {r2[0][0]} has {len(r2[0][1])}")
    for role, chart in (doc.get("charts") or {}).items():
        if chart["used"] > chart["patches"]:
            refuse(f"charts.{role}.used", f"{chart['used']} of {chart['patches']} patches")
        low, high = chart.get("wavelength_range_nm") or (0, 1)
        if not low < high:
            refuse(f"charts.{role}.wavelength_range_nm", f"{low:g}-{high:g} nm is no range")


def _check_statistics(stats: dict[str, Any], channels: list[str], refuse: Any) -> None:
    if stats["best"] not in stats["methods"]:
        refuse("statistics.best", f"{stats['best']!r} is not one of its methods ({', '.join(stats['methods'])})")
    if "channels" in stats and stats["channels"] != channels:
        refuse("statistics.channels", f"{', '.join(stats['channels'])}, the matrix {', '.join(channels)}")
    for name, method in stats["methods"].items():
        fitted = method.get("matrix")
        if fitted is None:
            continue
        own = fitted.get("channels", channels)
        want = n_terms(len(own), fitted.get("degree", 1))     # a root-polynomial: one row per term
        if len(fitted["matrix"]) != want:
            refuse(f"statistics.methods.{name}.matrix", f"{len(fitted['matrix'])} rows for {len(own)} channels "
                                                        f"(degree {fitted.get('degree', 1)}: {want} terms)")
        if own != channels:
            refuse(f"statistics.methods.{name}.matrix", f"channels {', '.join(own)}, the matrix "
                                                        f"{', '.join(channels)}")


def _check_estimator(estimator: dict[str, Any], channels: list[str], refuse: Any) -> None:
    where = "spectral.estimator"
    if estimator["channels"] != channels:
        refuse(f"{where}.channels", f"the spectral estimator maps {', '.join(estimator['channels'])} but the matrix "
                                    f"{', '.join(channels)}")
    rows, n_wl = estimator["matrix"], len(estimator["wavelengths_nm"])
    if len(rows) != n_wl or any(len(row) != len(channels) for row in rows):
        refuse(f"{where}.matrix", f"expected {n_wl} rows (one per wavelength) of {len(channels)} (one per channel)")
    wl = estimator["wavelengths_nm"]
    if any(b <= a for a, b in zip(wl, wl[1:], strict=False)):
        refuse(f"{where}.wavelengths_nm", "the wavelengths must increase")
    low, high = estimator.get("bounds", (0.0, 1.0))
    if not low < high:
        refuse(f"{where}.bounds", f"{low:g}..{high:g} is no range")
    for key, n in (("offset", n_wl), ("noise_var", len(channels))):
        values = estimator.get(key) if key == "offset" else (estimator.get("settings") or {}).get(key)
        if values is not None and len(values) != n:
            refuse(f"{where}.{'settings.' if key == 'noise_var' else ''}{key}", f"{len(values)} values, expected {n}")


def _check_created(created: str, refuse: Any) -> None:
    from datetime import datetime

    try:
        stamp = datetime.fromisoformat(created)
    except ValueError:
        refuse("created_at", f"{created!r} is not a date and time (ISO 8601, e.g. 2026-11-24T09:30:00+00:00)")
        return
    if stamp.tzinfo is None:
        refuse("created_at", f"{created!r} has no time zone (expected e.g. +00:00)")


# ---------------------------------------------------------------------------------------------------- digest
def canonical(value: Any) -> bytes:
    """The canonical JSON of ``value``: keys sorted, no spaces, ASCII (other characters escaped), no NaN."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False).encode()


def _digest_of(doc: dict[str, Any]) -> dict[str, Any]:
    fields = {key: hashlib.sha256(canonical(value)).hexdigest() for key, value in doc.items() if key != "digest"}
    everything = hashlib.sha256(canonical({k: v for k, v in doc.items() if k != "digest"})).hexdigest()
    return {"algorithm": DIGEST_ALGORITHM, "fields": fields, "sha256": everything}


def seal(doc: dict[str, Any]) -> dict[str, Any]:
    """``doc`` with its digest (computed on the JSON round trip of ``doc``, i.e. exactly what a reader sees)."""
    plain = json.loads(json.dumps({k: v for k, v in doc.items() if k != "digest"}, allow_nan=False))
    return {**plain, "digest": _digest_of(plain)}


def check_digest(doc: dict[str, Any], where: str | Path) -> None:
    """Refuse a profile whose content differs from its stored digest, naming the fields that changed."""
    stored = doc.get("digest")
    if not isinstance(stored, dict):
        raise ProfileError(f"{where}: no digest (written by a dualrgb before 0.2, or the digest was removed): its "
                           "content cannot be trusted; calibrate again")
    now = _digest_of(doc)
    if stored.get("sha256") == now["sha256"]:
        return
    before = stored.get("fields") or {}
    changed = sorted(k for k in set(before) | set(now["fields"]) if before.get(k) != now["fields"].get(k))
    what = (f"field{'s' if len(changed) > 1 else ''} {', '.join(changed)} changed" if changed
            else "its digest was edited")
    raise ProfileError(f"{where}: edited after it was written ({what}; the digest stored in it no longer matches): "
                       "a calibration is not edited by hand; calibrate again (capture --ppi sets the sampling)")


# ---------------------------------------------------------------------------------------------------- arrays
def npz_cap(doc: dict[str, Any]) -> int:
    """The most bytes the profile's .npz may hold: its float32 darks and whites at the raw frame's shape, plus
    slack for the zip and the stand model's observations (never over :data:`MAX_NPZ_BYTES`)."""
    h, w = doc["raw"]["shape"]
    n = len(doc["arrays"]["darks"]) + len(doc["arrays"]["whites"])
    return min(MAX_NPZ_BYTES, int(1.05 * 4 * h * w * n) + NPZ_SLACK_BYTES)


def check_npz(doc: dict[str, Any], npz: Path, names: list[str]) -> None:
    """The .npz holds every array the JSON names (``names``: the arrays in the file)."""
    wanted = [a["array"] for a in doc["arrays"]["darks"] + doc["arrays"]["whites"]]
    missing = [name for name in wanted if name not in names]
    if missing:
        raise ProfileError(f"{npz}: no array {', '.join(missing)}, which {doc['id']}.json names (arrays.darks / "
                           "arrays.whites); calibrate again")
