"""The house's layers, enforced by an AST walk of every module (the rules of docs: ARCHITECTURE "layers").

simulation/, drivers/ and resources/ import neither app/ nor Qt; only app/gui imports Qt; a GUI panel imports no
other panel and no concrete driver module (it goes through the Qt-free workflow layer)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
QT = ("PySide6", "pyqtgraph", "shiboken6")
CONCRETE_DRIVERS = ("drivers.camera.gphoto", "drivers.led_sphere.driver", "drivers.virtual")
PACKAGES = ("app", "drivers", "simulation", "resources")


def imports(path: Path) -> list[str]:
    """Absolute module names imported anywhere in ``path`` (function-level imports included)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append(node.module)
    return out


def violations(root: Path = ROOT) -> list[str]:
    bad = []
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            parts = path.relative_to(root).parts
            for mod in imports(path):
                top = mod.split(".")[0]
                if parts[0] in ("simulation", "drivers", "resources") and (top == "app" or top in QT):
                    bad.append(f"{'/'.join(parts)}: imports {mod}")
                if parts[0] == "app" and top in QT and parts[1] != "gui":
                    bad.append(f"{'/'.join(parts)}: imports {mod} outside app/gui")
                if parts[:3] == ("app", "gui", "panels") and (mod.startswith("app.gui.panels.")
                                                               or mod.startswith(CONCRETE_DRIVERS)):
                    bad.append(f"{'/'.join(parts)}: panel imports {mod}")
    return bad


def test_layers_hold():
    assert violations() == []


@pytest.mark.parametrize("rel, source, expected", [
    ("simulation/x.py", "from app.session import CaptureSession\n", "simulation/x.py: imports app.session"),
    ("drivers/x.py", "def f():\n    import PySide6.QtCore\n", "drivers/x.py: imports PySide6.QtCore"),
    ("app/processing/x.py", "import pyqtgraph as pg\n", "outside app/gui"),
    ("app/gui/panels/x.py", "from app.gui.panels.camera import image_widget\n", "panel imports app.gui.panels"),
    ("app/gui/panels/y.py", "from drivers.camera.gphoto import format_shutter\n", "panel imports drivers.camera"),
])
def test_each_rule_catches_its_violation(tmp_path, rel, source, expected):
    for pkg in PACKAGES:
        (tmp_path / pkg).mkdir()
    target = tmp_path / rel
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(source)
    found = violations(tmp_path)
    assert len(found) == 1 and expected in found[0]
