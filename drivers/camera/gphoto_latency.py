"""Measure a camera's latency: how long after the end of an exposure :meth:`Camera.expose` returns.

That is the time the light must be allowed beyond settle + exposure (core.light_safety.SafetySettings): a
camera slower than its allowance gets every frame rejected (the light is cut before the camera reported the
shutter closed). Run it once on the copy stand, lens cap on (no light is switched on; the frames are downloaded
and discarded, and deleted from the card):

    python -m dualrgb.drivers.camera.gphoto_latency [--port usb:001,007] [--repeats 3]

It prints one line per exposure time and the allowance to use, to be set as ``DUALRGB_GPHOTO_LATENCY_S``
(docs/first-session-d610.md).
"""
from __future__ import annotations

import argparse
import logging
import statistics
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from dualrgb.drivers.camera.base import Camera, CameraError
from dualrgb.drivers.camera.gphoto_labels import format_shutter

log = logging.getLogger(__name__)

EXPOSURES_S = (1 / 125, 1 / 8, 1.0, 4.0)   # short, and long enough for long-exposure NR (>= 1 s) to show
MARGIN = 1.5                                # allowance = worst measured latency x MARGIN + FLOOR_S
FLOOR_S = 0.2


@dataclass
class LatencyMeasurement:
    exposure_s: float
    latencies_s: list[float]                 # expose() return - trigger - exposure, per repeat
    fetch_s: list[float]                     # the download that follows (light off by then)

    def line(self) -> str:
        lat, fetch = self.latencies_s, self.fetch_s
        return (f"{format_shutter(self.exposure_s):>9}: shutter reported closed {statistics.median(lat):.2f} s "
                f"after the exposure (worst {max(lat):.2f} s of {len(lat)}); download {statistics.median(fetch):.2f} s")


def suggested_allowance(measurements: Sequence[LatencyMeasurement]) -> float:
    """The allowance to set: the worst latency seen, with a margin (rounded up to 0.1 s)."""
    worst = max(max(m.latencies_s) for m in measurements)
    return round(worst * MARGIN + FLOOR_S + 0.049, 1)


def measure_latency(camera: Camera, exposures: Sequence[float] = EXPOSURES_S, repeats: int = 3,
                    clock: Callable[[], float] | None = None) -> list[LatencyMeasurement]:
    """Expose and fetch ``repeats`` frames per exposure time (no light involved); the frames are discarded."""
    import time

    clock = clock or time.monotonic
    out = []
    for t in exposures:
        m = LatencyMeasurement(float(t), [], [])
        for _ in range(repeats):
            exposure = camera.expose(t)
            nr = camera.latency_for(t) - camera.latency_s      # a dark frame the camera says it adds (NR on)
            m.latencies_s.append(max(0.0, exposure.ended - exposure.started - exposure.exposure_s - nr))
            began = clock()
            camera.fetch(exposure)
            m.fetch_s.append(clock() - began)
        log.info("%s", m.line())
        out.append(m)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    from dualrgb.drivers.camera.gphoto import LATENCY_ENV, GPhotoCamera

    p = argparse.ArgumentParser(prog="python -m dualrgb.drivers.camera.gphoto_latency",
                                description=__doc__.split("\n")[0])
    p.add_argument("--port", help="the camera's port from `dualrgb devices` (default: the first camera)")
    p.add_argument("--repeats", type=int, default=3, choices=range(1, 21), metavar="1..20",
                   help="frames per exposure time (default 3)")
    args = p.parse_args(argv)
    try:
        with GPhotoCamera(port=args.port, delete_from_card=True) as cam:
            print(f"{cam.model}: quality {cam.image_quality or '?'}, auto ISO {cam.auto_iso}, long-exposure NR "
                  f"{cam.long_exposure_nr}; allowance now {cam.latency_s:g} s")
            measurements = measure_latency(cam, repeats=args.repeats)
    except CameraError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    for m in measurements:
        print(m.line())
    allowance = suggested_allowance(measurements)
    print(f"suggested allowance: {allowance:g} s  ->  export {LATENCY_ENV}={allowance:g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
