"""``vibro compile [MODEL ...]``: compile the simulation kernels ahead of time (sim.aot), and optionally warm numba's cache."""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Callable, Iterable, Iterator

ROOT = Path(__file__).resolve().parents[2]


def _sweep_model(root: Path) -> list[str]:
    """params.yaml's ``sweep.model`` (empty outside a checkout)."""
    import yaml

    try:
        return [str(yaml.safe_load((root / "params.yaml").read_text())["sweep"]["model"])]
    except (OSError, KeyError, TypeError, yaml.YAMLError):
        return []


def _diagnosed_systems(root: Path) -> list[str]:
    """The ``system`` column of every measured/*/runs.csv (the datasets the pipeline diagnoses)."""
    import csv

    names: list[str] = []
    for runs in sorted((root / "measured").glob("*/runs.csv")):
        try:
            with runs.open(newline="") as fh:
                names += [row["system"] for row in csv.DictReader(fh) if row.get("system")]
        except (OSError, KeyError, csv.Error):
            continue
    return names


def pipeline_models(root: Path = ROOT) -> tuple[str, ...]:
    """Models `make run`'s pipeline simulates, read from the repository (params.yaml ``sweep.model``, then the
    ``system`` column of every measured/*/runs.csv it diagnoses): compiled first, so a pipeline started early
    finds its kernels built.  Empty outside a checkout."""
    return tuple(dict.fromkeys(_sweep_model(root) + _diagnosed_systems(root)))


def pipeline_kernels(root: Path = ROOT) -> tuple[str, ...]:
    """The kernels `make run` compiles on first use, as ``vibro compile`` arguments: every kernel of the sweep model,
    and the numerical integrator of each other diagnosed system (a diagnosis compares time histories, which only the
    numerical integrator records: ``sim.api``'s exact propagators return none)."""
    sweep = _sweep_model(root)
    return tuple(sweep + [f"{m}:{NUMERICAL}" for m in dict.fromkeys(_diagnosed_systems(root)) if m not in sweep])


NUMERICAL, EXACT = "numerical", "exact"
"""``vibro compile MODEL:VARIANT``: only the numerical integrator, or only the exact propagator."""


def parse_kernel(text: str, known: Iterable[str]) -> tuple[str, str | None]:
    """(model, variant or None: all) of a ``MODEL[:numerical|:exact]`` argument; a clear error naming it."""
    from pipeline.core.errors import UserError
    from vibrobase.errors import did_you_mean

    name, _, variant = text.partition(":")
    known = list(known)
    if name not in known:
        raise UserError(f"unknown model '{name}'{did_you_mean(name, known)}; known models: {', '.join(known)}")
    if variant and variant not in (NUMERICAL, EXACT):
        raise UserError(f"'{text}': the kernel after ':' is '{NUMERICAL}' or '{EXACT}', got '{variant}'")
    return name, variant or None


Job = tuple[str, "str | None", bool, bool]      # (model, exact propagator or None, fill the JIT cache, build the AOT module)
Result = tuple[str, str, "str | None", "float | None"]   # (label, path, error or None, seconds or None: up to date)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "compile", help="compile the models' kernels ahead of time, so 'vibro simulate' starts without numba",
        description="Compile each model's simulation kernels (the numerical integrator and, for the drill, the RIMD "
                    "and the indenters, the exact propagator) into CPython extension modules with numba.pycc.  "
                    "'vibro simulate' and sim.simulate() on the main thread then load them in about a millisecond "
                    "instead of importing numba (about 1 s of CPU per process); the labels are bit-identical to the "
                    "JIT kernel's.  Modules are named by the hash of the kernel's sources and kept beside numba's "
                    "cache ($VIBRO_KERNEL_DIR, else .numba_cache/ in the repository, else ~/.cache/vibro); after a "
                    "change to sim/ the old modules go unused and simulate falls back to the JIT kernel until this "
                    "is rerun.  'make install' does not run it: without these modules each command compiles the "
                    "kernels it uses on first use (numba's cache, once per kernel).  An existing module is not "
                    "rebuilt.  Set VIBRO_NO_AOT=1 to "
                    "ignore the modules.  Kernels are built in parallel processes, those of the models the pipeline "
                    "uses (params.yaml's sweep model, then the systems of measured/*/runs.csv) first; one line per kernel as it finishes, with the "
                    "elapsed time and an estimate of the time left, and the total at the end.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
               "  vibro compile                 # every model: a few minutes on 2 cores; it prints the time it took\n"
               "  vibro compile drill           # the drill's two kernels\n"
               "  vibro compile indenter-metal:numerical   # only its numerical integrator (what a diagnosis uses)\n"
               "  vibro compile --workers 1\n"
               "  vibro compile --jit           # also fill numba's JIT cache (threads: sweeps, batches, diagnosis)\n"
               "  vibro compile --jit-only      # only numba's JIT cache, each kernel once (make test runs it)")
    p.add_argument("models", nargs="*", metavar="MODEL[:KERNEL]",
                   help="models to compile (default: all); MODEL:numerical or MODEL:exact builds only that kernel")
    p.add_argument("--workers", type=int, default=None,
                   help="kernels compiled at once, one process each (default: the number of cores)")
    p.add_argument("--jit", action="store_true", help="also compile the GIL-free JIT kernels into numba's cache "
                                                      "(30-70 s per kernel the first time)")
    p.add_argument("--jit-only", action="store_true",
                   help="only fill numba's JIT cache, no ahead-of-time module: what threads, batches and the test "
                        "suite load; compiled once here instead of by every process that first needs a kernel")
    p.add_argument("--quiet", action="store_true", help="short per-kernel lines (no module paths)")
    p.set_defaults(func=run)


def pipeline_first(names: Iterable[str]) -> list[str]:
    """``names`` with the pipeline's models (in :func:`pipeline_models` order) ahead of the others."""
    names = list(dict.fromkeys(names))
    first = pipeline_models()
    return [n for n in first if n in names] + [n for n in names if n not in first]


def _mmss(seconds: float) -> str:
    s = int(round(max(seconds, 0.0)))
    return f"{s // 60}:{s % 60:02d}"


class CompileClock:
    """One line per finished kernel: ``[k/N] label: built in 41 s; 1:52 elapsed, about 3:10 left``.

    The estimate is the mean build time so far times the kernels still to build, divided by the processes."""

    def __init__(self, n_total: int, workers: int, out=None, now: Callable[[], float] = time.perf_counter):
        self.n_total, self.workers = n_total, max(workers, 1)
        self.out = out or sys.stderr
        self.now = now
        self.t0 = now()
        self.done = 0
        self.built_s: list[float] = []

    def line(self, result: Result, n_left_to_build: int, quiet: bool) -> str:
        """Record ``result`` and return its progress line."""
        label, path, err, seconds = result
        self.done += 1
        elapsed = self.now() - self.t0
        if err is not None:
            state = "failed"
        elif seconds is None:
            state = "up to date"
        else:
            self.built_s.append(seconds)
            state = f"built in {seconds:.0f} s"
        text = f"vibro compile: [{self.done}/{self.n_total}] {label}: {state}; {_mmss(elapsed)} elapsed"
        if n_left_to_build and self.built_s:
            left = sum(self.built_s) / len(self.built_s) * n_left_to_build / min(self.workers, n_left_to_build)
            text += f", about {_mmss(left)} left (estimate)"
        if not quiet and err is None and path:
            text += f": {path}"
        return text

    def emit(self, text: str) -> None:
        self.out.write(text + "\n")
        self.out.flush()

    def total(self, n_built: int, n_current: int, n_failed: int = 0) -> str:
        """The closing line: the measured total wall time."""
        failed = f", {n_failed} failed" if n_failed else ""
        return (f"vibro compile: {n_built + n_current + n_failed} kernels in {_mmss(self.now() - self.t0)} "
                f"({n_built} built, {n_current} up to date{failed}; {self.workers} "
                f"process{'es' if self.workers > 1 else ''})")


def run(args) -> int:
    from pipeline.core.errors import UserError
    from sim import aot, get_model, model_names
    from sim.registry import kernel_variants

    wanted: dict[str, str | None] = {}       # model -> the one kernel asked for (None: all of its kernels)
    for name, variant in (parse_kernel(t, model_names()) for t in args.models):
        wanted[name] = variant if wanted.get(name, variant) == variant else None
    wanted = wanted or dict.fromkeys(model_names())
    names = list(wanted)
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be >= 1, got {args.workers}")
    current: list[Result] = []
    todo: list[Job] = []
    seen = set()
    for n in pipeline_first(names):
        spec = get_model(n)
        for exact in kernel_variants(spec):
            if wanted[n] is not None and (wanted[n] == EXACT) != (exact is not None):
                continue
            if (spec.funcs, exact) in seen:
                continue
            seen.add((spec.funcs, exact))
            path = aot.module_path(spec.funcs, exact)
            if path.exists() and not (args.jit or args.jit_only):     # up to date: no worker started
                current.append((_label(n, exact), str(path), None, None))
            else:
                todo.append((n, exact, args.jit or args.jit_only, not args.jit_only))
    workers = min(args.workers or os.cpu_count() or 1, max(len(todo), 1))
    clock = CompileClock(len(current) + len(todo), workers)
    if todo:
        clock.emit(f"vibro compile: building {len(todo)} kernel{'s' if len(todo) > 1 else ''} in {workers} "
                   f"process{'es' if workers > 1 else ''}, the pipeline's models first; one line per kernel")
    for r in current:
        clock.emit(clock.line(r, len(todo), args.quiet))
    failed: list[Result] = []
    n_current = len(current)        # ... and the jobs that found their kernel already built (seconds None)
    left = len(todo)
    for r in build_all(todo, workers):
        left -= 1
        clock.emit(clock.line(r, left, args.quiet))
        if r[2] is not None:
            failed.append(r)
        elif r[3] is None:
            n_current += 1
    n_built = len(todo) + len(current) - n_current - len(failed)
    clock.emit(clock.total(n_built, n_current, len(failed)))
    if failed:
        label, _, err, _ = failed[0]
        raise UserError(f"ahead-of-time compilation of the {label} kernel failed ({err}); "
                        f"simulate keeps using the JIT kernel")
    return 0


def build_all(todo: list[Job], workers: int) -> Iterator[Result]:
    """:func:`compile_kernel` of every job, yielded as each finishes (``workers`` processes; 1: in this process)."""
    if workers == 1:
        for job in todo:
            yield compile_kernel(*job)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(compile_kernel, *job) for job in todo]     # submitted in order: pipeline first
        for f in as_completed(futures):
            yield f.result()


def _label(model: str, exact: str | None) -> str:
    return f"{model} ({'exact propagator' if exact else 'numerical integrator'})"


def jit_argument_types() -> tuple:
    """The argument types sim.api calls ``run_point`` with (C-contiguous arrays), as a tuple: numba keys its cache by
    what ``compile`` was given, and a call looks its types up, so a kernel compiled from the signature's text would be
    compiled again by the first call."""
    from numba.core import sigutils

    from sim import aot

    args, _ = sigutils.normalize_signature(aot.RUN_POINT_SIGNATURE)
    return tuple(args)


def compile_kernel(model: str, exact: str | None, jit: bool, ahead: bool = True) -> Result:
    """Build one kernel's AOT module (``ahead``) and/or its numba cache (``jit``): (label, path, error or None,
    seconds or None when both were already built).  Runs in a worker process."""
    from sim import aot, get_model
    from sim.compiled import kernel_path, kernels

    spec = get_model(model)
    label = _label(model, exact)
    t0 = time.perf_counter()
    existed = aot.module_path(spec.funcs, exact).exists() or not ahead
    try:
        path = aot.build(spec.funcs, spec.n_bounded, exact) if ahead else kernel_path(spec.funcs, exact)
        if jit:
            run_point = kernels(spec.funcs, spec.n_bounded, exact)
            run_point.compile(jit_argument_types())
            existed = existed and sum(run_point.stats.cache_misses.values()) == 0     # loaded, not compiled
    except Exception as e:  # noqa: BLE001 - a compiler problem: named, and the JIT kernel still serves
        return label, "", f"{type(e).__name__}: {e}", None
    return label, str(path), None, None if existed else time.perf_counter() - t0
