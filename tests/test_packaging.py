"""The wheel installs one namespace, dualrgb: pyproject's package-dir maps the top-level folders onto it and its
package list names every folder that holds an ``__init__.py`` (a missing entry would be left out of the wheel).
The built wheel itself is checked by .ci/wheel_smoke.sh (top_level.txt is ``dualrgb`` alone)."""
from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _setuptools() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def _folders(root: Path) -> list[Path]:
    return [root, *(p for p in root.rglob("*") if p.is_dir() and p.name != "__pycache__")]


def test_every_package_folder_is_listed():
    """Code folders (with ``__init__.py``) and data folders alike: a folder left out is left out of the wheel."""
    config = _setuptools()
    found = set()
    for name, folder in config["package-dir"].items():
        for path in _folders(ROOT / folder):
            if any(f.is_file() for f in path.iterdir()):
                found.add(".".join((name, *path.relative_to(ROOT / folder).parts)))
    assert found == set(config["packages"])


def test_every_data_file_is_shipped():
    """Each file in a data folder matches that package's package-data patterns."""
    config = _setuptools()
    data = config["package-data"]
    for package, patterns in data.items():
        if not package.startswith("dualrgb.resources"):
            continue
        folder = ROOT / "resources" / Path(*package.split(".")[2:])
        for f in folder.iterdir():
            if f.is_file() and f.suffix != ".py":
                assert any(f.match(p) for p in patterns), f"{f} is not in package-data[{package!r}]"


def test_everything_is_under_dualrgb():
    config = _setuptools()
    assert all(p == "dualrgb" or p.startswith("dualrgb.") for p in config["packages"])
    assert not (ROOT / "resources" / "generate.py").exists()          # maintainer scripts live in tools/


def test_python_m_dualrgb_runs_the_cli(tmp_path):
    r = subprocess.run([sys.executable, "-m", "dualrgb", "--version"], capture_output=True, text=True, cwd=tmp_path,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("dualrgb ")
