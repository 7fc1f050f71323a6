"""Presets: the optimiser's light sources saved as JSON for the sphere (LED numbers 1-based, levels 0..1).

A preset file:
{
  "format": "dualrgb-preset/1", "software": {"dualrgb": ..., "numpy": ..., ...},   (simulation.versions)
  "name": "...", "method": "pso", "seed": 0, "mode": "reflective",
  "sources": [{"leds": [1, 6, 7], "levels": [0.0, 0.42, 1.0], "name": "source 1"}, ...],
  "errors": {"train": {"mean":..,"median":..,"p90":..,"max":..}, "test": {...}},
  "dataset": {"train": "...", "test": "..."}, "model": {"grid": "...", "camera": "...", ...}, "created": ISO time
}
"""
from __future__ import annotations

import datetime as _dt
import json
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

from dualrgb import resources
from dualrgb.common.atomic_files import atomic_write
from dualrgb.common.strict_json import dumps as strict_dumps
from dualrgb.simulation.lightsource import N_SPHERE_LEDS, LightSource
from dualrgb.simulation.spectral_io import read_text_file
from dualrgb.simulation.versions import output_header

log = logging.getLogger(__name__)

FORMAT = "dualrgb-preset/1"
MAX_PRESET_BYTES = 2**20


class PresetError(ValueError):
    """A preset file is unreadable or invalid (one-line message naming the file and the problem)."""


@dataclass
class Preset:
    name: str
    sources: tuple[LightSource, ...]
    method: str = "manual"
    seed: int | None = None
    mode: str = "reflective"
    errors: dict = field(default_factory=dict)
    dataset: dict = field(default_factory=dict)
    model: dict = field(default_factory=dict)
    created: str = ""

    def to_dict(self) -> dict:
        return {**output_header(FORMAT), "name": self.name, "method": self.method, "seed": self.seed, "mode": self.mode,
                "sources": [s.to_dict() for s in self.sources], "errors": self.errors, "dataset": self.dataset,
                "model": self.model,
                "created": self.created or _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")}


def save_preset(preset: Preset, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, strict_dumps(preset.to_dict(), indent=2) + "\n")
    return path


def _is_int(v: object) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v: object) -> bool:
    return (isinstance(v, (int, float)) and not isinstance(v, bool)) and math.isfinite(v)


def _source(s: object, i: int, n_leds: int) -> LightSource:
    """One ``sources`` item, checked strictly: every LED an integer 1..N listed once, exactly one level per
    LED in [0, 1]; nothing is guessed (no default levels, no number coercion)."""
    if not isinstance(s, dict):
        raise ValueError(f"expected an object with 'leds' and 'levels', found {type(s).__name__}")
    leds, levels, name = s.get("leds"), s.get("levels"), s.get("name", "")
    if not isinstance(leds, list) or not leds or not all(_is_int(n) for n in leds):
        raise ValueError(f"'leds' must be a non-empty list of whole LED numbers 1..{n_leds}, found {_show(leds)}")
    bad = [n for n in leds if not 1 <= n <= n_leds]
    if bad:
        raise ValueError(f"LED {bad[0]} is outside 1..{n_leds}")
    if len(set(leds)) != len(leds):
        raise ValueError(f"'leds' {leds} lists an LED twice")
    if not isinstance(levels, list) or not all(_is_number(v) for v in levels):
        raise ValueError(f"'levels' must be a list of numbers 0..1, one per LED, found {_show(levels)}")
    if len(levels) != len(leds):
        raise ValueError(f"{len(leds)} LEDs but {len(levels)} levels (one level per LED)")
    if any(not 0.0 <= v <= 1.0 for v in levels):
        raise ValueError(f"level {next(v for v in levels if not 0.0 <= v <= 1.0)} is outside 0..1")
    if not isinstance(name, str):
        raise ValueError(f"'name' must be text, found {_show(name)}")
    return LightSource(tuple(leds), tuple(float(v) for v in levels), name or f"source {i}")


def _show(value: object) -> str:
    text = json.dumps(value) if not isinstance(value, str) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _optional(data: dict, key: str, types: tuple, path: Path) -> None:
    if data.get(key) is not None and (not isinstance(data[key], types) or isinstance(data[key], bool)):
        raise PresetError(f"{path}: '{key}' must be {' or '.join(t.__name__ for t in types)}, "
                          f"found {_show(data[key])}")


def load_preset(path: str | Path, n_leds: int = N_SPHERE_LEDS) -> Preset:
    """Read a preset strictly (see :func:`_source`); any problem is one :class:`PresetError` line naming the
    file: unreadable, binary/UTF-16, over 1 MiB, invalid or too deeply nested JSON, a wrong field."""
    path = Path(path)
    text = read_text_file(path, "preset JSON", PresetError, MAX_PRESET_BYTES)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PresetError(f"{path}:{exc.lineno}: not valid JSON ({exc.msg})") from None
    except RecursionError:
        raise PresetError(f"{path}: not a preset (JSON nested too deeply)") from None
    if not isinstance(data, dict) or not isinstance(data.get("sources"), list) or not data["sources"]:
        raise PresetError(f"{path}: expected a JSON object with a non-empty 'sources' list")
    if len(data["sources"]) > n_leds:
        raise PresetError(f"{path}: {len(data['sources'])} light sources; at most {n_leds} are supported")
    sources = []
    for i, s in enumerate(data["sources"], start=1):
        try:
            sources.append(_source(s, i, n_leds))
        except (TypeError, ValueError) as exc:
            raise PresetError(f"{path}: source {i}: {exc}") from None
    for key in ("name", "method", "mode", "created"):
        _optional(data, key, (str,), path)
    _optional(data, "seed", (int,), path)
    for key in ("errors", "dataset", "model"):
        _optional(data, key, (dict,), path)
    return Preset(name=str(data.get("name") or path.stem), sources=tuple(sources),
                  method=str(data.get("method") or "manual"), seed=data.get("seed"),
                  mode=str(data.get("mode") or "reflective"), errors=data.get("errors") or {},
                  dataset=data.get("dataset") or {}, model=data.get("model") or {}, created=data.get("created") or "")


def packaged_presets() -> list[Path]:
    """The presets shipped in resources/presets (made by ``python -m tools.make_presets``)."""
    folder = resources.path("presets")
    return sorted(folder.glob("*.json")) if folder.is_dir() else []
