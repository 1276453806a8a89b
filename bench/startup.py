"""Start-up cost of the command line: process CPU seconds of one warm ``vibro simulate drill
--preset lab`` (kernel cache warm: ``vibro compile drill`` and a warm-up run build or load it first) with the
ahead-of-time kernel and, for comparison, with numba's JIT cache (``VIBRO_NO_AOT=1``), of ``vibro --help`` and of
``vibro simulate --help``.

Each command runs as ``python -m pipeline.cli ...`` in a fresh subprocess (what ``bin/vibro`` and the ``vibro``
entry point run), interleaved (A B C A B C ...); CPU = user + sys of the child (``RUSAGE_CHILDREN``), wall
around ``subprocess.run``; medians.  ``PYTHONDONTWRITEBYTECODE`` is removed from the child's environment so the
project's modules load from their ``.pyc`` like in a normal install (with it every run recompiles them,
~0.1 s).  Used by :mod:`bench.bench_precision` (a full run puts the rows in its generated table);
``python -m bench.startup [--reps N] [--root DIR]`` prints them (``--root``: another checkout, e.g. to compare
with an older commit; the kernel cache is this checkout's unless ``VIBRO_KERNEL_DIR`` is set).
Not a test: nothing asserts a timing.
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

_SIM = ("simulate", "drill", "--preset", "lab")
COMMANDS: dict[str, tuple[tuple[str, ...], dict[str, str]]] = {
    "vibro simulate drill --preset lab": (_SIM, {}),
    "VIBRO_NO_AOT=1 vibro simulate drill --preset lab": (_SIM, {"VIBRO_NO_AOT": "1"}),
    "vibro --help": (("--help",), {}),
    "vibro simulate --help": (("simulate", "--help"), {}),
}
"""Label -> (arguments of ``python -m pipeline.cli``, extra environment).  The first row loads the ahead-of-time
kernel (``vibro compile``, sim/aot.py); the second ignores it and loads numba's JIT cache instead."""


def _env(root: Path, extra: dict[str, str] | None = None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONDONTWRITEBYTECODE", "VIBRO_NO_AOT")}
    env["PYTHONPATH"] = os.pathsep.join([str(root), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env.setdefault("VIBRO_KERNEL_DIR", str(ROOT / ".numba_cache"))
    env.update(extra or {})
    return env


def run_once(args: tuple[str, ...], root: Path = ROOT, extra_env: dict[str, str] | None = None) -> tuple[float, float]:
    """(CPU s, wall s) of one ``python -m pipeline.cli *args`` subprocess; RuntimeError if it fails."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "pipeline.cli", *args], cwd=root, env=_env(root, extra_env),
                          capture_output=True, text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"python -m pipeline.cli {' '.join(args)} failed: {proc.stderr.strip().splitlines()[-1:]}")
    return (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime), wall


def startup(reps: int = 5, root: Path = ROOT) -> dict:
    """Medians of ``reps`` interleaved runs of every command of :data:`COMMANDS` after one warm-up run each."""
    root = Path(root)
    load0 = os.getloadavg()
    if (root / "pipeline" / "cli" / "compile.py").exists():
        run_once(("compile", "drill", "--quiet"), root)      # the AOT kernels, if missing (about 70 s)
    for args, extra in COMMANDS.values():
        run_once(args, root, extra)              # warm-up: kernel cache, .pyc files
    runs: dict[str, list[tuple[float, float]]] = {k: [] for k in COMMANDS}
    for _ in range(reps):
        for label, (args, extra) in COMMANDS.items():
            runs[label].append(run_once(args, root, extra))
    rows = [{"command": label, "cpu_s": statistics.median(c for c, _ in r), "wall_s": statistics.median(w for _, w in r),
             "cpu_all": [c for c, _ in r]} for label, r in runs.items()]
    return {"what": "process CPU of one warm command (fresh interpreter, warm kernel cache)", "reps": reps,
            "root": str(root), "rows": rows, "load_avg_before": list(load0), "load_avg_after": list(os.getloadavg())}


def table(res: dict) -> str:
    """Markdown rows of :func:`startup`'s result."""
    lines = ["| command (fresh process, warm kernel cache) | CPU s | wall s |", "|---|---|---|"]
    lines += [f"| `{r['command']}` | {r['cpu_s']:.2f} | {r['wall_s']:.2f} |" for r in res["rows"]]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(prog="python -m bench.startup", description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=5, help="interleaved repetitions (default 5)")
    ap.add_argument("--root", type=Path, default=ROOT, help="checkout whose pipeline.cli runs (default: this one)")
    a = ap.parse_args(argv)
    res = startup(a.reps, a.root)
    print(f"medians of {a.reps} interleaved runs; load average {res['load_avg_before'][0]:.1f} before, "
          f"{res['load_avg_after'][0]:.1f} after")
    print(table(res), end="")
    return res


if __name__ == "__main__":
    main()
