"""The house's layers, enforced by an AST walk of every module (the rules: docs/explanation/architecture.md,
"The layers").

common/ imports no other dualrgb package; simulation/, drivers/ and resources/ import neither app/ nor Qt; only
app/gui imports Qt; a GUI panel imports no other panel and no concrete driver module (it goes through the Qt-free
workflow layer). No two modules import each other, directly or through others (function-level and
TYPE_CHECKING imports count: a circle is a design knot even where Python tolerates it). The production packages
(app/workflow, app/processing, app/session, app/sequences) know nothing of the virtual lab: they import nothing
from drivers.virtual, app.lab (the lab's front-end side) or the front ends, and do not even name drivers.virtual
(issue 36: the lab is devices, reached by their addresses)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
QT = ("PySide6", "pyqtgraph", "shiboken6")
CONCRETE_DRIVERS = ("drivers.camera.gphoto", "drivers.led_sphere.driver", "drivers.virtual")
NAMESPACE = "dualrgb."
PACKAGES = ("app", "common", "drivers", "simulation", "resources")
PRODUCTION = ("workflow", "processing", "session", "sequences")        # under app/
LAB_OR_FRONT_ENDS = ("drivers.virtual", "app.lab", "app.gui", "app.commands", "app.cli", "app.demo")


def imports(path: Path, *, names: bool = False) -> list[str]:
    """Absolute module names imported anywhere in ``path`` (function-level imports included); with ``names``
    also ``pkg.name`` for every ``from pkg import name`` (the name may be a module). dualrgb's own modules are
    named by their folders (``dualrgb.app.cli`` -> ``app.cli``), as the rules below are."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append(node.module)
            if names:
                out += [f"{node.module}.{a.name}" for a in node.names]
    return [name.removeprefix(NAMESPACE) for name in out]


def violations(root: Path = ROOT) -> list[str]:
    bad = []
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            parts = path.relative_to(root).parts
            for mod in imports(path):
                top = mod.split(".")[0]
                if parts[0] == "common" and (top in PACKAGES or top in QT):
                    bad.append(f"{'/'.join(parts)}: imports {mod}")
                if parts[0] in ("simulation", "drivers", "resources") and (top == "app" or top in QT):
                    bad.append(f"{'/'.join(parts)}: imports {mod}")
                if parts[0] == "app" and top in QT and parts[1] != "gui":
                    bad.append(f"{'/'.join(parts)}: imports {mod} outside app/gui")
                if parts[:3] == ("app", "gui", "panels") and (mod.startswith("app.gui.panels.")
                                                               or mod.startswith(CONCRETE_DRIVERS)):
                    bad.append(f"{'/'.join(parts)}: panel imports {mod}")
            if parts[0] == "app" and len(parts) > 2 and parts[1] in PRODUCTION:
                hits = {m for m in imports(path, names=True)
                        if any(m == x or m.startswith(x + ".") for x in LAB_OR_FRONT_ENDS)}
                bad += [f"{'/'.join(parts)}: production imports {m}" for m in sorted(hits)
                        if not any(m.startswith(h + ".") for h in hits)]      # a module, not also its names
    return bad


def module_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Module -> the dualrgb modules it imports (a name resolved to the longest module it names; a package's
    ``__init__`` importing its own submodules is no edge)."""
    files = {}
    for pkg in PACKAGES:
        for path in (root / pkg).rglob("*.py"):
            name = ".".join(path.relative_to(root).with_suffix("").parts)
            files[name.removesuffix(".__init__")] = path

    def resolve(name: str) -> str | None:
        while name and name not in files:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {}
    for mod, path in files.items():
        targets = {resolve(m) for m in imports(path, names=True)}
        graph[mod] = {t for t in targets if t and t != mod and not mod.startswith(t + ".")}
    return graph


def import_circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    circles.append(sorted(component))
    return circles


def test_layers_hold():
    assert violations() == []


def test_production_does_not_name_the_virtual_lab():
    """The issue's own check, `grep -rn "drivers.virtual\\|drivers import virtual" app/workflow app/processing
    app/session app/sequences` printing nothing (docstrings and comments included)."""
    import re

    pattern = re.compile(r"drivers.virtual|drivers import virtual")
    hits = [f"{path.relative_to(ROOT)}:{n}: {line.strip()}" for pkg in PRODUCTION
            for path in sorted((ROOT / "app" / pkg).rglob("*.py"))
            for n, line in enumerate(path.read_text().splitlines(), 1) if pattern.search(line)]
    assert hits == []


def test_no_import_circles():
    assert import_circles(module_graph()) == []


def test_import_circles_are_found(tmp_path):
    for pkg in PACKAGES:
        (tmp_path / pkg).mkdir()
        (tmp_path / pkg / "__init__.py").write_text("")
    (tmp_path / "app" / "a.py").write_text("from dualrgb.app.b import x\n")
    (tmp_path / "app" / "b.py").write_text("def f():\n    from dualrgb.app import c\n")        # function-level counts
    (tmp_path / "app" / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                           "    import dualrgb.app.a\n")
    (tmp_path / "app" / "d.py").write_text("import dualrgb.app.a\n")                          # on no circle
    assert import_circles(module_graph(tmp_path)) == [["app.a", "app.b", "app.c"]]


@pytest.mark.parametrize("rel, source, expected", [
    ("simulation/x.py", "from dualrgb.app.session.capture_session import CaptureSession\n", "imports app.session"),
    ("common/x.py", "from dualrgb.simulation.grid import DEFAULT_GRID\n", "common/x.py: imports simulation.grid"),
    ("drivers/x.py", "def f():\n    import PySide6.QtCore\n", "drivers/x.py: imports PySide6.QtCore"),
    ("app/processing/x.py", "import pyqtgraph as pg\n", "outside app/gui"),
    ("app/gui/panels/x.py", "from dualrgb.app.gui.panels.camera import image_widget\n", "panel imports app.gui.panels"),
    ("app/gui/panels/y.py", "from dualrgb.drivers.camera.gphoto import format_shutter\n",
     "panel imports drivers.camera"),
    ("app/workflow/x.py", "def f():\n    from dualrgb.drivers.virtual.lab import VirtualLab\n",
     "app/workflow/x.py: production imports drivers.virtual.lab"),
    ("app/sequences/x.py", "from dualrgb.app.lab.truth import compare\n", "production imports app.lab.truth"),
    ("app/session/x.py", "from dualrgb.drivers import virtual\n", "production imports drivers.virtual"),
])
def test_each_rule_catches_its_violation(tmp_path, rel, source, expected):
    for pkg in PACKAGES:
        (tmp_path / pkg).mkdir()
    target = tmp_path / rel
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(source)
    found = violations(tmp_path)
    assert len(found) == 1 and expected in found[0]
