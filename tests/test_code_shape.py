"""The shape rule of CONTRIBUTING.md, kept from regressing: modules under 600 lines, functions short enough to
read at once (at most 50 lines, counted from the first decorator to the last line, docstring included).

A function that must stay long is listed in ``LONG_FUNCTIONS`` with the reason; the list cannot rot (an entry that
is no longer long, or no longer there, fails too). app/gui is held to the same rule since its rework (issue 11).
"""
from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("dualrgb", "app", "common", "drivers", "simulation", "resources")     # what the wheel installs
MAX_FUNCTION_LINES = 50
MAX_MODULE_LINES = 600

# numba kernels: one fused loop nest per item or pixel; splitting them into calls would cost inlining and compile
# time for no reader's gain (their docstrings say what each loop does)
_FUSED_KERNEL = "numba kernel: one fused loop nest"
LONG_FUNCTIONS = {
    "simulation/fast_linalg.py::_fit_segment": _FUSED_KERNEL + " (normal equations to Cholesky, across items)",
    "simulation/fast_linalg.py::_fit_one": _FUSED_KERNEL + " (normal equations to Cholesky, one item)",
    "simulation/fast_de.py::_de2000": "numba scalar CIEDE2000, inlined into the kernels (one formula, one place)",
    "simulation/fast_de.py::mean_de2000_mapped": _FUSED_KERNEL + " (map, XYZ -> Lab, CIEDE2000, mean)",
    "simulation/fast_expected.py::mean_expected_de2000": _FUSED_KERNEL + " (expected captured dE00 per item)",
    "app/processing/kernels.py::_merge_row": _FUSED_KERNEL + " (HDR merge of one row, both estimators)",
    "app/processing/master_kernels.py::flat_rows_variance": _FUSED_KERNEL + " (dark, variance merge, flat field, "
                                                            "QA counts of a row band)",
}


def _modules() -> list[Path]:
    return [p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))]


def _long_functions(path: Path) -> dict[str, int]:
    """``file::name`` (``file::Class.name`` for methods) -> lines, for every function over the limit."""
    rel = path.relative_to(ROOT).as_posix()
    out: dict[str, int] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = min([child.lineno, *(d.lineno for d in child.decorator_list)])
                lines = (child.end_lineno or child.lineno) - first + 1
                if lines > MAX_FUNCTION_LINES:
                    out[f"{rel}::{prefix}{child.name}"] = lines
                visit(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(path.read_text(encoding="utf-8")), "")
    return out


def _shape_violations(paths: list[Path], allowed: dict[str, str]) -> list[str]:
    problems = []
    for path in paths:
        n = len(path.read_text(encoding="utf-8").splitlines())
        if n > MAX_MODULE_LINES:
            problems.append(f"{path.relative_to(ROOT).as_posix()}: {n} lines (at most {MAX_MODULE_LINES})")
        for name, lines in _long_functions(path).items():
            if name not in allowed:
                problems.append(f"{name}: {lines} lines (at most {MAX_FUNCTION_LINES})")
    return problems


def test_modules_and_functions_keep_their_size():
    assert _shape_violations(_modules(), LONG_FUNCTIONS) == []


def test_the_long_function_allow_list_is_current():
    long_now = {name for path in _modules() for name in _long_functions(path)}
    assert sorted(set(LONG_FUNCTIONS) - long_now) == []


def test_the_rule_sees_a_long_method(tmp_path, monkeypatch):
    head = ["class C:", "    @staticmethod", "    def f():"]
    body = [f"        x{i} = {i}" for i in range(MAX_FUNCTION_LINES - len(head) + 1)]   # 50 lines from the decorator
    tail = ["", "", "def short():", "    return 1"]
    (tmp_path / "pkg").mkdir()
    module = tmp_path / "pkg" / "m.py"
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    module.write_text("\n".join(head + body + tail) + "\n", encoding="utf-8")
    assert _long_functions(module) == {}                                        # at the limit: fine
    module.write_text("\n".join(head + ["        x = 0"] + body + tail) + "\n", encoding="utf-8")
    assert _long_functions(module) == {"pkg/m.py::C.f": MAX_FUNCTION_LINES + 1}
