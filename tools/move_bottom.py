"""Move the shared infrastructure into the bottom package ``vibrobase`` (issue 42, item 4), idempotently.

Run from the repository root (``python tools/move_bottom.py``; ``--dry-run`` only lists what it would change).
It is written to be re-run after other branches merge: every step checks first and does nothing when its work is
already done, so a second run only rewrites imports that arrived since.

1. ``git mv`` sim/files.py, jsonable.py, unitcube.py, statuses.py, errors.py to vibrobase/ (history kept);
   ``vibrobase/__init__.py`` created when missing.
2. ``ParameterError`` (the simulator's exception about model parameters) leaves the moved errors module for
   ``sim/models/param.py`` (the module of the parameter it judges); ``sim.ParameterError`` stays the public name.
3. The re-export shims ``pipeline/core/files.py`` and ``pipeline/core/jsonable.py`` are removed (refused, with a
   message, if one has grown code of its own); ``pipeline/core/names.py`` stops re-exporting the statuses.
4. Every import in sim/, surrogate/, pipeline/, tests/, bench/, tools/ is rewritten to the one home of each name
   (module imports by module, ``from X import a, b`` split by name when the names now live apart), and dotted
   or path references in comments, docstrings and docs/*.md follow (``sim.files`` -> ``vibrobase.files``).
5. pyproject.toml's package list gains ``vibrobase*``; every dvc.yaml stage that depends on ``sim`` also depends
   on ``vibrobase``.

Imports it cannot rewrite safely (``import sim.errors``, a relative import of a moved module) are listed at the
end for a hand fix; the exit status is then 1.
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BOTTOM = "vibrobase"
MOVED = ("files", "jsonable", "unitcube", "statuses", "errors")
"""Modules of sim/ that move to vibrobase/ unchanged in name."""
SHIMS = ("files", "jsonable", "unitcube")
"""pipeline/core modules that only re-exported a moved module (removed)."""
STATUS_NAMES = ("STATUSES", "SETTLED_STATUSES", "BOUNDED_STATUSES", "IMPACTING_STATUSES")
CODE_DIRS = ("sim", "surrogate", "pipeline", "tests", "bench", "tools", BOTTOM)
SELF = Path(__file__).resolve()

MODULE_MAP = {f"sim.{m}": f"{BOTTOM}.{m}" for m in MOVED if m != "errors"}
MODULE_MAP |= {f"pipeline.core.{m}": f"{BOTTOM}.{m}" for m in SHIMS}
"""Old module -> new module, for every name it held."""


def symbol_home(old: str, name: str, importer: str) -> str | None:
    """The module ``name`` (imported from ``old`` by module ``importer``) lives in now; None: unchanged."""
    if old in MODULE_MAP:
        return MODULE_MAP[old]
    if old == "sim.errors":
        if name == "ParameterError":
            return "sim.models.param" if importer.split(".")[0] == "sim" else "sim"
        return f"{BOTTOM}.errors"
    if old == "pipeline.core.names" and name in STATUS_NAMES:
        return f"{BOTTOM}.statuses"
    if old == "pipeline.core.errors" and name == "ParameterError":
        return "sim"
    if old in ("sim", "pipeline.core") and name in MOVED + SHIMS:
        if old == "sim" and name in MOVED or old == "pipeline.core" and name in SHIMS:
            return BOTTOM        # 'from sim import files' -> 'from vibrobase import files'
    return None


REWRITTEN_FROM = set(MODULE_MAP) | {"sim.errors", "pipeline.core.names", "pipeline.core.errors", "sim",
                                    "pipeline.core"}

TEXT_SUBS = [(re.compile(rf"(?<![\w.]){re.escape(old)}(?![\w])"), new) for old, new in MODULE_MAP.items()]
TEXT_SUBS += [(re.compile(rf"(?<![\w/]){re.escape(old.replace('.', '/'))}\.py\b"), new.replace(".", "/") + ".py")
              for old, new in MODULE_MAP.items()]
TEXT_SUBS += [(re.compile(r"(?<![\w.])sim\.errors\.did_you_mean\b"), f"{BOTTOM}.errors.did_you_mean")]
"""Dotted and path references outside import statements (docstrings, comments, docs)."""

FROM_RE = re.compile(r"^(?P<ind>[ \t]*)from[ \t]+(?P<mod>[\w.]+)[ \t]+import[ \t]+"
                     r"(?P<names>\([^)]*\)|[^\n#]*?)(?P<tail>[ \t]*(?:#[^\n]*)?)$", re.M)
IMPORT_RE = re.compile(r"^(?P<ind>[ \t]*)import[ \t]+(?P<mods>[\w.]+(?:[ \t]+as[ \t]+\w+)?"
                       r"(?:[ \t]*,[ \t]*[\w.]+(?:[ \t]+as[ \t]+\w+)?)*)(?P<tail>[ \t]*(?:#[^\n]*)?)$", re.M)
WIDTH = 120
DROP = "\x00drop-this-line\x00"

problems: list[str] = []
changed: list[str] = []


def git(*args: str, dry: bool) -> None:
    print("git", *args)
    if not dry:
        subprocess.run(["git", "-C", str(ROOT), *args], check=True)


def module_of(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def format_from(ind: str, mod: str, names: list[str], tail: str) -> str:
    line = f"{ind}from {mod} import {', '.join(names)}{tail}"
    if len(line) <= WIDTH or len(names) == 1:
        return line
    head = f"{ind}from {mod} import ("
    rows, cur = [], ""
    for i, n in enumerate(names):
        piece = n + (", " if i < len(names) - 1 else ")")
        if cur and len(head) + len(cur) + len(piece.rstrip()) > WIDTH:
            rows.append(cur.rstrip())
            cur = ""
        cur += piece
    rows.append(cur + tail)
    return head + ("\n" + " " * len(head)).join(rows)


def rewrite_from(m: re.Match, importer: str, path: Path) -> str:
    mod, ind, tail = m["mod"], m["ind"], m["tail"]
    if mod not in REWRITTEN_FROM:
        return m[0]
    raw = m["names"].strip().strip("()")
    raw = re.sub(r"#[^\n]*", "", raw)
    names = [n.strip() for n in raw.replace("\n", " ").split(",") if n.strip()]
    if not names or names == ["*"]:
        if mod in MODULE_MAP or mod == "sim.errors":
            problems.append(f"{path.relative_to(ROOT)}: 'from {mod} import *' (fix by hand)")
        return m[0]
    groups: dict[str, list[str]] = {}
    for n in names:
        base = n.split()[0]
        home = symbol_home(mod, base, importer)
        if home == importer:            # the name is now defined in the importing module itself
            continue
        home = home or mod
        groups.setdefault(home, []).append(n)
    if list(groups) == [mod]:
        return m[0]
    keep_all = "noqa" in tail          # a lint waiver (E402) holds for every split line, a remark for the first
    lines = [format_from(ind, home, ns, tail if i == 0 or keep_all else "")
             for i, (home, ns) in enumerate(groups.items())]
    return "\n".join(lines) if lines else f"{ind}pass" if ind else DROP


def rewrite_import(m: re.Match, path: Path) -> str:
    items = [i.strip() for i in m["mods"].split(",")]
    out = []
    for it in items:
        name, _, alias = (p.strip() for p in it.partition(" as "))
        if name in MODULE_MAP:
            name = MODULE_MAP[name]
        elif name == "sim.errors":
            problems.append(f"{path.relative_to(ROOT)}: 'import {it}' (its names now live apart: fix by hand)")
        out.append(f"{name} as {alias}" if alias else name)
    return f"{m['ind']}import {', '.join(out)}{m['tail']}"


def text_subs(text: str) -> str:
    for pat, new in TEXT_SUBS:
        text = pat.sub(new, text)
    return text


def merge_top_level(text: str) -> str:
    """Fold repeated top-level one-line ``from vibrobase.X import ...`` statements into the first one."""
    pat = re.compile(rf"from ({BOTTOM}\.\w+) import ([^\n#()]+?)([ \t]*#[^\n]*)?")
    lines = text.split("\n")
    first: dict[str, int] = {}
    for i, ln in enumerate(lines):
        m = pat.fullmatch(ln)
        if m is None:
            continue
        if m[1] not in first:
            first[m[1]] = i
            continue
        f = pat.fullmatch(lines[first[m[1]]])
        names = [n.strip() for n in f[2].split(",")]
        names += [n.strip() for n in m[2].split(",") if n.strip() not in names]
        lines[first[m[1]]] = format_from("", m[1], names, f[3] or m[3] or "")
        lines[i] = DROP
    return "\n".join(lines).replace(DROP + "\n", "")


def rewrite_source(path: Path) -> None:
    text = path.read_text()
    importer = module_of(path)
    new = FROM_RE.sub(lambda m: rewrite_from(m, importer, path), text)
    new = IMPORT_RE.sub(lambda m: rewrite_import(m, path), new)
    new = new.replace(DROP + "\n", "").replace(DROP, "")
    new = text_subs(new)
    if new != text:
        new = merge_top_level(new)     # (a wrapped first line is left alone by later merges: it no longer matches)
    for m in re.finditer(r"^[ \t]*from[ \t]+(\.+)([\w.]*)[ \t]+import[ \t]+([^\n]+)", new, re.M):
        if importer.startswith("sim") and (m[2].split(".")[0] in MOVED or
                                           not m[2] and set(re.findall(r"\w+", m[3])) & set(MOVED)):
            problems.append(f"{path.relative_to(ROOT)}: relative import '{m[0].strip()}' (fix by hand)")
    if new != text:
        changed.append(str(path.relative_to(ROOT)))
        if not DRY:
            path.write_text(new)


def move_modules(dry: bool) -> None:
    bottom = ROOT / BOTTOM
    init = bottom / "__init__.py"
    if not init.exists():
        print(f"create {init.relative_to(ROOT)}")
        if not dry:
            bottom.mkdir(exist_ok=True)
            init.write_text('"""The bottom floor: infrastructure every package may import '
                            '(it imports nothing of the project)."""\n')
            subprocess.run(["git", "-C", str(ROOT), "add", str(init)], check=True)
    for m in MOVED:
        src, dst = ROOT / "sim" / f"{m}.py", bottom / f"{m}.py"
        if src.exists() and dst.exists():
            problems.append(f"sim/{m}.py and {BOTTOM}/{m}.py both exist (merge sim/{m}.py into it by hand)")
        elif src.exists():
            git("mv", str(src.relative_to(ROOT)), str(dst.relative_to(ROOT)), dry=dry)


PARAM_CLASS = re.compile(r"\n*^class ParameterError\([\w.]+\):\n(?:[ \t]+[^\n]*\n|\n(?=[ \t]))*", re.M)


def relocate_parameter_error(dry: bool) -> None:
    """``class ParameterError`` from vibrobase/errors.py into sim/models/param.py (after its imports)."""
    errors, param = ROOT / BOTTOM / "errors.py", ROOT / "sim" / "models" / "param.py"
    if not errors.exists():
        return
    etext = errors.read_text()
    m = PARAM_CLASS.search(etext)
    if m is None:
        return
    ptext = param.read_text()
    if "class ParameterError" not in ptext:
        ptext = re.sub(r"^from (?:sim|vibrobase)\.errors import ParameterError[ \t]*(?:#[^\n]*)?\n", "", ptext,
                       flags=re.M)
        imports = list(re.finditer(r"^(?:from|import)[ \t][^\n]*\n", ptext, re.M))
        at = imports[-1].end() if imports else 0
        ptext = ptext[:at] + "\n\n" + m[0].strip("\n") + "\n\n\n" + ptext[at:].lstrip("\n")
        print(f"move class ParameterError -> {param.relative_to(ROOT)}")
        if not dry:
            param.write_text(ptext)
    print(f"{BOTTOM}/errors.py: class ParameterError removed")
    if not dry:
        errors.write_text(etext[:m.start()] + "\n\n\n" + etext[m.end():].lstrip("\n"))


def only_reexports(src: str) -> bool:
    """True when a module holds nothing but a docstring, imports, ``__all__`` and comments."""
    src = re.sub(r'(?s)^\s*(""".*?"""|\'\'\'.*?\'\'\')', "", src)
    src = re.sub(r"(?ms)^from [\w.]+ import \(.*?\)", "", src)
    src = re.sub(r"(?ms)^__all__\s*=\s*[\[(].*?[\])]", "", src)
    src = re.sub(r"(?m)^(from|import) [^\n]*$|^[ \t]*#[^\n]*$", "", src)
    return not src.strip()


def remove_shims(dry: bool) -> None:
    for m in SHIMS:
        p = ROOT / "pipeline" / "core" / f"{m}.py"
        if not p.exists():
            continue
        if not only_reexports(p.read_text()):
            problems.append(f"pipeline/core/{m}.py has code of its own: not removed (move it to {BOTTOM}/{m}.py)")
            continue
        git("rm", "-q", str(p.relative_to(ROOT)), dry=dry)
    names = ROOT / "pipeline" / "core" / "names.py"
    if not names.exists():
        return
    text = orig = names.read_text()
    imp = re.search(r"^from (?:sim|vibrobase)\.statuses import ([^\n]+)\n", text, re.M)
    if imp:
        rest = re.sub(r'(?s)""".*?"""|__all__\s*=\s*\[.*?\]', "", text.replace(imp[0], ""))
        if not any(re.search(rf"\b{n.strip()}\b", rest) for n in imp[1].split(",")):
            text = text.replace(imp[0], "")
    allm = re.search(r"(?s)__all__\s*=\s*\[(.*?)\]", text)
    if allm and not re.search(r"^from \S+ import [^\n]*\bSTATUSES\b", text, re.M):
        items = [i.strip() for i in allm[1].split(",") if i.strip()]
        keep = [i for i in items if i.strip("'\"") not in STATUS_NAMES]
        if keep != items:
            line = "__all__ = [" + ", ".join(keep) + "]"
            text = text[:allm.start()] + line + text[allm.end():]
    if text != orig:
        print("pipeline/core/names.py: status re-exports removed")
        if not dry:
            names.write_text(text)


def update_config(dry: bool) -> None:
    pp = ROOT / "pyproject.toml"
    text = pp.read_text()
    m = re.search(r"^include = \[([^\]]*)\]", text, re.M)
    if m and f'"{BOTTOM}*"' not in m[1]:
        text = text[:m.end(1)] + f', "{BOTTOM}*"' + text[m.end(1):]
        print(f"pyproject.toml: {BOTTOM}* added to the packages")
        if not dry:
            pp.write_text(text)
    dvc = ROOT / "dvc.yaml"
    if dvc.exists():
        lines = dvc.read_text().splitlines(keepends=True)
        out = []
        for i, ln in enumerate(lines):
            out.append(ln)
            m = re.fullmatch(r"([ \t]*)- sim[ \t]*\n?", ln)
            if m:
                j = i - 1          # the whole deps list: contiguous '- ' lines at this indent
                while j >= 0 and re.match(rf"{m[1]}- ", lines[j]):
                    j -= 1
                k = i + 1
                while k < len(lines) and re.match(rf"{m[1]}- ", lines[k]):
                    k += 1
                if not any(re.fullmatch(rf"{m[1]}- {BOTTOM}[ \t]*\n?", x) for x in lines[j + 1:k]):
                    out.append(f"{m[1]}- {BOTTOM}\n")
        if out != lines:
            print(f"dvc.yaml: {BOTTOM} added next to every sim dependency")
            if not dry:
                dvc.write_text("".join(out))


def main(argv: list[str] | None = None) -> int:
    global DRY
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dry-run", action="store_true", help="list what would change, change nothing")
    DRY = ap.parse_args(argv).dry_run
    move_modules(DRY)
    relocate_parameter_error(DRY)
    remove_shims(DRY)
    update_config(DRY)
    files = [p for d in CODE_DIRS if (ROOT / d).is_dir() for p in sorted((ROOT / d).rglob("*.py"))
             if p.resolve() != SELF and "__pycache__" not in p.parts and "results" not in p.relative_to(ROOT).parts]
    for p in files:
        rewrite_source(p)
    for p in sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]:
        if p.exists():
            text = p.read_text()
            new = text_subs(text)
            if new != text:
                changed.append(str(p.relative_to(ROOT)))
                if not DRY:
                    p.write_text(new)
    print(f"{len(changed)} file(s) {'would be ' if DRY else ''}rewritten" + "".join(f"\n  {c}" for c in changed))
    if problems:
        print("to fix by hand:\n  " + "\n  ".join(problems), file=sys.stderr)
    return 1 if problems else 0


DRY = False

if __name__ == "__main__":
    sys.exit(main())
