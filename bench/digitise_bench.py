"""Digitise one original: a dual-RGB capture (2 lights x 2 exposures, thesis Table 8.1 times) with a saved
calibration, from the last frame landing to every deliverable written, at full resolution (the default: each
light demosaiced to the sensor's pixels) and at half resolution (2x2 cells), against the bare rawpy decode of the
same four frames and LibRaw's own full-resolution path (rawpy ``postprocess``: LINEAR demosaic, linear 16-bit
output) on them - all in one run, interleaved, so the load other processes put on the machine hits each alike.

The set is bench/processing_bench.py's scene (its darks and whites make the calibration, its scene frames are the
original); for large sensors (``--size``) it is generated row band by row band (:func:`make_large_set`, fewer
darks). Each measurement runs in a fresh process (peak RSS = ru_maxrss):

  decode          rawpy.imread + a copy of raw_image_visible of the 4 original frames: the floor
  full            CopyStand's streaming path at full resolution: frames 1-3 land during the capture (held as
                  decoded, not timed), then the last frame is decoded, and every band is merged, flat-fielded,
                  demosaiced, encoded and written (the TIFFs with ICC / XMP / tags and their SHA-256) and the
                  sidecar (phases: frames_added, deliver)
  half            the same at half resolution (frames merged as they land; the spectral cube and its rendering
                  are files there)
  libraw          rawpy.imread + postprocess(LINEAR demosaic, gamma 1, no auto-brightening, 16-bit, camera RGB) of
                  the 4 frames: what LibRaw's own full-resolution demosaic costs, nothing written
  full_all_frames the full-resolution delivery from the 4 frames on disk (``dualrgb process``)
  full_without_sha256  a diagnostic, not a product mode: ``full`` with the TIFFs' SHA-256 switched off (what the
                  fixity costs in the pipelined delivery; the sidecar then holds no digests)
  cube_on_demand  ``dualrgb cube``: the full-resolution delivery's cube (ENVI) made from its camera-RGB TIFFs
  full_rp2        ``full`` with a root-polynomial of degree 2 delivered (what the virtual lab's default dual-RGB
                  calibration delivers; the bench calibration's own matrix is least squares, linear)
  full_stages     where the full-resolution delivery's CPU time goes, stage by stage, single-threaded, and the
                  two-core floor they give (bench/delivery_stages.py); the summary's ``delivery`` compares the
                  measured ``full`` with it (``delivery_root_polynomial_2``: ``full_rp2``)
  models          the demosaic + colour encodings of every band (DeliveryEncoder.encode_mosaic), single-threaded,
                  with each characterisation model the calibration may deliver: the linear matrix (least squares
                  or dE00-optimised), root-polynomial degree 2 (21 terms) and 3 (71 terms) (issue 40): CPU seconds
                  and ns per delivered pixel, and what each adds over the linear matrix

Every run records the 1-minute load average before and after it (``load_1min``); ``--quiet-below L`` waits (up to
10 minutes) before each run until the load is below L. Targets (issues 31 and 41): full <= 2.0 x decode at 24 MP, its
CPU time <= 1.25 x the stages' sum; at 150 MP (``--size 14204x10652``) peak RSS <= 4 GB and time
per pixel within 1.3 x of the 24 MP case. Loading the profile and the numba kernels happen before the capture
starts and are reported separately.

    python -m bench.digitise_bench [--size WxH] [--repeats N] [--json PATH] [--cache DIR]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.child import cpu_s, run_in_child
from bench.delivery_stages import summary_lines

ROOT = Path(__file__).resolve().parents[1]
LIGHT_NAMES = {"light 1": "bench light 1", "light 2": "bench light 2"}
D610 = (6080, 4028)
LARGE_PIXELS = 50e6            # above this, the set is generated in bands and the half / LibRaw runs are left out
TARGETS = {"full_vs_decode": 2.0, "peak_rss_mb_150mp": 4096, "time_per_pixel_vs_24mp": 1.3}


def bench_estimator(lights: list) -> object:
    """The Wiener estimate of the bench lights (the model's sensitivities, the packaged training target): what a
    calibration with these lights would store."""
    from dualrgb.app.processing.spectral import model_sensitivities
    from dualrgb.simulation.datasets import default_setup
    from dualrgb.simulation.spectral_estimation import SpectralTraining, fit_wiener

    setup = default_setup("reflective")
    S = model_sensitivities("reflective", [nl.light for nl in lights])
    spectra = setup.train.spectra
    return fit_wiener(SpectralTraining(spectra @ S, spectra, setup.grid.wavelengths,
                                       ["R1", "G1", "B1", "R2", "G2", "B2"], S, np.full(6, 1e-6)))


def make_profile(folder: Path, spectral: bool = True) -> Path:
    """The calibration profile of the bench set (master darks, HDR whites, a plausible matrix and, with
    ``spectral``, a spectral estimator), cached."""
    sys.path.insert(0, str(ROOT))
    from dualrgb.app.processing.pipeline import CaptureProcessor, ExposureRef
    from dualrgb.app.workflow.calibration.profile import (
        CalibrationProfile,
        CameraIdentity,
        SphereIdentity,
        load_profile,
    )
    from dualrgb.core.vocabulary import NamedLight
    from dualrgb.simulation.lightsource import LightSource
    from dualrgb.simulation.matrix_fit import CharacterisationMatrix

    path = folder / "calibration" / ("cal-bench-spectral.json" if spectral else "cal-bench.json")
    if path.exists():
        return path
    plan = json.loads((folder / "plan.json").read_text())

    def ref(f: dict) -> ExposureRef:
        return ExposureRef(folder / f["file"], f["exposure_s"], f["file"])

    proc = CaptureProcessor(dark_frames=[ref(f) for f in plan["files"] if f["role"] == "dark"])
    for old, name in LIGHT_NAMES.items():
        proc.set_white(name, [ref(f) for f in plan["files"] if f["role"] == "flat" and f["light"] == old])
    lights = [NamedLight(n, LightSource((1, 6, 8) if i == 0 else (3, 5, 9), name=n)) for i, n in
              enumerate(LIGHT_NAMES.values())]
    exposures = {LIGHT_NAMES[f["light"]]: [] for f in plan["files"] if f["role"] == "scene"}
    for f in plan["files"]:
        if f["role"] == "scene":
            exposures[LIGHT_NAMES[f["light"]]].append(f["exposure_s"])
    white = next(iter(proc._whites.values())).white
    prof = CalibrationProfile(
        id=path.stem, created_at="2026-01-01T00:00:00+00:00", mode="reflective",
        camera=CameraIdentity("Nikon D610", "3000001", "", 50, 8.0), sphere=SphereIdentity("bench", "", "", 25.0),
        preset="bench", lights=lights, exposures=exposures, base_exposures={k: v[0] for k, v in exposures.items()},
        matrix=CharacterisationMatrix(np.vstack([np.eye(3) * 50, np.eye(3) * 50]),
                                      ["R1", "G1", "B1", "R2", "G2", "B2"]),
        statistics={"best": "least-squares", "methods": {"least-squares": {}}}, white_xyz=[95.047, 100.0, 108.883],
        raw={"white_level": proc.white_level, "black_level": proc.black_level, "cfa": proc.cfa,
             "linear_limit": proc.linear_limit, "shape": list(white.shape), "ppi_grid": "sensor"}, sources={},
        ppi=800.0, darks=proc.darks, whites=dict(proc._whites),
        estimator=bench_estimator(lights) if spectral else None)
    del proc
    prof.save(path.parent)
    load_profile(path)                                   # read back once: a damaged cache fails here, not in a run
    return path


def make_large_set(folder: Path, height: int, width: int, n_darks: int, band: int = 512) -> dict:
    """processing_bench.make_set's scene for a large sensor, each frame computed band by band (the whole-frame
    float arrays of make_set would need ~10 GB at 150 MP); the fixed-pattern dark is the same in every frame."""
    from bench.processing_bench import BLACK, LIGHTS, WHITE, _write_dng

    folder.mkdir(parents=True, exist_ok=True)
    plan_file = folder / "plan.json"
    key = {"height": height, "width": width, "n_darks": n_darks, "banded": True}
    if plan_file.exists():
        plan = json.loads(plan_file.read_text())
        if plan.get("key") == key and all((folder / f["file"]).exists() for f in plan["files"]):
            return plan
    xx = np.arange(width, dtype=np.float32)

    def frame(seed: int, t: float, radiance: float | None, scene: bool) -> np.ndarray:
        out = np.empty((height, width), np.uint16)
        noise = np.random.default_rng(seed)
        for r0 in range(0, height, band):
            yy = np.arange(r0, min(r0 + band, height), dtype=np.float32)[:, None]
            dark = BLACK + np.random.default_rng([7, r0]).uniform(0, 3, (len(yy), width)).astype(np.float32)
            x = dark + noise.normal(0, 2.0, dark.shape).astype(np.float32)
            if radiance is not None:
                r2 = ((xx - width / 2) / (width / 2)) ** 2 + ((yy - height / 2) / (height / 2)) ** 2
                img = radiance * (1 - 0.3 * r2)
                if scene:
                    img = img * (0.02 + 0.95 * (0.5 + 0.5 * np.sin(xx / 97.0) * np.cos(yy / 71.0)))
                x += img * np.float32(t)
            out[r0: r0 + len(yy)] = np.clip(x, 0, WHITE)
        return out

    files, seed = [], 0
    for t in sorted({t for ts in LIGHTS.values() for t in ts}):
        for i in range(n_darks):
            name = f"dark_{t:.6f}_{i:02d}.dng"
            _write_dng(folder / name, frame(seed := seed + 1, t, None, False), t)
            files.append({"file": name, "role": "dark", "exposure_s": t})
    for li, (light, ts) in enumerate(LIGHTS.items()):
        radiance = (WHITE - BLACK) * 0.6 / ts[0]
        for t in ts:
            for role in ("flat", "scene"):
                name = f"{role}_{li + 1}_{t:.6f}.dng"
                _write_dng(folder / name, frame(seed := seed + 1, t, radiance, role == "scene"), t)
                files.append({"file": name, "role": role, "exposure_s": t, "light": light})
    plan = {"key": key, "files": files}
    plan_file.write_text(json.dumps(plan, indent=1))
    return plan


def _scene_frames(folder: Path) -> list[tuple[str, Path, float]]:
    plan = json.loads((folder / "plan.json").read_text())
    return [(LIGHT_NAMES[f["light"]], folder / f["file"], f["exposure_s"])
            for f in plan["files"] if f["role"] == "scene"]


def _child_decode(folder: str) -> dict:
    import rawpy

    t0, c0 = time.perf_counter(), cpu_s()
    for _light, path, _t in _scene_frames(Path(folder)):
        with rawpy.imread(str(path)) as raw:
            raw.raw_image_visible.copy()
    return {"seconds": time.perf_counter() - t0, "cpu_s": cpu_s() - c0}


def _child_libraw(folder: str) -> dict:
    """LibRaw's own full-resolution linear path: LINEAR (bilinear) demosaic, linear 16-bit camera RGB."""
    import rawpy

    sys.path.insert(0, str(ROOT))
    from dualrgb.drivers.raw import LINEAR_POSTPROCESS

    t0, c0 = time.perf_counter(), cpu_s()
    for _light, path, _t in _scene_frames(Path(folder)):
        with rawpy.imread(str(path)) as raw:
            raw.postprocess(demosaic_algorithm=rawpy.DemosaicAlgorithm.LINEAR,
                            **{**LINEAR_POSTPROCESS, "output_color": rawpy.ColorSpace.raw})
    return {"seconds": time.perf_counter() - t0, "cpu_s": cpu_s() - c0}


def _ready(folder_p: Path, spectral: bool = True):
    from dualrgb.app.warm_kernels import warm_delivery, warm_processing
    from dualrgb.app.workflow.calibration.profile import load_profile

    prof = load_profile(make_profile(folder_p, spectral))
    warm_processing()
    warm_delivery((2,))                                # the full-resolution row kernels: 2 exposures per light
    import tifffile  # noqa: F401 - imported as a stand's process has it after its first original (~10 ms)
    return prof


def _without_sha256() -> None:
    """A diagnostic, not a product mode: the TIFF streams compute no digest (what the SHA-256 fixity costs)."""
    from dualrgb.app.processing import tiff_stream

    init = tiff_stream.TiffStream.__init__

    def no_digest(self, *args, **kwargs) -> None:
        init(self, *args, **{**kwargs, "digest": None})
    tiff_stream.TiffStream.__init__ = no_digest  # type: ignore[method-assign]


def _child_digitise(folder: str, resolution: str, streaming: bool = True, keep: str = "", sha256: bool = True,
                    model: str = "linear") -> dict:
    sys.path.insert(0, str(ROOT))
    if not sha256:
        _without_sha256()
    from bench.delivery_stages import with_model
    from dualrgb.app.processing.pipeline import ExposureRef
    from dualrgb.app.workflow.delivery import delivery
    from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, deliver
    from dualrgb.app.workflow.stand.copystand import begin_channels, profile_processor

    folder_p = Path(folder)
    t_load = time.perf_counter()
    prof = with_model(_ready(folder_p), model)
    t_ready = time.perf_counter()
    images = _timed_write_images(delivery)
    frames = _scene_frames(folder_p)
    builder = begin_channels(profile_processor(prof), [nl.name for nl in prof.lights], resolution)
    t0, c0 = time.perf_counter(), cpu_s()
    for i, (light, path, t) in enumerate(frames):
        if streaming and i == len(frames) - 1:
            t0, c0 = time.perf_counter(), cpu_s()        # the last frame lands: the clock starts
        builder.add(light, ExposureRef(path, t, path.name))
    t_added = time.perf_counter()
    out = Path(keep) if keep else Path(tempfile.mkdtemp(dir=folder))
    source = builder.result()
    d = deliver(source, prof, Original("BENCH-1", title="bench"), out, camera=prof.camera,
                dose=LightDoseRecord(1.0, 0.1), exposures={n: prof.exposures[n] for n in prof.exposures},
                render_illuminant="A")
    seconds, cpu = time.perf_counter() - t0, cpu_s() - c0
    source.close()
    sizes = {k: p.stat().st_size for k, p in d.files.items()}
    if not keep:
        import shutil

        shutil.rmtree(out, ignore_errors=True)
    return {"seconds": seconds, "cpu_s": cpu, "load_profile_and_warm_up_s": t_ready - t_load,
            "deliverables_bytes": sizes, "delivered_pixels": int(np.prod(source.shape)),
            "phases_s": {"frames_added": t_added - t0, "deliver": seconds - (t_added - t0),
                         "write_images": images["wall"], "write_images_cpu": images["cpu"],
                         "deliver_rest": seconds - (t_added - t0) - images["wall"]}}


def _timed_write_images(delivery) -> dict:
    """Wrap delivery.write_images to time it (wall and process CPU) in the measured run."""
    real, spent = delivery.write_images, {"wall": 0.0, "cpu": 0.0}

    def timed(*args, **kwargs):
        t, c = time.perf_counter(), cpu_s()
        try:
            return real(*args, **kwargs)
        finally:
            spent["wall"] += time.perf_counter() - t
            spent["cpu"] += cpu_s() - c
    delivery.write_images = timed
    return spent


def _child_cube(folder: str) -> dict:
    """``dualrgb cube`` on a full-resolution delivery (made untimed first), and how well the cube compresses."""
    import zlib

    sys.path.insert(0, str(ROOT))
    from dualrgb.app.workflow.delivery.spectral_on_demand import make_cube

    keep = Path(tempfile.mkdtemp(dir=folder))
    _child_digitise(folder, "full", True, str(keep))
    delivery = keep / "BENCH-1"
    t0, c0 = time.perf_counter(), cpu_s()
    made = make_cube(delivery, keep / "cube")
    seconds, cpu = time.perf_counter() - t0, cpu_s() - c0
    size = made.cube.stat().st_size
    sample = made.cube.read_bytes()[: 64 << 20]                          # 64 MB of it, zlib level 1 (deflate)
    tz = time.perf_counter()
    packed = len(zlib.compress(sample, 1))
    mb_s = len(sample) / 1e6 / (time.perf_counter() - tz)
    import shutil

    shutil.rmtree(keep, ignore_errors=True)
    return {"seconds": seconds, "cpu_s": cpu, "cube_bytes": size, "deflate_ratio": len(sample) / packed,
            "deflate_mb_s": mb_s}


def _child_models(folder: str) -> dict:
    """CPU seconds of the one-pass demosaic + colour encodings of a full-resolution original, single-threaded, with
    each delivered model (the bench profile's linear matrix, and root-polynomials of degree 2 and 3 whose linear
    rows are that matrix): the per-pixel cost of each model."""
    sys.path.insert(0, str(ROOT))
    from dualrgb.app.processing.demosaic import HALO
    from dualrgb.app.processing.encode import DeliveryEncoder
    from dualrgb.app.processing.pipeline import ExposureRef
    from dualrgb.app.workflow.stand.copystand import begin_channels, profile_processor
    from dualrgb.simulation.colour_models import n_terms

    prof = _ready(Path(folder))
    builder = begin_channels(profile_processor(prof), [nl.name for nl in prof.lights], "full")
    for light, path, t in _scene_frames(Path(folder)):
        builder.add(light, ExposureRef(path, t, path.name))
    stack = builder.result(threads=1)
    H, W = stack.shape
    mosaics = [stack.mosaic_band(r0, min(64, H - r0)).copy() for r0 in range(0, H, 64)]   # read once (streamed)
    cfa = stack.cfa_index
    stack.close()
    bands = [np.empty((64, W, 3), np.uint16) for _ in range(5)]
    out: dict = {}
    for name, degree in (("linear", 1), ("root-polynomial-2", 2), ("root-polynomial-3", 3)):
        A = np.zeros((n_terms(6, degree), 3))
        A[:6] = prof.matrix.matrix[:6] if prof.matrix.degree == 1 else 0.0
        A[6:] = 0.01 * A[:6].mean()                      # the cost does not depend on the values
        enc = DeliveryEncoder((H, W, 6), A, prof.white_xyz, ["ProPhoto RGB", "sRGB"], threads=1, degree=degree)
        spent = 0.0
        for r0, mosaic in zip(range(0, H, 64), mosaics, strict=True):
            rows = min(64, H - r0)
            c0 = cpu_s()
            enc.encode_mosaic(r0, bands[0][:rows], [b[:rows] for b in bands[1:3]], [b[:rows] for b in bands[3:5]],
                              mosaic=mosaic, p0=HALO, cfa=cfa)
            spent += cpu_s() - c0
        enc.close()
        out[name] = {"cpu_s": spent, "ns_per_pixel": 1e9 * spent / (H * W), "terms": int(A.shape[0])}
    for row in out.values():
        row["over_linear_ns_per_pixel"] = row["ns_per_pixel"] - out["linear"]["ns_per_pixel"]
    total = sum(r["cpu_s"] for r in out.values())
    return {"seconds": total, "cpu_s": total, "models_cpu": out, "delivered_pixels": H * W}


def _child_warm() -> dict:
    """Compile the kernels into numba's on-disk cache once, so no measured run pays (or counts the memory of)
    LLVM compiling them."""
    sys.path.insert(0, str(ROOT))
    from dualrgb.app.warm_kernels import warm_delivery, warm_processing

    warm_processing()
    warm_delivery((2,))
    return {}


def _run_child(kind: str, folder: Path) -> dict:
    if kind in ("decode", "libraw"):
        return run_in_child("bench.digitise_bench", f"_child_{kind}", str(folder))
    if kind == "cube_on_demand":
        return run_in_child("bench.digitise_bench", "_child_cube", str(folder))
    if kind == "full_stages":
        return run_in_child("bench.delivery_stages", "child_stages", str(folder))
    if kind == "models":
        return run_in_child("bench.digitise_bench", "_child_models", str(folder))
    resolution = "half" if kind == "half" else "full"
    return run_in_child("bench.digitise_bench", "_child_digitise", str(folder), resolution,
                        kind != "full_all_frames", "", kind != "full_without_sha256",
                        "root-polynomial-2" if kind == "full_rp2" else "linear")


def _storage_table() -> dict:
    from dualrgb.app.workflow.delivery.deliverables import storage

    sizes = {"24mp": D610, "150mp": (14204, 10652)}
    return {k: {r: storage(w, h, 2, 38, r) for r in ("full", "half")} for k, (w, h) in sizes.items()}


def _child_prepare(folder: str, height: int, width: int) -> dict:
    """The set and its calibration, in a child of their own: Linux keeps a process's peak RSS across fork and exec,
    so a parent that had built a 150 MP calibration (~6 GB) would hand its peak to every measured child."""
    from bench.processing_bench import make_set

    if height * width > LARGE_PIXELS:
        make_large_set(Path(folder), height, width, 2)
    else:
        make_set(Path(folder), height, width, 10)
    make_profile(Path(folder), True)
    return {}


def bench_digitise(height: int = D610[1], width: int = D610[0], cache: str | None = None, repeats: int = 3,
                   kinds: list[str] | None = None, quiet_below: float | None = None) -> dict:
    large = height * width > LARGE_PIXELS
    folder = Path(cache or Path(tempfile.gettempdir()) / f"dualrgb_bench_set_{width}x{height}")
    run_in_child("bench.digitise_bench", "_child_prepare", str(folder), height, width)
    run_in_child("bench.digitise_bench", "_child_warm")
    kinds = kinds or (["decode", "full"] if large else ["decode", "full", "full_rp2", "full_without_sha256", "half",
                                                       "libraw", "full_all_frames", "cube_on_demand", "full_stages",
                                                       "models"])
    runs: dict[str, list[dict]] = {k: [] for k in kinds}
    loads = [os.getloadavg()[0]]
    for _ in range(repeats):                      # interleaved, so load from other processes hits all alike
        for kind in kinds:
            before = _wait_quiet(quiet_below)
            run = _run_child(kind, folder)
            run["load_1min"] = [round(before, 2), round(os.getloadavg()[0], 2)]
            runs[kind].append(run)
            loads += run["load_1min"]
    return _summary(runs, width, height, repeats, loads)


def _wait_quiet(below: float | None, patience_s: float = 600.0) -> float:
    """The 1-minute load average, after waiting (at most ``patience_s``) for it to drop below ``below``."""
    end = time.monotonic() + patience_s
    while below is not None and os.getloadavg()[0] >= below and time.monotonic() < end:
        time.sleep(5.0)
    return os.getloadavg()[0]


def _summary(runs: dict[str, list[dict]], width: int, height: int, repeats: int, loads: list[float]) -> dict:
    best = {k: min(v, key=lambda r: r["seconds"]) for k, v in runs.items()}
    dec = best["decode"]["seconds"]
    out: dict = {"frame": f"{width}x{height}", "megapixels": round(width * height / 1e6, 1), "original_frames": 4,
                 "repeats": repeats, "decode_s": round(dec, 3), "cpu_decode_s": round(best["decode"]["cpu_s"], 3),
                 "decode_load_1min": best["decode"]["load_1min"],
                 "decode_runs_s": [round(x["seconds"], 3) for x in runs["decode"]]}
    for kind, r in best.items():
        if kind == "decode":
            continue
        entry = {"seconds": round(r["seconds"], 3), "vs_decode": round(r["seconds"] / dec, 2),
                 "cpu_s": round(r["cpu_s"], 3), "peak_rss_mb": round(max(x["peak_rss_mb"] for x in runs[kind])),
                 "load_1min": r["load_1min"], "runs_s": [round(x["seconds"], 3) for x in runs[kind]],
                 "runs_cpu_s": [round(x["cpu_s"], 3) for x in runs[kind]]}
        if "models_cpu" in r:
            entry["models_cpu"] = {k: {m: round(v, 3) for m, v in row.items()} for k, row in r["models_cpu"].items()}
        for extra in ("deliverables_bytes", "phases_s", "cube_bytes", "deflate_ratio", "deflate_mb_s", "stages_cpu_s"):
            if extra in r:
                entry[extra] = ({k: round(v, 3) for k, v in r[extra].items()} if extra in ("phases_s", "stages_cpu_s")
                                else round(r[extra], 2) if isinstance(r[extra], float) else r[extra])
        if "delivered_pixels" in r:
            entry["ns_per_sensor_pixel"] = round(1e9 * r["seconds"] / (width * height), 2)
            entry["delivered_pixels"] = r["delivered_pixels"]
        out[kind] = entry
    if "full_stages" in best:
        from bench.delivery_stages import floor_summary

        stages = best["full_stages"]["stages_cpu_s"]
        for kind, key, model in (("full", "delivery", "linear"),
                                 ("full_rp2", "delivery_root_polynomial_2", "root-polynomial-2")):
            if kind in out:
                out[key] = floor_summary(best["decode"], stages, out[kind], model)
    full = best.get("full", {})
    out.update({"peak_rss_mb": out.get("full", {}).get("peak_rss_mb"),
                "load_profile_and_warm_up_s": round(full.get("load_profile_and_warm_up_s", 0.0), 2),
                "storage_bytes": _storage_table(), "load_average_1min": [round(v, 2) for v in loads],
                "cpus": os.cpu_count(), "targets": TARGETS})
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--size", default=f"{D610[0]}x{D610[1]}", help="sensor WIDTHxHEIGHT (default the D610's)")
    p.add_argument("--small", action="store_true", help="a 1/16-size set (1520 x 1008) for a quick check")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--cache", help="folder for the generated DNGs and the profile")
    p.add_argument("--json", help="where to write the result (default bench/results/digitise.json)")
    p.add_argument("--kinds", help="comma-separated runs (default: all for the size; decode and full are needed)")
    p.add_argument("--quiet-below", type=float, help="before each run, wait (up to 10 min) for the 1-minute load "
                   "average to drop below this")
    a = p.parse_args(argv)
    w, h = (1520, 1008) if a.small else (int(v) for v in a.size.lower().split("x"))
    res = bench_digitise(h, w, a.cache, a.repeats, a.kinds.split(",") if a.kinds else None, a.quiet_below)
    print(json.dumps(res, indent=2))
    print("\n".join(summary_lines(res)))
    dest = Path(a.json) if a.json else ROOT / "bench" / "results" / "digitise.json"
    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_text(json.dumps(res, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

_ = resource  # used in the child processes' code string
