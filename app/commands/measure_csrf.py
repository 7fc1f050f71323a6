"""``dualrgb measure csrf``: the camera's spectral sensitivity with a monochromator (thesis 4.2) -> a camera CSV.

    dualrgb measure csrf --virtual-lab --start 380 --end 780 --step 10 --out d610_csrf.csv
    dualrgb measure csrf --monochromator /dev/ttyUSB0 --camera auto --radiance tsr.csv --out d610_csrf.csv
    dualrgb measure csrf --manual --camera auto --photodiode resp.csv --photocurrent current.csv --out d610.csv

The sweep runs in a session folder (``--session``, default ``<out>-session`` beside the CSV): crash-safe and
resumable with the same options. On the virtual lab (``--world``: the camera it renders with is the world's; the
world is part of the session's definition) without ``--radiance`` the virtual spectroradiometer measures the
monochromator's output after the sweep (``<session>/radiance-virtual.csv``), and the result is compared with the
curves the virtual camera renders with.
"""
from __future__ import annotations

import argparse
import contextlib
import logging
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dualrgb.app.commands.options import add_world_option, count, frame_size, input_file, number, seconds, seed
from dualrgb.app.commands.stand_options import ask_person, real_camera
from dualrgb.app.json_output import add_json_option, text_stream, write_json

if TYPE_CHECKING:                       # types only: the devices are imported when the command runs (fast --help)
    from dualrgb.app.protocols import Monochromator
    from dualrgb.app.sequences.base import ProgressEvent
    from dualrgb.app.workflow.csrf import CsrfMeasurement
    from dualrgb.drivers.camera.base import Camera
    from dualrgb.simulation.radiance_reference import RadianceReference

log = logging.getLogger(__name__)

FORMAT = "dualrgb-csrf/1"
RADIANCE_METHODS = ("integral", "peak")    # simulation.radiance_reference.REDUCTION_METHODS (a test keeps them in step)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("csrf", help="the camera's spectral sensitivity with a monochromator -> camera CSV",
                       description="Sweep a monochromator over a wavelength range, a metered exposure per "
                                   "wavelength (shutter open only while a frame is exposed), darks at every exposure "
                                   "used, then CSRF = signal / exposure / radiance (thesis 4.2, eq 4.1), normalised "
                                   "to the green maximum, written as a camera CSV for `simulate --camera-csv`.")
    dev = p.add_mutually_exclusive_group(required=True)
    dev.add_argument("--virtual-lab", action="store_true", help="the virtual lab's monochromator bench")
    dev.add_argument("--monochromator", metavar="PORT", help="a Cornerstone 130/260 on this serial port")
    dev.add_argument("--manual", action="store_true", help="a monochromator set by hand (you are asked each time)")
    p.add_argument("--camera", help="the camera as 'MODEL @ PORT' (from `dualrgb devices`) or 'auto'")
    p.add_argument("--start", type=number(100, 2500, unit=" nm"), default=380.0, help="first wavelength (380 nm)")
    p.add_argument("--end", type=number(100, 2500, unit=" nm"), default=780.0, help="last wavelength (780 nm)")
    p.add_argument("--step", type=number(above=0.0, unit=" nm"), default=10.0, help="step (10 nm)")
    p.add_argument("--out", type=Path, required=True, help="the camera CSV to write")
    p.add_argument("--session", type=Path, help="session folder (default: <out>-session beside it)")
    r = p.add_argument_group("radiance reference (docs: how-to/measure-stand, the accepted files)")
    r.add_argument("--radiance", type=input_file, help="spectroradiometer readings (CSV or CGATS) or a radiance table")
    r.add_argument("--photodiode", type=input_file, metavar="RESPONSIVITY", help="photodiode responsivity CSV (A/W)")
    r.add_argument("--photocurrent", type=input_file, help="photocurrents at each wavelength CSV (A)")
    r.add_argument("--radiance-method", choices=RADIANCE_METHODS, default="integral",
                   help="a reading per wavelength: its band integral (default) or peak (thesis eq 4.1)")
    r.add_argument("--window", type=number(1.0, 200.0, unit=" nm"), default=20.0,
                   help="+- nm around each wavelength the readings are reduced over (20)")
    s = p.add_argument_group("sweep")
    s.add_argument("--frames", type=count(1, 50), default=2, help="frames per wavelength (2)")
    s.add_argument("--dark-frames", type=count(1, 200), default=5, help="darks per exposure used (5)")
    s.add_argument("--target", type=number(0.05, 0.9), default=0.6,
                   help="brightest channel's level, fraction of the linear limit (0.6)")
    s.add_argument("--max-exposure", type=seconds(0.001, 3600), default=30.0, help="longest exposure (30 s)")
    s.add_argument("--region", type=number(0.02, 1.0), default=0.3, help="central fraction of each side (0.3)")
    s.add_argument("--timeout", type=seconds(0.05, 60), default=2.0, help="monochromator reply timeout (2 s)")
    v = p.add_argument_group("devices")
    v.add_argument("--frame-size", type=frame_size, default=(240, 160), help="virtual lab frames WxH (240x160)")
    v.add_argument("--seed", type=seed, default=0, help="virtual lab noise seed")
    add_world_option(v)          # the camera the bench renders with is the world's (another camera: a world file)
    v.add_argument("--iso", type=count(25, 409600), help="set the camera's ISO first")
    v.add_argument("--aperture", type=number(0.5, 128), help="set the camera's f-number first")
    add_json_option(p)
    p.set_defaults(func=main)


def _check_options(args: argparse.Namespace) -> None:
    if bool(args.photodiode) != bool(args.photocurrent):
        raise ValueError("--photodiode and --photocurrent go together (the responsivity and the photocurrents)")
    if args.radiance and args.photodiode:
        raise ValueError("give one radiance reference: --radiance, or --photodiode with --photocurrent")
    if args.virtual_lab:
        if args.camera:
            raise ValueError("--camera is for a real camera; --virtual-lab has its own")
    else:
        if args.world != "nominal":
            raise ValueError(f"--world {args.world}: a world is what the virtual lab renders; use it with "
                             "--virtual-lab")
        if not args.camera:
            raise ValueError("name the camera: --camera 'MODEL @ PORT' or --camera auto (`dualrgb devices`)")
        if not (args.radiance or args.photodiode):
            raise ValueError("a real measurement needs the monochromator's radiance: --radiance FILE, or "
                             "--photodiode RESPONSIVITY --photocurrent FILE (docs: how-to/measure-stand, the "
                             "accepted files)")


def _reference(args: argparse.Namespace) -> RadianceReference:
    from dualrgb.simulation.radiance_reference import read_photodiode_reference, read_radiance_reference

    if args.photodiode:
        return read_photodiode_reference(args.photodiode, args.photocurrent)
    return read_radiance_reference(args.radiance, method=args.radiance_method, window_nm=args.window)


@contextlib.contextmanager
def _devices(args: argparse.Namespace) -> Iterator[tuple[Camera, Monochromator]]:
    """(camera, monochromator) of a real bench (app.workflow.csrf_bench.bench_devices); the shutter closed and
    ports closed on the way out."""
    from dualrgb.app.workflow.csrf_bench import CORNERSTONE, MANUAL, CsrfBench, bench_devices

    bench = CsrfBench(MANUAL if args.manual else CORNERSTONE, port=args.monochromator or "", timeout_s=args.timeout)
    with contextlib.ExitStack() as stack:
        camera = stack.enter_context(real_camera(args))
        yield stack.enter_context(bench_devices(bench, camera))


def _measure(args: argparse.Namespace, settings: Any, reference: RadianceReference | None) -> Any:
    """The measurement on the virtual lab's bench (app.lab.csrf_bench: the virtual camera set to --iso /
    --aperture) or on the real one."""
    from dualrgb.simulation.radiance_reference import read_radiance_reference

    def read(p: Path) -> RadianceReference:
        return read_radiance_reference(p, method=args.radiance_method, window_nm=args.window)
    if args.virtual_lab:
        from dualrgb.app.lab.csrf_bench import VirtualBench, measure_on_virtual_bench, virtual_bench
        from dualrgb.drivers.camera.base import CameraSettings

        with virtual_bench(VirtualBench(args.world, args.frame_size, args.seed, args.timeout)) as bench:
            if bench.camera is not None and (args.iso or args.aperture):
                bench.camera.apply(CameraSettings(iso=args.iso, aperture=args.aperture))
            return measure_on_virtual_bench(bench, settings, args.out, args.session, reference=reference,
                                            read_radiance=read, prompt=ask_person, on_event=_printer)
    from dualrgb.app.workflow.csrf_bench import measure_on_bench

    with _devices(args) as (camera, mono):
        return measure_on_bench(camera, mono, settings, args.out, args.session, radiance=reference,
                                prompt=ask_person, on_event=_printer)


def _printer(event: ProgressEvent) -> None:
    print(f"[{event.step:3d}/{event.total}] {event.message}", file=sys.stderr, flush=True)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.sequences.csrf import CsrfSettings

    _check_options(args)
    settings = CsrfSettings(args.start, args.end, args.step, frames=args.frames, dark_frames=args.dark_frames,
                            target_fraction=args.target, max_exposure_s=args.max_exposure, region=args.region)
    reference = _reference(args) if (args.radiance or args.photodiode) else None     # bad files before any device
    outcome = _measure(args, settings, reference)
    if outcome.radiance_file is not None:
        print(f"virtual spectroradiometer: {outcome.radiance_file}", file=sys.stderr)
    if outcome.measurement is None:
        print("dualrgb: measurement cancelled; the shutter is closed", file=sys.stderr)
        return 1
    _report(args, outcome.measurement, outcome.rms_percent)
    return 0


def _report(args: argparse.Namespace, m: CsrfMeasurement, rms: dict[str, float] | None) -> None:
    exposures = sorted(set(m.exposures.values()))
    out = text_stream(args.json)                   # `--json -`: stdout carries the JSON alone
    print(f"camera CSV: {m.path} ({len(m.result.wavelengths)} wavelengths, exposures {exposures[0]:g}-"
          f"{exposures[-1]:g} s, session {m.session})", file=out)
    if rms is not None:
        print("virtual lab: RMS error against the rendering camera, % of each channel's peak: "
              + ", ".join(f"{c} {v:.2f}" for c, v in rms.items()), file=out)
    if args.json:
        write_json(args.json, FORMAT, {"camera_csv": str(m.path), "session": str(m.session),
                                       "instrument": m.instrument, "result": m.result.to_dict(),
                                       "rms_percent_of_peak": rms})
