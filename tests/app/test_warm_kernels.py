"""``python -m dualrgb.app.warm_kernels`` (what ``make venv`` runs after installing, docs/how-to/install.md): every
group of kernels is compiled or loaded, one line each, and numba's cache then holds them; an argument is refused."""
from __future__ import annotations

import subprocess
import sys

from dualrgb.app import warm_kernels


def test_the_documented_command_warms_every_group():
    out = subprocess.run([sys.executable, "-m", "dualrgb.app.warm_kernels"], capture_output=True, text=True,
                         timeout=900, check=False)                      # a hang guard: cold, it compiles ~1 min
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert [line.split(": ")[1] for line in lines] == list(warm_kernels.GROUPS)
    assert all(line.startswith("numba kernels: ") and line.endswith(" s") for line in lines)


def test_the_kernels_are_in_the_cache_afterwards():
    from dualrgb.app.processing.encode import _encode_mosaic_rows
    from dualrgb.simulation.fast_de import mean_de2000_mapped
    from dualrgb.simulation.warmup import _cached

    said: list[str] = []
    took = warm_kernels.warm_all(said.append)
    assert list(took) == list(warm_kernels.GROUPS) and len(said) == len(took)
    assert _cached(_encode_mosaic_rows) in (True, None) and _cached(mean_de2000_mapped) in (True, None)
    assert _encode_mosaic_rows.signatures and mean_de2000_mapped.signatures   # compiled or loaded here


def test_an_argument_is_refused(capsys):
    assert warm_kernels.main(["--now"]) == 2
    assert "usage: python -m dualrgb.app.warm_kernels" in capsys.readouterr().err
