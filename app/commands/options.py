"""The argparse ``type=`` validators every ``dualrgb`` command uses: each option is checked while the command
line is parsed, before any device acts (a bad ``--dark-frames`` must not cost metering frames under the
lights), and a bad value gives argparse's one-line ``argument --x: ...`` error naming the value and the range.

    p.add_argument("--timeout", type=seconds(0.01, 120), default=3.0)
    p.add_argument("--dark-frames", type=count(1, 200), default=10)
    p.add_argument("--frame-size", type=frame_size, default=(600, 400))
    p.add_argument("--leds-csv", type=input_file)
    add_world_option(p)                  # --world NAME|FILE: what the virtual lab renders

Numbers are finite (``inf``/``nan`` refused), integers are whole (``2.5`` refused), bounds are inclusive.
"""
from __future__ import annotations

import argparse
import math
import os
import stat
from collections.abc import Callable
from pathlib import Path

# the virtual camera renders the whole frame in memory; the D610's own raw is 6080 x 4028
MIN_FRAME_SIDE, MAX_FRAME_SIDE = 64, 8192
MAX_SEED = 2**32 - 1                      # numpy's SeedSequence accepts any non-negative int; keep it portable


def _fail(text: str, problem: str) -> argparse.ArgumentTypeError:
    return argparse.ArgumentTypeError(f"{text!r}: {problem}")


def _limits(lo: float | None, hi: float | None) -> str:
    if lo is not None and hi is not None:
        return f"from {lo:g} to {hi:g}"
    return f"at least {lo:g}" if lo is not None else f"at most {hi:g}"


def number(lo: float | None = None, hi: float | None = None, *, above: float | None = None,
           unit: str = "") -> Callable[[str], float]:
    """A finite float in [lo, hi]; ``above``: strictly greater than it (e.g. a positive time)."""
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise _fail(text, f"expected a number{unit}") from None
        if not math.isfinite(v):
            raise _fail(text, f"expected a finite number{unit}")
        if above is not None and not v > above:
            raise _fail(text, f"expected more than {above:g}{unit}")
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            raise _fail(text, f"expected {_limits(lo, hi)}{unit}")
        return v
    parse.__name__ = "number"              # argparse names the type in 'invalid <name> value' messages
    return parse


def seconds(lo: float, hi: float) -> Callable[[str], float]:
    """A time in seconds from ``lo`` (> 0) to ``hi``."""
    return number(lo, hi, above=0.0, unit=" s")


def count(lo: int = 1, hi: int | None = None) -> Callable[[str], int]:
    """A whole number in [lo, hi]."""
    def parse(text: str) -> int:
        try:
            v = int(text, 10)
        except ValueError:
            raise _fail(text, "expected a whole number") from None
        if v < lo or (hi is not None and v > hi):
            raise _fail(text, f"expected a whole number {_limits(lo, hi)}")
        return v
    parse.__name__ = "count"
    return parse


seed = count(0, MAX_SEED)
positive = count(1)


def numbers(lo: float, hi: float) -> Callable[[str], tuple[float, ...]]:
    """A comma-separated list of finite numbers in [lo, hi] (sorted, duplicates dropped), e.g. ``0,0.002,1``."""
    one = number(lo, hi)

    def parse(text: str) -> tuple[float, ...]:
        try:
            return tuple(sorted({one(cell) for cell in text.split(",")}))
        except argparse.ArgumentTypeError as exc:
            raise _fail(text, f"expected comma-separated numbers from {lo:g} to {hi:g} ({exc})") from None
    parse.__name__ = "numbers"
    return parse


def leds(n: int = 10, words: tuple[str, ...] = ()) -> Callable[[str], tuple[int, ...]]:
    """Distinct LED numbers 1..n, comma-separated (``1,4,10``); ``all`` / ``none`` when in ``words``."""
    def parse(text: str) -> tuple[int, ...]:
        if text in words:
            return tuple(range(1, n + 1)) if text == "all" else ()
        try:
            found = tuple(int(x, 10) for x in text.split(","))
        except ValueError:
            found = ()
        if not found or any(not 1 <= v <= n for v in found) or len(set(found)) != len(found):
            also = f" or {' / '.join(words)}" if words else ""
            raise _fail(text, f"expected distinct LED numbers from 1 to {n}, comma-separated like 1,4,10{also}")
        return found
    parse.__name__ = "leds"
    return parse


def frame_size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` with each side from 64 to 8192 pixels."""
    try:
        w, h = (int(x, 10) for x in text.lower().split("x"))
    except ValueError:
        raise _fail(text, "expected WIDTHxHEIGHT like 600x400") from None
    for side in (w, h):
        if not MIN_FRAME_SIDE <= side <= MAX_FRAME_SIDE:
            raise _fail(text, f"expected each side from {MIN_FRAME_SIDE} to {MAX_FRAME_SIDE} pixels")
    return w, h


def identifier(text: str) -> str:
    """An original's identifier as given on the command line: something besides spaces (the full checks, on
    every field, are core.metadata's, before a device opens)."""
    if not text.strip():
        raise _fail(text, "expected the original's identifier or accession number, e.g. ACC-123")
    return text


def input_file(text: str) -> str:
    """An existing regular file (a folder, a FIFO or a device would hang or fail later)."""
    try:
        st = os.stat(text)
    except FileNotFoundError:
        raise _fail(text, "no such file") from None
    except OSError as exc:
        raise _fail(text, f"cannot read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise _fail(text, f"{kind}; expected a file")
    return text


def calibration_source(text: str) -> str:
    """A calibration profile (an existing .json file) or a session folder holding one (its newest is used)."""
    if os.path.isdir(text):
        if not os.path.isdir(os.path.join(text, "calibration")):
            raise _fail(text, "a folder without calibration/; expected a calibration file (.json) or a session "
                              "folder made by `dualrgb calibrate --session`")
        return text
    return input_file(text)


def stand_dir(text: str) -> str:
    """A stand folder (holding stand.json, as ``dualrgb measure`` writes it)."""
    if not os.path.isdir(text):
        raise _fail(text, "expected a stand folder (written by `dualrgb measure leds` or `measure import-leds`)")
    if not os.path.isfile(os.path.join(text, "stand.json")):
        raise _fail(text, "no stand.json in it; expected a folder written by `dualrgb measure leds` / `import-leds`")
    return text


def world(text: str) -> str:
    """A packaged world's name (resources/worlds/<name>.json) or an existing world JSON file; the file's keys are
    checked when the virtual lab loads it (drivers.virtual.world), before any device acts."""
    from dualrgb import resources
    if resources.path("worlds", f"{text}.json").is_file():
        return text
    if text.endswith(".json") or os.sep in text or os.path.exists(text):
        return input_file(text)
    names = sorted(p.stem for p in resources.path("worlds").glob("*.json"))
    raise _fail(text, f"expected a packaged world ({', '.join(names)}) or a world JSON file")


world.__name__ = "world"


def worlds(text: str) -> tuple[str, ...]:
    """Worlds as ``--world`` takes each, comma-separated; ``all``: every packaged world; ``none``: no world."""
    from dualrgb import resources

    if text.strip() in ("all", "none"):
        return tuple(resources.world_names()) if text.strip() == "all" else ()
    names = tuple(w.strip() for w in text.split(",") if w.strip())
    if not names:
        raise _fail(text, "expected world names or files, comma-separated, 'all' or 'none'")
    return tuple(world(w) for w in names)


worlds.__name__ = "worlds"


def column_option(text: str) -> tuple[str, str]:
    """``FIELD=NAME``: the queue CSV's column that holds an original's field (app.workflow.day.queue_csv)."""
    from dualrgb.app.workflow.day.queue_csv import column_option as parse

    try:
        return parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def render_illuminant(text: str) -> str:
    """A light the spectral rendering is seen under (simulation.other_lights: D65, D50, A, FL11, LED; any case)
    -> its command-line name."""
    from dualrgb.simulation.other_lights import light_key, light_of_key

    try:
        return light_key(light_of_key(text))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_render_option(p: argparse.ArgumentParser) -> None:
    """``--render-illuminant``: the light the delivered spectral rendering is seen under."""
    from dualrgb.simulation.other_lights import REFERENCE_LIGHT, light_key, light_keys

    names = ", ".join(f"{k} ({v})" if k != v else k for k, v in light_keys().items())
    default = light_key(REFERENCE_LIGHT)
    p.add_argument("--render-illuminant", type=render_illuminant, default=None, metavar="LIGHT",
                   help=f"the light the spectral cube is rendered under (<id>_under_<LIGHT>_prophoto_16bit.tif, "
                        f"written with the cube: --spectral, or at half resolution; asking for it where no cube is "
                        f"written is refused before the light): {names}; default {default}")
    p.add_argument("--spectral", action=argparse.BooleanOptionalAction, default=None,
                   help="write the spectral cube and its rendering with the masters at any resolution "
                        "(--no-spectral: never; default: the delivery settings', else at half resolution only)")
    p.add_argument("--delivery-settings", type=Path, metavar="FILE",
                   help="the delivery settings (TOML: spectral products, other working spaces, access copies, "
                        "creator, rights, bag-info; default <per-user data folder>/delivery.toml when it exists)")


def delivery_request(args: argparse.Namespace, profiles: object = None):
    """The delivery settings the options ask for (app.workflow.delivery.delivery_settings), checked before any device
    opens
    or light goes on: a rendering asked for where none is written, or a cube from a calibration without a
    spectral estimator (``profiles``: one calibration or a dict of them), is one line."""
    from dualrgb.app.workflow.delivery.deliverables import check_spectral_request
    from dualrgb.app.workflow.delivery.delivery_settings import check_render_request, load

    settings = load(args.delivery_settings).with_spectral(args.spectral)
    check_render_request(settings, args.resolution, args.render_illuminant)
    for profile in profiles.values() if isinstance(profiles, dict) else [profiles]:
        check_spectral_request(profile, settings.spectral is True)
    return settings


def layout(text: str) -> str:
    """A chart layout ``ROWSxCOLUMNS`` such as 10x14 (simulation.charts.parse_layout reads it again)."""
    rows, sep, cols = text.lower().replace("×", "x").partition("x")
    if not sep or not rows.strip().isdigit() or not cols.strip().isdigit() or min(int(rows), int(cols)) < 1:
        raise _fail(text, "expected ROWSxCOLUMNS such as 10x14 (a ColorChecker Digital SG) or 4x6 (a Classic)")
    return text


def add_chart_options(p: argparse.ArgumentParser) -> None:
    """``--train-target / --test-target FILE`` with ``--*-layout ROWSxCOLS`` and ``--*-leave-out NAMES``: the
    stand's own charts (app.workflow.calibration.charts; README "Charts"); ``chart_choices(args)`` collects them."""
    g = p.add_argument_group("charts (default: the mode's packaged targets)")
    for role, what in (("train", "training"), ("test", "test")):
        g.add_argument(f"--{role}-target", type=input_file, metavar="FILE",
                       help=f"the {what} chart's reference spectra: spectral CGATS (X-Rite / BabelColor .txt, "
                            "ArgyllCMS .cie / .ti3) or a spectral CSV, as its vendor or a spectrophotometer wrote it")
        g.add_argument(f"--{role}-layout", type=layout, metavar="ROWSxCOLS",
                       help=f"the {what} chart's rows x columns as it lies on the stand (default: the file's; a "
                            "Digital SG is 10x14, its columns lettered A-N)")
        g.add_argument(f"--{role}-leave-out", metavar="NAMES", default="",
                       help=f"{what} chart patches the calibration does not use, comma-separated (e.g. an SG's "
                            "repeated border greys)")


def chart_choices(args: argparse.Namespace) -> dict:
    """``{"train": ChartChoice, "test": ChartChoice}`` from :func:`add_chart_options`' options."""
    from dualrgb.app.workflow.calibration.charts import ChartChoice

    return {role: ChartChoice(getattr(args, f"{role}_target") or "", getattr(args, f"{role}_layout") or "",
                              getattr(args, f"{role}_leave_out") or "") for role in ("train", "test")}


def corners(text: str) -> tuple[str, tuple[float, ...]]:
    """``train=X,Y,X,Y,X,Y,X,Y`` (the target's four corners in the raw file's pixels) -> (name, 8 numbers)."""
    from dualrgb.app.workflow.raw_import.import_checks import parse_corners

    name, sep, rest = text.partition("=")
    name = name.strip().lower()
    if not sep or name not in ("train", "test"):
        raise argparse.ArgumentTypeError(f"{text!r}: expected train=X,Y,X,Y,X,Y,X,Y or test=...")
    try:
        return name, parse_corners(rest)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def key_value(text: str) -> tuple[str, str]:
    """``Key=Value``, e.g. a BagIt bag-info field (the key: letters, digits and dashes, as BagIt's are)."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip() or not all(c.isalnum() or c == "-" for c in key.strip()):
        raise argparse.ArgumentTypeError(f"{text!r}: expected Key=Value, the key of letters, digits and dashes")
    return key.strip(), value.strip()


def field_value(text: str) -> tuple[str, str]:
    """``FIELD=VALUE``, an original's extra field (any name core.metadata accepts; the value may be empty: the field
    removed), e.g. ``collection set --extra department=Paintings``."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: expected FIELD=VALUE, e.g. department=Paintings")
    return name.strip(), value


RESOLUTION_HELP = ("full: the sensor's pixels, each light's frames demosaiced (Malvar-He-Cutler, linear); half: one "
                   "pixel per 2x2 Bayer cell, no interpolation (a quarter of the pixels). Default full")


def add_resolution_option(p: argparse.ArgumentParser) -> None:
    """``--resolution full|half``: the originals' deliverables at the sensor's resolution or on its 2x2 cells."""
    p.add_argument("--resolution", choices=("full", "half"), default="full", help=RESOLUTION_HELP)


def add_world_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--world NAME|FILE`` (default ``nominal``): what the virtual lab renders (a camera, LEDs, flare and
    reference error that may differ from the nominal model; README "Worlds"). ``args.world`` is the text."""
    from dualrgb import resources

    names = ", ".join(resources.world_names())
    parser.add_argument("--world", type=world, default="nominal", metavar="NAME|FILE",
                        help=f"virtual lab: the world it renders, a packaged name ({names}) or a world JSON file "
                             "(default nominal)")


__all__ = ["MAX_FRAME_SIDE", "add_chart_options", "add_render_option", "add_world_option", "calibration_source",
           "chart_choices",
           "column_option", "count", "frame_size", "input_file", "layout", "leds", "number", "numbers", "positive",
           "render_illuminant", "seconds", "seed", "stand_dir", "world", "worlds"]
