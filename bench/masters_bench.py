"""What the archival deliverables of issue 39 cost, in time and bytes, per original: at the virtual lab's default
frame (600 x 400 at full resolution) and at the D610's 24 MP (6080 x 4028).

Each run delivers one dual-RGB original (6 channels, a ChannelStack in memory, so the raw decoding and HDR merge
that bench/digitise_bench.py measures are left out) through ``deliver`` with a set of delivery settings, and times
the whole delivery and the size of each file:

* ``masters``: the default masters (ProPhoto, sRGB, XYZ, two camera-RGB) with their EXIF, XMP and ICC profiles;
* ``working_spaces``: plus the eciRGB v2 and Adobe RGB (1998) masters;
* ``access``: plus the JPEG 2000 (lossless) and the pyramidal TIFF access copies;
* ``spectral``: the masters plus the spectral cube and its rendering (at full resolution, on request);

and ``bag``: ``dualrgb bag`` of the ``access`` delivery (copies: this machine's file system offers no reflink).

    .venv/bin/python -m bench.masters_bench [--sizes default,24mp] [--json bench/results/masters.json]
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SIZES = {"default": (600, 400), "24mp": (6080, 4028)}
SETS = {"masters": {}, "working_spaces": {"masters": ("eciRGB v2", "Adobe RGB (1998)")},
        "access": {"masters": ("eciRGB v2", "Adobe RGB (1998)"), "access": ("jp2", "pyramid")},
        "spectral": {"spectral": True}}


def _profile(folder: Path, shape: tuple[int, int]):
    sys.path.insert(0, str(ROOT / "tests"))
    from spectral_profiles import estimator
    from workflow_profiles import make_profile

    from dualrgb.core.vocabulary import NamedLight
    from dualrgb.simulation.lightsource import LightSource
    from dualrgb.simulation.matrix_fit import CharacterisationMatrix

    prof = make_profile(folder, shape=(8, 12))
    lights = prof.lights + [NamedLight("P light 2", LightSource((3, 5, 9), (1.0, 0.5, 0.8), "P light 2"))]
    channels = ["R1", "G1", "B1", "R2", "G2", "B2"]
    matrix = CharacterisationMatrix(np.random.default_rng(1).uniform(0, 30, (6, 3)), channels)
    return replace(prof, lights=lights, matrix=matrix, estimator=estimator(tuple(channels)),
                   raw={**prof.raw, "shape": [shape[1], shape[0]], "ppi_grid": "sensor"},
                   exposures={"P light 1": [0.04], "P light 2": [0.05]})


def _stack(width: int, height: int):
    from dualrgb.app.processing.pipeline import ChannelStack

    rng = np.random.default_rng(2)
    cells = rng.uniform(0.02, 1.2, (height // 64 + 1, width // 64 + 1, 6)).astype(np.float32)
    data = np.repeat(np.repeat(cells, 64, 0), 64, 1)[:height, :width]
    data += rng.normal(0, 0.004, data.shape).astype(np.float32)
    return replace(ChannelStack(np.ascontiguousarray(data), ["R1", "G1", "B1", "R2", "G2", "B2"],
                                ["P light 1", "P light 2"], {"P light 1": 0.0, "P light 2": 0.0}), resolution="full")


def bench_size(width: int, height: int, work: Path) -> dict:
    from dualrgb.app.workflow.delivery.bagging import make_day_bag
    from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver
    from dualrgb.app.workflow.delivery.delivery_settings import DeliverySettings

    prof = _profile(work / "cal", (width, height))
    source = _stack(width, height)
    out: dict = {"width": width, "height": height, "sets": {}}
    deliver(source, prof, Original("B-warm"), work / "warm", camera=prof.camera, dose=LightDoseRecord(1.0, 0.1),
            settings=DeliverySettings())                         # first use: the colour data, the camera model
    shutil.rmtree(work / "warm")
    for name, kw in SETS.items():
        folder = work / name
        t = time.perf_counter()
        d = deliver(source, prof, Original(f"B-{name}"), folder, camera=prof.camera, dose=LightDoseRecord(1.0, 0.1),
                    exposures={"P light 1": [0.04], "P light 2": [0.05]}, settings=DeliverySettings(**kw))
        wall = time.perf_counter() - t
        sizes = {k: p.stat().st_size for k, p in d.files.items()}
        out["sets"][name] = {"deliver_s": round(wall, 3), "bytes": sizes, "total_bytes": sum(sizes.values())}
        if name == "access":
            out["access_copy_s"] = _access_times(d, prof, work)
            t = time.perf_counter()
            bag = make_day_bag(folder, work / "bag")
            out["bag"] = {"s": round(time.perf_counter() - t, 3), "bytes": bag.bytes, "files": bag.files,
                          "placed": bag.placed}
        if name != "access":
            shutil.rmtree(folder)
    base = out["sets"]["masters"]
    for s in out["sets"].values():
        s["extra_s"] = round(s["deliver_s"] - base["deliver_s"], 3)
        s["extra_bytes"] = s["total_bytes"] - base["total_bytes"]
    acc = out["sets"]["access"]["bytes"]
    out["access_copies"] = {"jp2_bytes": acc["access_jp2"], "pyramid_bytes": acc["access_pyramid"],
                            "jp2_ratio_to_srgb": round(acc["access_jp2"] / acc["srgb"], 3)}
    return out


def _access_times(d, prof, work: Path) -> dict:
    """Each access copy made again on its own from the delivered sRGB master (seconds)."""
    from datetime import UTC, datetime

    from dualrgb.app.workflow.delivery.access_copies import make_access_copy
    from dualrgb.app.workflow.delivery.deliverables import ACCESS_NAMES, Deliverable
    from dualrgb.app.workflow.delivery.master_metadata import MasterContext

    now = datetime.now(UTC)
    ctx = MasterContext(d.original, prof.id, prof.camera, 1.0, 300.0, now, now, white_xyz=list(prof.white_xyz))
    out = {}
    for key in ("jp2", "pyramid"):
        im = Deliverable(work / f"again_{ACCESS_NAMES[key]}", 3, "access", space=key, what=key)
        t = time.perf_counter()
        make_access_copy(im, d.files["srgb"], ctx)
        out[key] = round(time.perf_counter() - t, 3)
        im.path.unlink()
    return out


def bench_masters(sizes: tuple[str, ...] = ("default", "24mp")) -> dict:
    from dualrgb.app.warm_kernels import warm_delivery

    warm_delivery()
    res: dict = {"cpus": os.cpu_count(), "load_average_1min": round(os.getloadavg()[0], 2), "sizes": {}}
    for key in sizes:
        with tempfile.TemporaryDirectory(dir=os.environ.get("BENCH_TMP")) as tmp:
            res["sizes"][key] = bench_size(*SIZES[key], Path(tmp))
    return res


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="default,24mp")
    p.add_argument("--json", type=Path, default=ROOT / "bench" / "results" / "masters.json")
    a = p.parse_args(argv)
    res = bench_masters(tuple(a.sizes.split(",")))
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps(res, indent=2) + "\n")
    print(json.dumps(res, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
