"""No function of the project is over 80 lines, numba kernels excepted.

A function's length is ``end_lineno - lineno + 1`` of its ``def`` (docstring included, decorators not), measured on
every function and method under sim/, surrogate/ and pipeline/, nested ones included.  Functions decorated with
``njit`` / ``jit`` (the numba kernels, whose loops are kept in one body for speed) and the kernel template
``sim/_kernel_template.py`` are skipped.
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("sim", "surrogate", "pipeline")
SKIP_FILES = {"sim/_kernel_template.py"}
MAX_LINES = 80
KERNEL_DECORATORS = {"njit", "jit"}


def is_kernel(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """True when the function carries a numba decorator (``njit``, ``jit``, ``numba.njit(...)``, ...)."""
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", None)
        if name in KERNEL_DECORATORS:
            return True
    return False


def long_functions(source: str, filename: str, limit: int = MAX_LINES) -> list[str]:
    """``file:line name (n lines)`` for each non-kernel function of ``source`` longer than ``limit`` lines."""
    out = []
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not is_kernel(node):
            length = node.end_lineno - node.lineno + 1
            if length > limit:
                out.append(f"{filename}:{node.lineno} {node.name} ({length} lines)")
    return out


def project_files() -> list[Path]:
    """The project's Python files under sim/, surrogate/ and pipeline/, the kernel template left out."""
    files = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            if path.relative_to(ROOT).as_posix() not in SKIP_FILES:
                files.append(path)
    return files


def test_no_function_over_80_lines():
    offenders = []
    for path in project_files():
        offenders += long_functions(path.read_text(), path.relative_to(ROOT).as_posix())
    assert not offenders, f"functions over {MAX_LINES} lines (split them into named helpers):\n" + "\n".join(offenders)


def test_checker_sees_a_long_function_and_skips_kernels():
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_LINES))       # def line + 80 = 81 lines
    source = (f"def long_one():\n{body}\n"
              f"def short_one():\n    return 1\n\n"
              f"@njit(cache=True)\ndef kernel():\n{body}\n"
              f"@numba.jit\ndef kernel2():\n{body}\n"
              f"class C:\n    def method(self):\n{''.join('    ' + line for line in body.splitlines(True))}")
    found = long_functions(source, "synthetic.py")
    assert found == ["synthetic.py:1 long_one (81 lines)", f"synthetic.py:{source.splitlines().index('    def method(self):') + 1} "
                     "method (81 lines)"]
    exact = "def at_limit():\n" + "".join(f"    x{i} = {i}\n" for i in range(MAX_LINES - 1))
    assert long_functions(exact, "edge.py") == []
