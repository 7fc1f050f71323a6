"""Where a full-resolution delivery's time goes (issue 41): each stage's single-threaded CPU cost, the two-core
floor they give, and the measured delivery against it (bench/digitise_bench.py runs these, ``make bench`` prints
them).

Stages, each measured alone in one thread on the bench's original (CPU seconds, robust on a shared machine):

  decode_last_frame      LibRaw's decode of the frame that starts the clock (held as decoded)
  merge_flat             dark subtraction, HDR merge and flat field of every band of both lights
                         (MasterStack.mosaic_band_into)
  demosaic               Malvar-He-Cutler of every row of both lights into channel planes (the fused kernel's
                         first half, alone)
  colour_encodings       camera RGB x 2, XYZ, sRGB, ProPhoto from the planes, with the calibration's model: the
                         fused one-pass kernel (DeliveryEncoder.encode_mosaic) minus the demosaic alone
  tiff_writing           the five TIFFs' headers, ICC, XMP and strips, their buffers, every band written with
                         O_DIRECT, fsync and rename (nothing hashed)
  sha256                 SHA-256 of as many bytes as the five TIFFs hold, in the writes' pieces
  sidecar_and_folder     deliver() without its images: settings, metadata, the sidecar (JSON) and the folder swap

The floor on two cores: the last frame's decode (one thread, nothing to overlap it with) + the sum of the other
stages / 2 (both cores busy the whole time, nothing lost to hand-overs), written in five groups (``GROUPS``:
decode, pixel_work, encode, hashing, io). The gap: the measured delivery minus that floor; the overhead: its CPU
time minus the stages' sum; ``cpu_projection``: its CPU time laid on two idle cores (what a loaded machine's wall
time cannot show).
"""
from __future__ import annotations

import hashlib
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from bench.child import cpu_s

ROOT = Path(__file__).resolve().parents[1]
MODELS = {"linear": "least squares (linear: the bench calibration's matrix)",
          "root-polynomial-2": "root-polynomial degree 2 (21 terms: what the virtual lab's default dual-RGB "
                               "calibration delivers, docs/data/demo-reflective-hdr.json)"}
TARGETS = {"vs_decode": 2.0, "cpu_vs_stage_sum": 1.25}


def with_model(prof, model: str):
    """``prof`` delivering ``model``: its own linear matrix, or a root-polynomial of degree 2 whose linear rows are
    that matrix (the cost does not depend on the other terms' values)."""
    if model == "linear":
        return prof
    from dualrgb.simulation.colour_models import n_terms
    from dualrgb.simulation.matrix_fit import CharacterisationMatrix

    degree = int(model.rsplit("-", 1)[1])
    A = np.zeros((n_terms(6, degree), 3))
    A[:6] = prof.matrix.matrix
    A[6:] = np.linspace(-0.5, 0.5, 3 * (len(A) - 6)).reshape(-1, 3)
    prof.matrix = CharacterisationMatrix(A, list(prof.matrix.channels), model, degree)
    return prof


def _demosaic_only():
    """A numba loop running the fused kernel's demosaic alone (compiled here, warmed before any clock)."""
    from numba import njit

    from dualrgb.app.processing.demosaic import mhc_planes, row_colours

    @njit(nogil=True)
    def planes(P, p0, y0, cfa, rows, S):  # pragma: no cover - compiled
        for r in range(rows):
            even_green, here = row_colours(cfa, y0 + r)
            for li in range(P.shape[0]):
                mhc_planes(P[li], p0 + r, even_green, here, S[3 * li: 3 * li + 3])
    return planes


def child_stages(folder: str) -> dict:
    """The stages' single-threaded CPU seconds (both models' colour encodings), in a fresh process."""
    sys.path.insert(0, str(ROOT))
    from bench.digitise_bench import _ready, _scene_frames
    from dualrgb.app.processing.pipeline import ExposureRef
    from dualrgb.app.workflow.stand.copystand import begin_channels, profile_processor

    prof = _ready(Path(folder))
    frames = _scene_frames(Path(folder))
    builder = begin_channels(profile_processor(prof), [nl.name for nl in prof.lights], "full")
    for light, path, t in frames[:-1]:
        builder.add(light, ExposureRef(path, t, path.name))
    c0 = cpu_s()
    builder.add(frames[-1][0], ExposureRef(frames[-1][1], frames[-1][2], frames[-1][1].name))
    out: dict = {"decode_last_frame": cpu_s() - c0}
    with builder.result(threads=1) as stack:
        out.update(_pixel_stages(prof, stack))
    H, W = stack.shape
    nbytes = 5 * H * W * 3 * 2
    out["tiff_writing"] = _tiff_writing(Path(folder), H, W)
    out["sha256"] = _sha256(nbytes, 64 * W * 3 * 2)
    out["sidecar_and_folder"] = _sidecar(Path(folder), prof, stack)
    return {"seconds": 0.0, "cpu_s": 0.0, "stages_cpu_s": out, "tiff_bytes": nbytes}


def _pixel_stages(prof, stack) -> dict:
    """merge_flat, demosaic and each model's colour encodings over every 64-row band, in this thread."""
    from dualrgb.app.processing.demosaic import HALO
    from dualrgb.app.processing.encode import DeliveryEncoder

    H, W = stack.shape
    planes = _demosaic_only()
    S = np.empty((6, W), np.float32)
    planes(np.zeros((2, 5, 9), np.float32), 2, 0, stack.cfa_index, 1, np.empty((6, 5), np.float32))   # compile
    matrices = {m: with_model(_copy(prof), m).matrix for m in MODELS}
    encoders = {m: DeliveryEncoder((H, W, 6), cm.matrix, prof.white_xyz, ["ProPhoto RGB", "sRGB"], threads=1,
                                   degree=cm.degree) for m, cm in matrices.items()}
    bands = [np.empty((64, W, 3), np.uint16) for _ in range(5)]
    spent = dict.fromkeys(["merge_flat", "demosaic", *MODELS], 0.0)
    scratch: dict = {}
    for r0 in range(0, H, 64):
        rows = min(64, H - r0)
        c0 = cpu_s()
        mosaic = stack.mosaic_band_into(r0, rows, scratch)
        c1 = cpu_s()
        planes(mosaic, HALO, r0, stack.cfa_index, rows, S)
        spent["merge_flat"] += c1 - c0
        spent["demosaic"] += cpu_s() - c1
        for m, enc in encoders.items():
            c0 = cpu_s()
            enc.encode_mosaic(r0, bands[0][:rows], [b[:rows] for b in bands[1:3]], [b[:rows] for b in bands[3:5]],
                              mosaic=mosaic, p0=HALO, cfa=stack.cfa_index, in_thread=True)
            spent[m] += cpu_s() - c0
    for enc in encoders.values():
        enc.close()
    out = {"merge_flat": spent["merge_flat"], "demosaic": spent["demosaic"]}
    out.update({f"colour_encodings_{m}": spent[m] - spent["demosaic"] for m in MODELS})
    return out


def _copy(prof):
    import copy

    return copy.copy(prof)


def _tiff_writing(folder: Path, H: int, W: int) -> float:
    """CPU seconds of five TIFFs of the delivery's size and tags written band by band (O_DIRECT), unhashed."""
    from dualrgb.app.processing.outputs import TiffMetadata, icc_profile, open_tiff

    meta = TiffMetadata("dualrgb bench", "BENCH-1; bench", "Nikon", "D610", 800.0, "2026:01:01 00:00:00",
                        b"<x:xmpmeta/>" * 400)
    out = Path(tempfile.mkdtemp(dir=folder))
    c0 = cpu_s()
    streams = [open_tiff(out / f"{i}.tif", (H, W, 3), meta, photometric="rgb", icc=icc_profile("sRGB"),
                         band_rows=64) for i in range(5)]
    for r0 in range(0, H, 64):
        for s in streams:
            s.band(min(64, H - r0))
            s.commit()
    for s in streams:
        s.close()
    spent = cpu_s() - c0
    shutil.rmtree(out, ignore_errors=True)
    return spent


def _sha256(nbytes: int, piece: int) -> float:
    """CPU seconds of SHA-256 over ``nbytes`` in ``piece``-byte updates (five files' worth, as written)."""
    data = np.random.default_rng(0).integers(0, 256, piece, dtype=np.uint8)
    view = memoryview(data)
    c0 = cpu_s()
    for _file in range(5):
        h = hashlib.sha256()
        for _ in range(nbytes // 5 // piece):
            h.update(view)
        h.update(view[: nbytes // 5 % piece])
        h.hexdigest()
    return cpu_s() - c0


def _sidecar(folder: Path, prof, stack) -> float:
    """CPU seconds of deliver() with its images made empty: settings, metadata, sidecar, folder swap."""
    from dualrgb.app.workflow.delivery import delivery
    from dualrgb.app.workflow.delivery.delivery import LightDoseRecord, Original, Written, deliver

    def no_images(source, profile, images, ctx, **kwargs):
        files = {}
        for k, im in images.items():
            if im.streamed:
                im.path.write_bytes(b"")
                files[k] = im.path
        return Written(files, {k: {"bytes": 0, "sha256": "0" * 64} for k in files}, 0.0)
    real, delivery.write_images = delivery.write_images, no_images
    out = Path(tempfile.mkdtemp(dir=folder))
    try:
        c0 = cpu_s()
        deliver(stack, prof, Original("BENCH-1", title="bench"), out, camera=prof.camera,
                dose=LightDoseRecord(1.0, 0.1), exposures={n: prof.exposures[n] for n in prof.exposures},
                render_illuminant="A")
        return cpu_s() - c0
    finally:
        delivery.write_images = real
        shutil.rmtree(out, ignore_errors=True)


GROUPS = {"decode": ("decode_last_frame",), "pixel_work": ("merge_flat", "demosaic"),
          "encode": ("colour_encodings",), "hashing": ("sha256",), "io": ("tiff_writing", "sidecar_and_folder")}
FLOOR = "decode + (pixel_work + encode + hashing + io) / 2"


def floor_summary(decode: dict, stages: dict, full: dict, model: str) -> dict:
    """The stage split for ``model`` (each stage and the five groups the floor is written in), the two-core floor,
    and the measured delivery (``full``: the bench's best run: seconds, cpu_s) against it and against the decode
    (``decode``: the bare decode of the 4 frames: seconds, cpu_s). ``cpu_projection``: the delivery's measured CPU
    time laid on two cores with nothing lost (the last frame's decode alone, the rest halved): what the wall time
    would be on a quiet machine if the overlap were perfect, the figure to judge by when the load inflates the wall."""
    split = {k: round(v, 3) for k, v in stages.items() if not k.startswith("colour_encodings_")}
    split["colour_encodings"] = round(stages[f"colour_encodings_{model}"], 3)
    groups = {g: round(sum(split[k] for k in keys), 3) for g, keys in GROUPS.items()}
    total = sum(split.values())
    last = split["decode_last_frame"]
    floor = last + (total - last) / 2
    dec, dec_cpu = decode["seconds"], decode["cpu_s"]
    two_core = last + (full["cpu_s"] - last) / 2
    return {"model": MODELS[model], "stages_cpu_s": split, "groups_cpu_s": groups, "floor_formula": FLOOR,
            "stage_sum_cpu_s": round(total, 3), "floor_s": round(floor, 3), "floor_vs_decode": round(floor / dec, 3),
            "floor_vs_decode_cpu": round(floor / dec_cpu, 3),
            "measured_s": full["seconds"], "measured_vs_decode": round(full["seconds"] / dec, 3),
            "gap_s": round(full["seconds"] - floor, 3), "cpu_s": full["cpu_s"],
            "cpu_vs_decode_cpu": round(full["cpu_s"] / dec_cpu, 3),
            "cpu_vs_stage_sum": round(full["cpu_s"] / total, 3), "overhead_cpu_s": round(full["cpu_s"] - total, 3),
            "cpu_projection": {"two_core_s": round(two_core, 3), "vs_decode_cpu": round(two_core / dec_cpu, 3),
                               "vs_decode": round(two_core / dec, 3)},
            "load_1min": full["load_1min"], "targets": TARGETS,
            "met": {"vs_decode": full["seconds"] / dec <= TARGETS["vs_decode"],
                    "cpu_vs_stage_sum": full["cpu_s"] / total <= TARGETS["cpu_vs_stage_sum"]}}


def summary_lines(result: dict) -> list[str]:
    """The stage split, floor and overhead of a digitise result, as lines for the terminal."""
    lines = []
    for key in ("delivery", "delivery_root_polynomial_2"):
        d = result.get(key)
        if not d:
            continue
        split = ", ".join(f"{k} {v:.3f}" for k, v in d["stages_cpu_s"].items())
        groups = ", ".join(f"{k} {v:.3f}" for k, v in d["groups_cpu_s"].items())
        proj = d["cpu_projection"]
        lines += [f"{result['frame']} delivery, {d['model']}:",
                  f"  stages (CPU-s, one thread): {split}; sum {d['stage_sum_cpu_s']:.3f}",
                  f"  grouped: {groups}",
                  f"  two-core floor {d['floor_formula']} = {d['floor_s']:.3f} s = {d['floor_vs_decode']:.2f}x "
                  f"the decode ({result['decode_s']:.3f} s); measured {d['measured_s']:.3f} s = "
                  f"{d['measured_vs_decode']:.2f}x (target {d['targets']['vs_decode']}x), gap {d['gap_s']:.3f} s",
                  f"  CPU {d['cpu_s']:.3f} s = {d['cpu_vs_stage_sum']:.2f}x the stages' sum (target "
                  f"{d['targets']['cpu_vs_stage_sum']}x), overhead {d['overhead_cpu_s']:.3f} CPU-s; on two idle "
                  f"cores {proj['two_core_s']:.3f} s = {proj['vs_decode_cpu']:.2f}x the decode's CPU "
                  f"({result['cpu_decode_s']:.3f} s)",
                  f"  1-minute load during the runs: {min(result['load_average_1min']):.2f}-"
                  f"{max(result['load_average_1min']):.2f} ({os.cpu_count()} cores)"]
    return lines
