"""``dualrgb demo``: the whole capture + processing workflow on the virtual lab, headless."""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

from dualrgb.app.commands.options import add_chart_options, add_world_option, chart_choices, count, frame_size, seed
from dualrgb.app.terminal_progress import TerminalProgress
from dualrgb.app.workflow.stand.defaults import DARK_FRAMES, DEFAULT_MODE, MODES, VIRTUAL_FRAME_SIZE

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="run the whole workflow headless on the virtual lab",
                       description="Presets, darks, flats, train/test captures, processing and report on the "
                                   "virtual lab (sphere emulator on a pty + virtual camera).")
    p.add_argument("--out", type=Path, required=True, help="output folder (session, presets, report.json)")
    p.add_argument("--mode", choices=MODES, default=DEFAULT_MODE)
    p.add_argument("--hdr", action="store_true", help="add the ND 2.0-filtered scene with HDR brackets")
    p.add_argument("--frame-size", type=frame_size, default=VIRTUAL_FRAME_SIZE,
                   help="virtual frame WxH, 64..8192 per side (default {}x{})".format(*VIRTUAL_FRAME_SIZE))
    p.add_argument("--seed", type=seed, default=0)
    add_world_option(p)
    p.add_argument("--dark-frames", type=count(1, 200), default=None,
                   help=f"dark frames per exposure (default {DARK_FRAMES})")
    p.add_argument("--new-session", action="store_true",
                   help="when --out holds a session made with other options, start a new one beside it "
                        "(default: refuse, naming the difference)")
    p.add_argument("--no-de-fit", action="store_true",
                   help="leave the ΔE00-optimised matrix out (default: every model the processing delivers - least "
                        "squares, ΔE00-optimised, root-polynomial 2 and 3 - cross-validation choosing)")
    add_chart_options(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from dualrgb.app.demo import DemoSettings, run_demo  # heavy imports only when the demo runs
    from dualrgb.app.warm_kernels import ensure_ready
    from dualrgb.app.workflow.calibration.charts import load_charts

    settings = DemoSettings(out=args.out, mode=args.mode, hdr=args.hdr, frame_size=args.frame_size,
                            seed=args.seed, world=args.world, new_session=args.new_session,
                            optimise_matrix=False if args.no_de_fit else None,
                            charts=load_charts(chart_choices(args), args.mode))
    if args.dark_frames is not None:
        settings.dark_frames = args.dark_frames
    ensure_ready()                                      # first run: compiled once here, said in one line
    with TerminalProgress("demo", lines=True) as progress:
        data = run_demo(settings, progress)
    print(f"{'condition':<22} {'train mean':>10} {'test mean':>10} {'sim train':>10} {'sim test':>10} "
          f"{'nf train':>9} {'nf test':>8}")
    for name in data["conditions"]:
        c = data[name]
        sim = {} if "nd_patches" in c else c["simulated"]       # predictions are for the plain (no ND) scene
        pred = " ".join(f"{sim[k]:>{w}.3f}" if k in sim else f"{'-':>{w}}"
                        for k, w in (("train", 10), ("test", 10), ("noise_free_train", 9), ("noise_free_test", 8)))
        print(f"{name:<22} {c['train']['mean']:>10.3f} {c['test']['mean']:>10.3f} {pred}")
    print("sim: the expected captured error the optimiser predicted (for the delivered matrix); nf: noise-free")
    o = data.get("original")
    if o:
        sp = o.get("spectral") or {}
        print(f"original {o['original']} ({o['condition']} lights, per pixel against its truth): dE00 mean "
              f"{o['xyz']['mean']:.3f} / p90 {o['xyz']['p90']:.3f}"
              + (f", spectral RMSE mean {sp['rmse_mean']:.4f} / p90 {sp['rmse_p90']:.4f}" if sp else ""))
    print(f"frames {data['frames']}, lost {data['lost_frames']}, light dose {data['light_dose']['lux_s']:.0f} lux.s, "
          f"{data['elapsed_s']:.1f} s -> {args.out / 'report.json'}")
    return 0
