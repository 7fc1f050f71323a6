"""What ``dualrgb calibrate`` prints when it is done: by default the few lines a technician acts on (the test
chart's mean dE00, the grades, what to run next); with ``-v`` the whole description ``dualrgb calibration show``
prints (the models' table, the spectral figures, the stand model's statistics).

    say_calibrated(args, profile, out)
"""
from __future__ import annotations

import argparse
import shlex
import sys
from typing import Any, TextIO

from dualrgb.app.workflow.stand.defaults import VIRTUAL_FRAME_SIZE


def summary_lines(profile: Any) -> list[str]:
    """The calibration's accuracy and grade in two lines, the failed criteria named."""
    stats = profile.statistics
    best = (stats.get("methods") or {}).get(stats.get("best", ""), {})
    test, train = (best.get("test") or {}).get("mean"), (best.get("train") or {}).get("mean")
    accuracy = f"test chart mean dE00 {test:.2f}" if isinstance(test, float | int) else "test chart dE00 not measured"
    if isinstance(train, float | int):
        accuracy += f" (training chart {train:.2f})"
    pixel = (stats.get("per_pixel_de00") or {}).get("test") or {}        # issue 40: beside every patch mean
    if isinstance(pixel.get("mean"), float | int) and isinstance(pixel.get("p90"), float | int):
        accuracy += f", per pixel test {pixel['mean']:.2f} / p90 {pixel['p90']:.2f}"
    lines = [f"calibration {profile.id}: {accuracy}, {profile.matrix.method} matrix"]
    grading = (stats.get("quality") or {}).get("grading") or {}
    if not grading:
        return [*lines, "grade: not recorded in this calibration"]
    verdicts = []
    for std, g in grading.items():
        failed = [m for m, s in g.get("metrics", {}).items() if s == "fail"]
        verdicts.append(f"{std} {str(g.get('verdict', '?')).split(' ')[0]}"
                        + (f" ({', '.join(failed)})" if failed else ""))
    scope = next(iter(grading.values())).get("scope", "")
    return [*lines, f"grade: {', '.join(verdicts)}" + (f" ({scope})" if scope else "")]


def devices_text(args: argparse.Namespace) -> str:
    """The device options a capture needs to match this calibration, as typed."""
    if getattr(args, "virtual_lab", False):
        size = tuple(args.frame_size)
        extra = f" --frame-size {size[0]}x{size[1]}" if size != tuple(VIRTUAL_FRAME_SIZE) else ""
        return "--virtual-lab" + extra + (f" --world {args.world}" if args.world != "nominal" else "")
    return f"--port {shlex.quote(args.port)} --camera {shlex.quote(args.camera)}"


def next_lines(args: argparse.Namespace, profile: Any) -> list[str]:
    """What to run next: capture with this calibration, and where the statistics are."""
    session = args.session if args.session is not None else profile.path.parent.parent
    where = shlex.quote(str(session))
    failed = any(g.get("failed") for g in ((profile.statistics.get("quality") or {}).get("grading") or {}).values())
    lines = ["next: the grade fails a criterion: check the charts' placement and lighting, then calibrate again"
             if failed else f"next: dualrgb capture --session {where} --id IDENTIFIER {devices_text(args)}"]
    lines.append(f"details: dualrgb calibration show {where} (the models, spectra and stand model; -v here)")
    return lines


def say_calibrated(args: argparse.Namespace, profile: Any, out: TextIO) -> None:
    """The lines ``calibrate`` ends with (see the module docstring)."""
    from dualrgb.app.processing.quality import grading_lines
    from dualrgb.app.workflow.calibration.profile import describe

    if args.verbose:
        for line in describe(profile):
            print(line, file=out)
        for line in grading_lines(profile.statistics.get("quality")):
            print(f"grade {line}", file=out)
    else:
        for line in summary_lines(profile) + next_lines(args, profile):
            print(line, file=out)
    print(f"calibration: {profile.path}", file=out)
    print(f"dualrgb: calibration {profile.id} written", file=sys.stderr)
