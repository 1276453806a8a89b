"""Import direction of the project (docs/architecture.md, "Package map"): parsed from the source (ast), so a
lazy import inside a function counts as well.

vibrobase      imports nothing of the project (the bottom floor: errors, atomic files, JSON, statuses, unit cube)
sim            imports vibrobase at most
pipeline.core  imports sim and vibrobase at most
surrogate      imports sim and vibrobase at most (the library never imports the application, and raises its own errors)
workflows      pipeline.datasets / synthesis / optimise / comparison / diagnosis / maps / report / tracking / training
               never import pipeline.cli
pipeline.cli   imported by nobody but itself (the console entry ``vibro = pipeline.cli:main``)
and the graph between packages has no cycle.  Within vibrobase, sim and surrogate no two modules import each other
(directly or round a longer loop), and no module imports a private name (``_name``) of another package.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PROJECT = ("vibrobase", "sim", "surrogate", "pipeline")


def unit(module: str) -> str:
    """The architectural unit of a dotted module: vibrobase, sim, surrogate, or pipeline.<package>."""
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
WORKFLOWS = ("pipeline.datasets", "pipeline.synthesis", "pipeline.optimise", "pipeline.comparison", "pipeline.diagnosis",
             "pipeline.maps", "pipeline.report", "pipeline.tracking", "pipeline.training")
ALLOWED = {
    "vibrobase": set(),
    "sim": {"vibrobase"},
    "pipeline.core": {"sim", "vibrobase"},
    "surrogate": {"sim", "vibrobase"},
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



# --- modules: no import cycle within vibrobase, sim and surrogate; no private name of another package ----------
MODULES = {module_name(f): f for top in PROJECT for f in sorted((ROOT / top).rglob("*.py"))}
"""Every project module by dotted name (packages by their own name)."""


def module_named(name: str) -> str:
    """The module an imported dotted name is: itself when a module, else its parent (``sim.api.simulate``)."""
    return name if name in MODULES else name.rpartition(".")[0]


def package_of(module: str) -> str:
    """The package a module belongs to: a package is its own, a module file its parent's."""
    is_pkg = module in MODULES and MODULES[module].name == "__init__.py"
    return module if is_pkg else module.rpartition(".")[0]


def imported_names(source: str, module: str) -> list[tuple[int, str]]:
    """(line, dotted name) of everything ``module`` (source ``source``) imports, anywhere in it: ``import a.b``
    gives ``a.b``, ``from a import b`` gives ``a.b`` (a module or a name of ``a``); relative imports resolved."""
    pkg = package_of(module).split(".")
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(pkg[:len(pkg) - (node.level - 1)] + ([base] if base else []))
            out += [(node.lineno, f"{base}.{a.name}") for a in node.names]
    return out


def module_graph(top: str) -> dict[str, set[str]]:
    """module -> the modules of ``top`` it imports (a lazy import inside a function counts)."""
    graph = {}
    for mod, f in MODULES.items():
        if mod.split(".")[0] == top:
            deps = {module_named(name) for _, name in imported_names(f.read_text(), mod)}
            graph[mod] = {d for d in deps if d.split(".")[0] == top} - {mod}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import loop of ``graph`` (module -> modules it imports) as [a, b, ..., a], or None."""
    state: dict[str, int] = {}          # 1: on the current path, 2: done

    def visit(u: str, path: list[str]) -> list[str] | None:
        state[u] = 1
        for v in sorted(graph.get(u, ())):
            if state.get(v) == 1:
                return (path + [u])[(path + [u]).index(v):] + [v]
            if not state.get(v) and (loop := visit(v, path + [u])):
                return loop
        state[u] = 2
        return None

    for u in sorted(graph):
        if not state.get(u) and (loop := visit(u, [])):
            return loop
    return None


@pytest.mark.parametrize("top", ("vibrobase", "sim", "surrogate"))
def test_no_import_cycle_between_modules(top):
    """A lazy import inside a function counts: it hides a loop from Python, not from a reader."""
    loop = find_cycle(module_graph(top))
    assert loop is None, "import cycle: " + " -> ".join(loop or [])


def test_the_model_spec_and_the_effect_table_do_not_import_each_other():
    graph = module_graph("sim")
    assert "sim.models.fitbound" in graph["sim.models.effects"] and "sim.models.effects" in graph["sim.models.base"]
    assert "sim.models.base" not in graph["sim.models.effects"]


def test_the_cycle_check_sees_a_loop():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None
    assert module_named("sim.layout") == "sim.layout" and module_named("sim.api.simulate") == "sim.api"


def private_imports(source: str, module: str) -> list[tuple[int, str]]:
    """(line, dotted name) of every private name (``_name``, or a name in a ``_private`` module) that ``module``
    imports from another package."""
    own = package_of(module)
    found = []
    for line, name in imported_names(source, module):
        parts = name.split(".")
        first = next((i for i, p in enumerate(parts) if p.startswith("_") and not p.startswith("__")), None)
        if parts[0] not in PROJECT or first is None:
            continue
        owner = ".".join(parts[:first])            # the package or module that holds the private part
        if (package_of(owner) if owner in MODULES else owner) != own:
            found.append((line, name))
    return found


PRIVATE_IMPORTS_TODAY: dict[str, str] = {}
"""Files allowed to import another package's private name for now (path -> why); a new one fails the test."""


def test_no_private_name_of_another_package():
    found = [f"{f.relative_to(ROOT)}:{line}: {name}" for mod, f in MODULES.items()
             for line, name in private_imports(f.read_text(), mod) if str(f.relative_to(ROOT)) not in PRIVATE_IMPORTS_TODAY]
    assert found == [], "private names imported from another package (make them public there):\n" + "\n".join(found)


def test_the_private_name_scan_sees_a_violation():
    """Another package's private name or module is found; a private name of the module's own package is not."""
    src = ("from pipeline.diagnosis.features import _summary\nfrom pipeline.maps.compute import _x\n"
           "def f():\n    import sim._kernel_template\n    from . import _y\n    from ..core import _z\n")
    assert private_imports(src, "pipeline.maps.probe") == [(1, "pipeline.diagnosis.features._summary"),
                                                          (4, "sim._kernel_template"), (6, "pipeline.core._z")]


# --- no module outside sim/models names a model (ModelSpec owns everything about a model) -------------
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
