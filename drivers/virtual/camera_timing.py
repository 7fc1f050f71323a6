"""A real camera's timing for the virtual camera: the shutter lag after the trigger and the USB download.

A world file's ``camera_timing`` (drivers/virtual/world.py) is either a preset's name (``"d610"``) or
``{"shutter_lag_s": s, "download_s": s}``; the virtual camera then waits the shutter lag (real time, the light on)
between the trigger and the exposure, and takes at least ``download_s`` (real time, the light off) to hand over a
frame, so a queue's pipeline (app.workflow.day.queue_run) is measured against a realistic stand. Without the key the
virtual camera has neither (the nominal world: as fast as the host renders).

The D610 preset: an uncompressed 14-bit NEF of the D610's 24.3 MP is about 30 MB (docs/first-session-d610.md,
/work/shared/FACTS.md); the D610's USB port is USB 2.0 Hi-Speed (Nikon D610 specifications), whose practical PTP
throughput of some 25-35 MB/s gives about 1 s per frame; the shutter lag of 0.07 s is an assumed mid-value of the
0.05-0.1 s that review labs publish for DSLRs of its class in manual focus (Nikon publishes none). Neither is
measured here: measure a body with ``python -m dualrgb.drivers.camera.gphoto_latency`` (it prints the download
time and the latency) and write a world with those figures.
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from typing import Any

log = logging.getLogger(__name__)

MAX_S = 30.0


@dataclass(frozen=True)
class CameraTiming:
    """Seconds the virtual camera spends as a real one would (module docstring); 0: none."""

    shutter_lag_s: float = 0.0
    download_s: float = 0.0
    preset: str = ""                 # the preset's name when the world named one

    @property
    def identity(self) -> bool:
        return self.shutter_lag_s == 0.0 and self.download_s == 0.0

    def lag(self) -> None:
        """The shutter lag, waited in real time (the trigger to the shutter opening)."""
        if self.shutter_lag_s > 0:
            time.sleep(self.shutter_lag_s)

    def download(self, started: float) -> None:
        """Wait until the download begun at ``started`` (time.perf_counter) has lasted ``download_s``."""
        left = self.download_s - (time.perf_counter() - started)
        if left > 0:
            time.sleep(left)

    def to_dict(self) -> str | dict[str, float]:
        if self.preset:
            return self.preset
        return {"shutter_lag_s": self.shutter_lag_s, "download_s": self.download_s}


# the D610 over USB 2.0 (module docstring: the figures' sources)
PRESETS = {"d610": CameraTiming(shutter_lag_s=0.07, download_s=1.0, preset="d610")}
_FIELDS = ("shutter_lag_s", "download_s")


def parse_timing(source: str, key: str, value: Any) -> CameraTiming:
    """A world's ``camera_timing``: a preset's name or an object of the two seconds (ValueError: one line)."""
    if isinstance(value, str):
        if value not in PRESETS:
            raise ValueError(f"{source}: key {key!r}: expected one of {', '.join(PRESETS)} or an object with "
                             f"{' and '.join(_FIELDS)}, found {value!r}")
        return PRESETS[value]
    if not isinstance(value, dict):
        raise ValueError(f"{source}: key {key!r}: expected a preset's name ({', '.join(PRESETS)}) or an object "
                         f"with {' and '.join(_FIELDS)}, found {type(value).__name__}")
    for k in value:
        if k not in _FIELDS:
            raise ValueError(f"{source}: unknown key '{key}.{k}'; expected one of {', '.join(_FIELDS)}")
    seconds: dict[str, float] = {}
    for k, v in value.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 <= v <= MAX_S:
            raise ValueError(f"{source}: key '{key}.{k}': expected a number of seconds from 0 to {MAX_S:g}, "
                             f"found {v!r}")
        seconds[k] = float(v)
    return CameraTiming(shutter_lag_s=seconds.get("shutter_lag_s", 0.0), download_s=seconds.get("download_s", 0.0))
