"""Fault injection, input that cannot crash (issue 9 items 11-15): user files and options that used to abort a
native kernel, hang, or end in a traceback give one line instead."""
from __future__ import annotations

import argparse
import json
import logging
import os
import random
import socket
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from fault_rigs import ROOT

pytestmark = pytest.mark.fault("input")


def cli(*argv: str, env: dict | None = None, timeout: float = 120) -> subprocess.CompletedProcess:
    full = {**os.environ, "PYTHONWARNINGS": "ignore", **(env or {})}
    return subprocess.run([sys.executable, "-m", "dualrgb", *argv], capture_output=True, text=True, env=full,
                          cwd=ROOT, timeout=timeout)


def one_line_error(r: subprocess.CompletedProcess, fragment: str = "") -> str:
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1 and lines[0].startswith("dualrgb: error: "), (r.returncode,
                                                                                                r.stderr[-3000:])
    assert fragment in lines[0]
    return lines[0]


def spectral_csv(path: Path, columns: int, value=1.0, wavelengths=range(380, 790, 10)) -> Path:
    rows = [f"{w}," + ",".join(str(value(w, c)) if callable(value) else str(value) for c in range(columns))
            for w in wavelengths]
    path.write_text("wavelength_nm," + ",".join(f"C{c + 1}" for c in range(columns)) + "\n" + "\n".join(rows)
                    + "\n")
    return path


# ---- 11. no kernel is handed data it was not written for -----------------------------------------------
@pytest.mark.parametrize("columns", [4, 9, 12])
@pytest.mark.parametrize("method", ["exhaustive", "pso"])
def test_led_csv_with_another_led_count_is_one_line_before_any_kernel(tmp_path, columns, method):
    leds = spectral_csv(tmp_path / "leds.csv", columns)
    one_line_error(cli("simulate", "--leds-csv", str(leds), "--method", method),
                   f"{leds}:1: expected 10 data columns after the wavelength, found {columns}")


KERNEL_GUARDS = """
import sys
from dataclasses import replace
import numpy as np
from dualrgb.simulation.datasets import default_setup
from dualrgb.simulation.objective import Evaluator
from dualrgb.simulation.fast_de import mean_de2000_xyz
setup = default_setup("reflective")
ev = Evaluator(setup)
idx = np.zeros((2, 2, 3), dtype=np.int64)
calls = {
    "4 LEDs": lambda: Evaluator(replace(setup, leds=setup.leds[:4])),
    "short camera": lambda: Evaluator(replace(setup, camera=setup.camera[:-3])),
    "LED 11": lambda: ev.cost_indexed(np.where(np.arange(12).reshape(2, 2, 3) == 11, 10, 0), np.ones((2, 2, 3))),
    "LED 0": lambda: ev.cost_indexed(np.full((2, 2, 3), -1), np.ones((2, 2, 3))),
    "LED 1e9": lambda: ev.cost_indexed(np.full((2, 2, 3), 10**9), np.ones((2, 2, 3))),
    "shapes": lambda: ev.cost_indexed(idx, np.ones((2, 2, 2))),
    "de2000 shapes": lambda: mean_de2000_xyz(np.ones((2, 5)), np.ones((2, 5)), np.ones((2, 5)), np.ones(3),
                                             *(np.ones(4, np.float32),) * 3, np.empty(2, np.float32)),
}
for name, call in calls.items():
    try:
        call()
    except ValueError as exc:          # SpectralDataError is a ValueError
        print(name, "REFUSED", str(exc).replace(chr(10), " "), sep="|", flush=True)
    else:
        print(name, "RAN", "", sep="|", flush=True)
"""


def test_kernels_are_never_handed_data_they_were_not_written_for():
    """In a subprocess: without the guards these inputs abort the interpreter inside numba (that would end
    the test session, not fail a test)."""
    r = subprocess.run([sys.executable, "-c", KERNEL_GUARDS], capture_output=True, text=True, cwd=ROOT,
                       timeout=300)
    results = {name: (status, message) for name, status, message in
               (line.split("|", 2) for line in r.stdout.splitlines())}
    assert r.returncode == 0, f"crashed ({r.returncode}) after {list(results)}: {r.stderr[-1500:]}"
    names = ["4 LEDs", "short camera", "LED 11", "LED 0", "LED 1e9", "shapes", "de2000 shapes"]
    assert all(results.get(n, ("missing",))[0] == "REFUSED" for n in names), results
    results = {n: m for n, (_, m) in results.items()}
    assert "4 LEDs, the sphere has 10" in results["4 LEDs"] and "uses LED 11" in results["LED 11"]


# ---- 12. presets: a strict schema ------------------------------------------------------------------------
def _preset(*sources) -> str:
    return json.dumps({"format": "dualrgb-preset/1", "name": "t", "sources": list(sources)})


GOOD = {"leds": [1, 6, 8], "levels": [1.0, 0.5, 0.25]}
BAD_PRESETS = {
    "levels 0": _preset({"leds": [1, 2], "levels": 0}),
    "levels null": _preset({"leds": [1, 2], "levels": None}),
    "levels []": _preset({"leds": [1, 2], "levels": []}),
    "levels missing": _preset({"leds": [1, 2]}),
    "levels too few": _preset({"leds": [1, 2], "levels": [1.0]}),
    "level above 1": _preset({"leds": [1], "levels": [1.5]}),
    "level negative": _preset({"leds": [1], "levels": [-0.1]}),
    "level NaN": '{"sources": [{"leds": [1], "levels": [NaN]}]}',
    "level Infinity": '{"sources": [{"leds": [1], "levels": [Infinity]}]}',
    "level bool": _preset({"leds": [1], "levels": [True]}),
    "level string": _preset({"leds": [1], "levels": ["1"]}),
    "leds floats": _preset({"leds": [1.7, 2.2], "levels": [1, 1]}),
    "leds string": _preset({"leds": "123", "levels": [1, 1, 1]}),
    "leds bools": _preset({"leds": [True], "levels": [1]}),
    "leds duplicate": _preset({"leds": [2, 2], "levels": [1, 1]}),
    "led 0": _preset({"leds": [0], "levels": [1]}),
    "led 11": _preset({"leds": [11], "levels": [1]}),
    "leds empty": _preset({"leds": [], "levels": []}),
    "source not an object": _preset([1, 2]),
    "too many sources": _preset(*[GOOD] * 11),
    "seed a string": json.dumps({"sources": [GOOD], "seed": "zero"}),
    "name a number": json.dumps({"sources": [{**GOOD, "name": 5}]}),
    "top level list": "[1, 2]",
    "deep nesting": "[" * 100000,
    "not JSON": "{",
}


@pytest.mark.parametrize("case", sorted(BAD_PRESETS))
def test_bad_preset_is_one_line_naming_the_file(tmp_path, case):
    from dualrgb.simulation.presets import PresetError, load_preset

    path = tmp_path / "preset.json"
    path.write_text(BAD_PRESETS[case])
    with pytest.raises(PresetError) as info:
        load_preset(path)
    assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)


@pytest.mark.parametrize("kind", ["utf-16", "binary", "too large", "fifo", "folder"])
def test_unreadable_preset_files_name_the_file(tmp_path, kind):
    from dualrgb.simulation.presets import PresetError, load_preset

    path = tmp_path / "preset.json"
    if kind == "utf-16":
        path.write_bytes(_preset(GOOD).encode("utf-16"))
    elif kind == "binary":
        path.write_bytes(bytes(range(256)) * 4)
    elif kind == "too large":
        path.write_text(json.dumps({"sources": [GOOD], "notes": "x" * (2 << 20)}))
    elif kind == "fifo":
        os.mkfifo(path)
    else:
        path.mkdir()
    with pytest.raises(PresetError) as info:
        run_with_deadline(lambda: load_preset(path))
    assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)


def test_a_good_preset_still_loads_exactly(tmp_path):
    from dualrgb.simulation.presets import load_preset

    path = tmp_path / "p.json"
    path.write_text(_preset(GOOD, {"leds": [3, 5, 9], "levels": [1, 1, 1], "name": "second"}))
    p = load_preset(path)
    assert [s.leds for s in p.sources] == [(1, 6, 8), (3, 5, 9)]
    assert p.sources[0].levels == (1.0, 0.5, 0.25) and p.sources[1].name == "second"


def run_with_deadline(fn, seconds: float = 20.0):
    """Run ``fn`` in a thread; a call that blocks (a FIFO opened for reading) fails the test, not the suite."""
    box: dict = {}

    def target():
        try:
            box["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - handed back to the test thread
            box["error"] = exc
    t = threading.Thread(target=target, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"still blocked after {seconds} s"
    if "error" in box:
        raise box["error"]
    return box.get("value")


# ---- 13. raw files: regular files only, one line each, fuzzed --------------------------------------------
@pytest.fixture(scope="module")
def dng_bytes() -> bytes:
    from dualrgb.drivers.virtual.dng import DngInfo
    from dualrgb.drivers.virtual.dng import dng_bytes as write_dng_bytes

    mosaic = np.random.default_rng(0).integers(600, 15000, size=(48, 64)).astype(np.uint16)
    return write_dng_bytes(mosaic, DngInfo(exposure_s=0.01, iso=100, aperture=8.0))


def _fuzz_cases() -> list[tuple[str, float, int]]:
    """(kind, where, bit): 'cut' keeps ``where`` bytes (or that fraction of the file), 'flip' flips a bit at
    byte ``where`` (or that fraction); the header (first 720 bytes: IFDs, tags, CFA) gets most flips."""
    rnd = random.Random(13)
    cases = [("cut", n, 0) for n in range(0, 72, 3)] + [("cut", round(rnd.random(), 4), 0) for _ in range(56)]
    cases += [("flip", rnd.randrange(720), rnd.randrange(8)) for _ in range(190)]
    cases += [("flip", round(rnd.random(), 4), rnd.randrange(8)) for _ in range(30)]
    return cases


def _mutate(data: bytes, kind: str, where: float, bit: int) -> bytes:
    pos = int(where * len(data)) if isinstance(where, float) else int(where)
    if kind == "cut":
        return data[:pos]
    b = bytearray(data)
    b[min(pos, len(b) - 1)] ^= 1 << bit
    return bytes(b)


@pytest.mark.parametrize("kind,where,bit", _fuzz_cases())
def test_fuzzed_dng_loads_or_gives_one_line(tmp_path, capfd, dng_bytes, kind, where, bit):
    from dualrgb.app.commands.raw_info import raw_info
    from dualrgb.drivers.raw import RawFileError, load_raw

    path = tmp_path / "fuzz.DNG"
    path.write_bytes(_mutate(dng_bytes, kind, where, bit))
    try:
        info = raw_info(load_raw(path))
    except RawFileError as exc:
        msg = str(exc)
        assert msg.startswith(f"{path}: ") and "\n" not in msg
        assert "X-Trans" not in msg                          # a damaged DNG is not an X-Trans raw
    else:
        assert info["cfa_pattern"] in ("RGGB", "BGGR", "GRBG", "GBRG")
    assert capfd.readouterr().err == ""                      # no tifffile warnings, no LibRaw chatter


def test_fifo_named_nef_is_refused_without_blocking(tmp_path):
    from dualrgb.drivers.raw import RawFileError, load_raw

    fifo = tmp_path / "DSC_0001.NEF"
    os.mkfifo(fifo)
    with pytest.raises(RawFileError, match="not a regular file"):
        run_with_deadline(lambda: load_raw(fifo))


@pytest.mark.parametrize("content", [b"II*\x00", b"MM\x00*", b"II*\x00\x08\x00\x00\x00", b"\x00" * 7])
def test_raw_info_on_a_tiff_header_stub_is_one_line(tmp_path, content):
    path = tmp_path / "t.NEF"
    path.write_bytes(content)
    one_line_error(cli("raw-info", str(path)), str(path))


# ---- 14. every option is validated while parsing, before any device acts -------------------------------
BAD_OPTIONS = [
    ("sphere-emulator --watchdog inf", "--watchdog"), ("sphere-emulator --watchdog 0", "--watchdog"),
    ("sphere-emulator --watchdog nan", "--watchdog"), ("sphere --port x --timeout 1e-9 identify", "--timeout"),
    ("sphere --port x --timeout inf status", "--timeout"), ("sphere --port x apply p.json --source 0", "--source"),
    ("devices --timeout -1", "--timeout"), ("devices --timeout nan", "--timeout"),
    ("devices --timeout 1e9", "--timeout"), ("demo --out OUT --frame-size 40000x30000", "--frame-size"),
    ("demo --out OUT --frame-size 10x10", "--frame-size"), ("demo --out OUT --frame-size 600x-400", "--frame-size"),
    ("demo --out OUT --dark-frames 0", "--dark-frames"), ("demo --out OUT --dark-frames 2.5", "--dark-frames"),
    ("demo --out OUT --seed -1", "--seed"), ("simulate --top 0", "--top"), ("simulate --step 0", "--step"),
    ("simulate --step inf", "--step"), ("simulate --seed 1e3", "--seed"), ("simulate --leds-csv MISSING", "--leds-csv"),
    ("study parsimony --tolerance nan", "--tolerance"), ("study unbinned --workers 0", "--workers"),
    ("study sweep --camera-csv MISSING", "--camera-csv"),
]


@pytest.mark.parametrize("command,option", BAD_OPTIONS, ids=[c for c, _ in BAD_OPTIONS])
def test_bad_option_is_refused_while_parsing(tmp_path, capsys, command, option):
    """Refused by the parser itself: no command function runs, so no device can act (a bad --dark-frames
    used to cost 11 metering frames under the lights first)."""
    from dualrgb.app import cli as cli_mod

    argv = [str(tmp_path / "out") if a == "OUT" else str(tmp_path / "none.csv") if a == "MISSING" else a
            for a in command.split()]
    with pytest.raises(SystemExit) as info:
        cli_mod.build_parser().parse_args(argv)
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert info.value.code == 2 and f"argument {option}: " in last and "Traceback" not in last


def _all_actions(parser: argparse.ArgumentParser):
    for action in parser._actions:
        yield action
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _all_actions(sub)


def test_every_numeric_option_uses_a_shared_validator():
    """No command parses a number with bare int/float: those accept inf, nan, 0 and negative counts."""
    from dualrgb.app import cli as cli_mod
    from dualrgb.app.commands import options
    from dualrgb.app.commands.import_raw import corners

    shared = {f.__name__ for f in (options.frame_size, options.input_file, options.world, options.worlds,
                                   options.stand_dir, options.column_option, options.render_illuminant,
                                   options.layout, options.identifier, options.key_value, options.field_value,
                                   options.calibration_source, corners)} | {
        "number", "count", "numbers", "leds"}
    raw = [a.dest for a in _all_actions(cli_mod.build_parser()) if getattr(a, "type", None) in (int, float)]
    allowed_raw = {"led", "level"}               # `sphere set`: checked by LedSphere, with the light switched off
    assert set(raw) <= allowed_raw, f"bare int/float options: {raw}"
    assert {getattr(a.type, "__name__", "") for a in _all_actions(cli_mod.build_parser())
            if callable(getattr(a, "type", None)) and a.type not in (int, float, str, Path)} <= shared | {"_bins"}


# ---- 15. the GUI on a stale or incomplete display: one line, exit 1 -------------------------------------
HIDDEN_LIBRARY = """
import sys
from dualrgb.app.gui import platform_check
real = platform_check._dlopen
platform_check._dlopen = lambda so: so != "libxcb-cursor.so.0" and real(so)
from dualrgb.app.cli import main
sys.exit(main(["gui"]))
"""


def test_missing_xcb_library_gives_the_install_command():
    """`dualrgb gui` with libxcb-cursor.so.0 hidden from the probe (a subprocess: if the probe let Qt start,
    Qt's abort ends that process, not the test session)."""
    base = {k: v for k, v in os.environ.items() if k not in ("WAYLAND_DISPLAY",)}
    r = subprocess.run([sys.executable, "-c", HIDDEN_LIBRARY], capture_output=True, text=True, cwd=ROOT,
                       env={**base, "QT_QPA_PLATFORM": "", "DISPLAY": ":0"}, timeout=120)
    line = one_line_error(r, "libxcb-cursor.so.0")
    assert "sudo apt-get install libxcb-cursor0 libxcb-icccm4" in line or "sudo dnf install xcb-util-cursor" in line


def test_install_command_names_every_package():
    from dualrgb.app.gui import platform_check

    both = platform_check.xcb_libraries_problem(lambda so: so != "libxcb-icccm.so.4", os_release={})
    assert "apt-get install" in both and "dnf install" in both and "xcb-util-wm" in both
    for package in ("libxcb-cursor0", "libxcb-icccm4", "libxcb-image0", "libxcb-keysyms1", "libxcb-randr0",
                    "libxcb-render-util0", "libxcb-shape0", "libxcb-xinerama0", "libxcb-xkb1", "libxkbcommon-x11-0",
                    "libegl1", "libgl1", "libfontconfig1", "libdbus-1-3"):
        assert package in platform_check.install_command({"ID": "ubuntu"})
    assert platform_check.install_command({"ID": "fedora"}).startswith("sudo dnf install xcb-util-cursor")
    assert platform_check.xcb_libraries_problem(lambda so: True) is None


@pytest.mark.parametrize("env", [{"DISPLAY": ":99"}, {"DISPLAY": "localhost:77"},
                                 {"WAYLAND_DISPLAY": "wayland-9"}, {"WAYLAND_DISPLAY": "wayland-9", "DISPLAY": ":98"}],
                         ids=["stale X", "stale X over TCP", "stale Wayland", "stale both"])
def test_gui_on_a_stale_display_is_one_line_exit_1(tmp_path, env):
    base = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    r = subprocess.run([sys.executable, "-m", "dualrgb", "gui"], capture_output=True, text=True, cwd=ROOT,
                       env={**base, "QT_QPA_PLATFORM": "", "XDG_RUNTIME_DIR": str(tmp_path), **env}, timeout=120)
    one_line_error(r)
    assert "Aborted" not in r.stderr and "core dumped" not in r.stderr


def test_display_probes_tell_stale_from_live(tmp_path):
    from dualrgb.app.gui import platform_check

    if platform_check._dlopen("libxcb.so.1"):
        assert "no X server answers" in platform_check.x_display_problem(":99")
    env = {"WAYLAND_DISPLAY": "wayland-7", "XDG_RUNTIME_DIR": str(tmp_path)}
    assert "no Wayland compositor answers" in platform_check.wayland_problem(env)
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as server:
        server.bind(str(tmp_path / "wayland-7"))
        server.listen(1)
        assert platform_check.wayland_problem(env) is None        # a live compositor socket passes


# ---- 15. data that runs but cannot mean what was meant: a warning ----------------------------------------
def test_a_camera_channel_that_responds_nowhere_is_an_error(tmp_path):
    """Issue 28: refused where the file is read (it was a warning, then a division by zero after a whole
    calibration)."""
    from dualrgb.simulation.datasets import default_setup
    from dualrgb.simulation.spectral_io import SpectralDataError

    path = spectral_csv(tmp_path / "c.csv", 3, lambda w, c: 0 if c == 1 else 0.5)
    with pytest.raises(SpectralDataError, match="c.csv: column 'C2' is 0 at every wavelength; a camera channel"):
        default_setup("reflective", camera_csv=str(path))


@pytest.mark.parametrize("what", ["zero LED", "identical training spectra"])
def test_degenerate_spectra_warn(tmp_path, caplog, what):
    from dualrgb.simulation.datasets import default_setup

    caplog.set_level(logging.WARNING)
    if what == "zero LED":
        kwargs = {"leds_csv": str(spectral_csv(tmp_path / "l.csv", 10, lambda w, c: 0 if c == 2 else 1))}
        expected = "LED 3 is zero"
    else:
        kwargs = {"train_csv": str(spectral_csv(tmp_path / "t.csv", 30, 0.5))}
        expected = "all 30 patches have identical spectra"
    default_setup("reflective", **kwargs)
    assert expected in caplog.text
