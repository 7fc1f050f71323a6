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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
from scipy.optimize import nnls

import resources
from simulation.lightsource import LightSource
from simulation.versions import output_header

log = logging.getLogger(__name__)

FORMAT = "dualrgb-preset/1"


class PresetError(ValueError):
    """A preset file is unreadable or invalid (one-line message naming the file and the problem)."""


@dataclass
class Preset:
    name: str
    sources: tuple[LightSource, ...]
    method: str = "manual"
    seed: Optional[int] = None
    mode: str = "reflective"
    errors: dict = field(default_factory=dict)
    dataset: dict = field(default_factory=dict)
    model: dict = field(default_factory=dict)
    created: str = ""

    def to_dict(self) -> dict:
        return {**output_header(FORMAT), "name": self.name, "method": self.method, "seed": self.seed, "mode": self.mode,
                "sources": [s.to_dict() for s in self.sources], "errors": self.errors, "dataset": self.dataset,
                "model": self.model,
                "created": self.created or _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}


def save_preset(preset: Preset, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(preset.to_dict(), indent=2) + "\n", encoding="utf-8")
    tmp.replace(path)
    return path


def load_preset(path: str | Path) -> Preset:
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise PresetError(f"{path}: cannot read preset ({exc.strerror or exc})") from None
    except json.JSONDecodeError as exc:
        raise PresetError(f"{path}:{exc.lineno}: not valid JSON ({exc.msg})") from None
    if not isinstance(data, dict) or not isinstance(data.get("sources"), list) or not data["sources"]:
        raise PresetError(f"{path}: expected a JSON object with a non-empty 'sources' list")
    sources = []
    for i, s in enumerate(data["sources"], start=1):
        if not isinstance(s, dict) or "leds" not in s:
            raise PresetError(f"{path}: source {i}: expected an object with 'leds' and 'levels'")
        try:
            sources.append(LightSource.from_dict({**s, "name": s.get("name") or f"source {i}"}))
        except (TypeError, ValueError) as exc:
            raise PresetError(f"{path}: source {i}: {exc}") from None
    return Preset(name=str(data.get("name") or path.stem), sources=tuple(sources),
                  method=str(data.get("method", "manual")), seed=data.get("seed"),
                  mode=str(data.get("mode", "reflective")), errors=data.get("errors") or {},
                  dataset=data.get("dataset") or {}, model=data.get("model") or {}, created=data.get("created", ""))


def packaged_presets() -> list[Path]:
    """The presets shipped in resources/presets (made by ``python -m resources.make_presets``)."""
    folder = resources.path("presets")
    return sorted(folder.glob("*.json")) if folder.is_dir() else []


def d65_mix(leds: np.ndarray, illuminant: np.ndarray, cmfs: np.ndarray) -> tuple[LightSource, float]:
    """A sphere mix approximating D65 for the 3-channel baseline (thesis 1.4).

    Non-negative least squares of the LED spectra to the D65 spectrum, scaled so the largest level is 1.
    Returns the light source and its chromaticity distance to D65 (CIE 1976 u'v').
    """
    levels, _ = nnls(np.asarray(leds).T, np.asarray(illuminant, dtype=float))
    levels = levels / levels.max()

    def uv(spd: np.ndarray) -> np.ndarray:
        X, Y, Z = spd @ cmfs
        d = X + 15 * Y + 3 * Z
        return np.array([4 * X / d, 9 * Y / d])

    duv = float(np.linalg.norm(uv(levels @ leds) - uv(illuminant)))
    used = [i for i in range(len(levels)) if levels[i] > 1e-4]
    return LightSource(tuple(i + 1 for i in used), tuple(float(levels[i]) for i in used), "D65 mix"), duv
