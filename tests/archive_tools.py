"""The archive's own tools for the tests (issue 39): SLUB's checkit_tiff with its shipped baseline config, exiftool's
validator, and the TIFFs of a delivery. Each skips with the Debian package to install where its tool is absent."""
from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

SLUB_CONFIG = Path("/usr/share/checkit_tiff/example_configs/cit_tiff6_baseline_SLUB.cfg")
PPI_RULE = re.compile(r"^(28[23]); mandatory; range\(300, 4000\)$", re.MULTILINE)


def tool(name: str, package: str) -> str:
    if shutil.which(name) is None:
        pytest.skip(f"{name} is not installed (Debian: apt-get install {package})")
    return name


def slub_config(tmp_path: Path, relax_ppi: bool) -> Path:
    """SLUB's baseline config as shipped, or with only its 300-4000 ppi rule (X and YResolution) relaxed to any
    sampling up to 4000 ppi (for a stand whose real ppi is lower, which the QA line says)."""
    tool("checkit_tiff", "checkit-tiff")
    if not SLUB_CONFIG.is_file():
        pytest.skip(f"{SLUB_CONFIG} missing (Debian checkit-tiff ships it)")
    if not relax_ppi:
        return SLUB_CONFIG
    text = SLUB_CONFIG.read_text()
    relaxed, n = PPI_RULE.subn(r"\1; mandatory; range(1, 4000)", text)
    assert n == 2, "the shipped config's ppi rules changed"
    out = tmp_path / "slub_ppi_relaxed.cfg"
    out.write_text(relaxed)
    return out


def checkit(config: Path, tiff: Path) -> tuple[bool, str]:
    """checkit_tiff's verdict (it exits 0 whatever it finds: the last line says) and its report."""
    r = subprocess.run(["checkit_tiff", str(config), str(tiff)], capture_output=True, text=True, timeout=120)
    text = r.stdout + r.stderr
    return "Yes, the given tif is valid" in text, text


def exiftool_validate(path: Path) -> str:
    """exiftool -validate's result line ('OK', or 'n Warnings (...)') and its warnings."""
    r = subprocess.run([tool("exiftool", "libimage-exiftool-perl"), "-validate", "-warning", "-a", "-s", str(path)],
                       capture_output=True, text=True, timeout=120)
    return r.stdout.strip()


def tiffs_of(folder: Path) -> list[Path]:
    return sorted(folder.glob("*.tif"))
