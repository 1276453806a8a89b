"""Import direction of the project (docs/architecture.md, "Package map"): parsed from the source (ast), so a
lazy import inside a function counts as well.

sim            imports nothing of the project
pipeline.core  imports sim at most
surrogate      imports sim and pipeline.core at most (the library never imports the application)
workflows      pipeline.datasets / optimise / diagnosis / maps / report / tracking / training never import pipeline.cli
pipeline.cli   imported by nobody but itself (the console entry ``vibro = pipeline.cli:main``)
and the graph between packages has no cycle.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PROJECT = ("sim", "surrogate", "pipeline")


def unit(module: str) -> str:
    """The architectural unit of a dotted module: sim, surrogate, or pipeline.<package>."""
    parts = module.split(".")
    if parts[0] != "pipeline":
        return parts[0]
    return ".".join(parts[:2]) if len(parts) > 1 else "pipeline"


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports_of(path: Path) -> set[str]:
    """Project modules imported anywhere in ``path`` (absolute and relative imports)."""
    mod = module_name(path)
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = mod.split(".") if is_pkg else mod.split(".")[:-1]
                pkg = pkg[:len(pkg) - (node.level - 1)]
                base = ".".join(pkg + ([base] if base else []))
            out.add(base)
            out |= {f"{base}.{a.name}" for a in node.names}   # 'from pipeline import tracking'
    return {m for m in out if m.split(".")[0] in PROJECT}


def graph() -> dict[str, set[str]]:
    """unit -> units it imports (self-edges dropped)."""
    g: dict[str, set[str]] = {}
    for top in PROJECT:
        for f in sorted((ROOT / top).rglob("*.py")):
            src = unit(module_name(f))
            g.setdefault(src, set())
            g[src] |= {unit(m) for m in imports_of(f)} - {src, "pipeline"}
    return g


G = graph()
WORKFLOWS = ("pipeline.datasets", "pipeline.optimise", "pipeline.diagnosis", "pipeline.maps", "pipeline.report",
             "pipeline.tracking", "pipeline.training")
ALLOWED = {
    "sim": set(),
    "pipeline.core": {"sim"},
    "surrogate": {"sim", "pipeline.core"},
}


def test_every_package_is_known():
    known = set(ALLOWED) | set(WORKFLOWS) | {"pipeline", "pipeline.cli"}
    assert set(G) <= known, f"new package(s) {sorted(set(G) - known)}: place them in the layering here and in docs"


@pytest.mark.parametrize("low", sorted(ALLOWED))
def test_lower_layers_import_only_below(low):
    assert G.get(low, set()) <= ALLOWED[low], f"{low} imports {sorted(G[low] - ALLOWED[low])}"


def test_nothing_imports_the_cli():
    users = sorted(u for u, deps in G.items() if "pipeline.cli" in deps)
    assert users == [], f"{users} import pipeline.cli"


def test_no_cycle_between_packages():
    state: dict[str, int] = {}

    def visit(u, path):
        state[u] = 1
        for v in sorted(G.get(u, ())):
            if state.get(v) == 1:
                raise AssertionError("import cycle: " + " -> ".join(path + [u, v]))
            if not state.get(v):
                visit(v, path + [u])
        state[u] = 2

    for u in sorted(G):
        if not state.get(u):
            visit(u, [])


def test_the_check_sees_a_violation(tmp_path):
    """The parser finds lazy and relative imports (so the assertions above can fail)."""
    p = ROOT / "pipeline" / "core" / "names.py"
    assert unit("pipeline.cli.sweep") == "pipeline.cli" and unit("sim.models.drill") == "sim"
    src = tmp_path / "x.py"
    src.write_text("def f():\n    from pipeline.cli import main\n    import surrogate.bundle\n")
    ast_mods = set()
    for node in ast.walk(ast.parse(src.read_text())):
        if isinstance(node, ast.ImportFrom):
            ast_mods.add(node.module)
        elif isinstance(node, ast.Import):
            ast_mods |= {a.name for a in node.names}
    assert {"pipeline.cli", "surrogate.bundle"} <= ast_mods and p.exists()


# --- no module outside sim/models names a model (issue 11: ModelSpec owns everything about a model) -------------
TEXT_KEYWORDS = ("help", "epilog", "description", "usage")
"""argparse keyword texts: they may name models as examples for the user."""
TEXT_NAMES = re.compile(r"^(EPILOG|DESCRIPTION|HELP|USAGE)(_\w+)?$|^\w+_(EPILOG|DESCRIPTION|HELP)$")
"""Module-level CLI help texts (``EPILOG = \"\"\"...\"\"\"``) passed to argparse."""
NAMED_TODAY = {
    ("pipeline/cli/synth.py", "indenter-metal"): "the --system default of `vibro synth`",
    ("pipeline/cli/args.py", "give a MODEL (e.g. drill; 'vibro models' lists them) or --rig FILE"): "an example in an error",
}
"""The few literals that name a model today, each with why; a new one fails the test."""


def model_name_literals(path: Path, names: tuple[str, ...]) -> list[tuple[int, str]]:
    """(line, text) of every string constant in ``path`` that names a model, except docstrings, bare string
    statements, argparse help/epilog/description/usage texts and module-level help-text constants."""
    pat = re.compile(r"(?<![\w-])(" + "|".join(map(re.escape, names)) + r")(?![\w-])")
    tree = ast.parse(path.read_text(), str(path))
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):      # docstrings, bare strings
            skip.add(id(node.value))
        elif isinstance(node, ast.keyword) and node.arg in TEXT_KEYWORDS:
            skip |= {id(n) for n in ast.walk(node.value)}
        elif isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and TEXT_NAMES.match(t.id)
                                                  for t in node.targets):
            skip |= {id(n) for n in ast.walk(node.value)}
    return [(n.lineno, n.value) for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)
            and id(n) not in skip and pat.search(n.value)]


def test_no_model_name_outside_the_models():
    import sim

    names = sim.model_names()
    found = {(str(f.relative_to(ROOT)), text): line for top in ("pipeline", "surrogate")
             for f in sorted((ROOT / top).rglob("*.py")) for line, text in model_name_literals(f, names)}
    new = sorted(f"{f}:{line}: {text[:70]!r}" for (f, text), line in found.items() if (f, text) not in NAMED_TODAY)
    assert new == [], "model names outside sim/models (put the knowledge in the model's ModelSpec):\n" + "\n".join(new)


def test_the_model_name_scan_sees_a_literal(tmp_path):
    """The scan finds a model name in code but not in a docstring, a help text or a longer word."""
    src = tmp_path / "x.py"
    src.write_text('"""drill"""\nEPILOG = "drill"\ndef f(p):\n    """drill"""\n    p.add_argument("--m", help="drill")\n'
                   '    if p == "drill":\n        return "drilling", "indenter-metals"\n')
    assert model_name_literals(src, ("drill", "indenter-metal")) == [(6, "drill")]
