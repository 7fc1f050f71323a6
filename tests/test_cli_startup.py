"""CLI start-up: building the parser (what --help, --version, sphere, devices and raw-info pay before they run)
imports none of the heavy libraries; --version names the installed version. Timings are in `make bench`."""
from __future__ import annotations

import subprocess
import sys

import pytest

HEAVY = ("numpy", "scipy", "colour", "matplotlib", "numba", "rawpy", "PySide6", "serial", "tqdm", "dask",
         "importlib.metadata")

PROBE = """
import sys
from dualrgb.app.cli import build_parser
parser = build_parser()
try:
    parser.parse_args({argv!r})
except SystemExit:
    pass
heavy = {heavy!r}
print("HEAVY:" + " ".join(sorted(m for m in heavy if m in sys.modules)))
"""


@pytest.mark.parametrize("argv", [["--help"], ["sphere", "--help"], ["devices", "--help"], ["raw-info", "--help"],
                                  ["study", "parsimony", "--help"], ["simulate", "--help"],
                                  ["measure", "csrf", "--help"], ["capture", "--help"], ["process", "--help"],
                                  ["cube", "--help"], ["verify", "--help"], ["bag", "--help"]])
def test_parser_imports_nothing_heavy(argv):
    code = PROBE.format(argv=argv, heavy=HEAVY)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    loaded = r.stdout.rsplit("HEAVY:", 1)[1].strip()
    assert loaded == "", f"{' '.join(argv)} imported {loaded}"


def test_version_is_the_distributions(capsys):
    from importlib import metadata

    from dualrgb.app.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out == f"dualrgb {metadata.version('dualrgb')}\n"


def test_the_command_line_keeps_blas_to_one_thread_unless_told():
    """Small fits on a busy 2-core machine ran 40x slower with OpenBLAS' threads: the CLI sets one thread before
    numpy loads, and a user's own setting wins."""
    import os
    import subprocess
    import sys

    code = "import os, dualrgb.app.cli; print(os.environ['OPENBLAS_NUM_THREADS'])"
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    assert subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=120).stdout.strip() == "1"
    env["OPENBLAS_NUM_THREADS"] = "4"
    assert subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=120).stdout.strip() == "4"
