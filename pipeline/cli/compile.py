"""``vibro compile [MODEL ...]``: compile the simulation kernels ahead of time (sim.aot), and optionally warm numba's cache."""
from __future__ import annotations

import argparse
import os
import sys
import time


def add_parser(sub) -> None:
    p = sub.add_parser(
        "compile", help="compile the models' kernels ahead of time, so 'vibro simulate' starts without numba",
        description="Compile each model's simulation kernels (the numerical integrator and, for the drill and the RIMD, the "
                    "exact propagator) into CPython extension modules with numba.pycc.  'vibro simulate' and "
                    "sim.simulate() on the main thread then load them in about a millisecond instead of importing "
                    "numba (about 1 s of CPU per process); the labels are bit-identical to the JIT kernel's.  "
                    "Modules are named by the hash of the kernel's sources and kept beside numba's cache "
                    "($VIBRO_KERNEL_DIR, else .numba_cache/ in the repository, else ~/.cache/vibro); after a change "
                    "to sim/ the old modules go unused and simulate falls back to the JIT kernel until this is rerun.  "
                    "'make install' runs it.  An existing module is not rebuilt.  Set VIBRO_NO_AOT=1 to ignore the "
                    "modules.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
               "  vibro compile                 # every model: about 6 min of CPU the first time (3.5 min on 2 cores)\n"
               "  vibro compile drill           # the drill's two kernels (about 2 min of CPU)\n"
               "  vibro compile --workers 1\n"
               "  vibro compile --jit           # also fill numba's JIT cache (threads: sweeps, batches, diagnosis)")
    p.add_argument("models", nargs="*", metavar="MODEL", help="models to compile (default: all)")
    p.add_argument("--workers", type=int, default=None,
                   help="kernels compiled at once, one process each (default: the number of cores)")
    p.add_argument("--jit", action="store_true", help="also compile the GIL-free JIT kernels into numba's cache "
                                                      "(30-70 s per kernel the first time)")
    p.add_argument("--quiet", action="store_true", help="no per-kernel lines")
    p.set_defaults(func=run)


def run(args) -> int:
    from pipeline.core.errors import UserError
    from sim import aot, get_model, model_names
    from sim.registry import kernel_variants

    names = args.models or list(model_names())
    for n in names:
        if n not in model_names():
            raise UserError(f"unknown model '{n}'; known models: {', '.join(model_names())}")
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be >= 1, got {args.workers}")
    results, todo, seen = [], [], set()
    for n in names:
        spec = get_model(n)
        for exact in kernel_variants(spec):
            if (spec.funcs, exact) in seen:
                continue
            seen.add((spec.funcs, exact))
            path = aot.module_path(spec.funcs, exact)
            if path.exists() and not args.jit:      # up to date: reported without starting a worker
                results.append((_label(n, exact), str(path), None, None))
            else:
                todo.append((n, exact, args.jit))
    workers = min(args.workers or os.cpu_count() or 1, max(len(todo), 1))
    if workers == 1:
        results += [compile_kernel(*job) for job in todo]
    else:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            results += list(pool.map(compile_kernel, *zip(*todo)))
    failed = [r for r in results if r[2] is not None]
    if not args.quiet:
        for label, path, err, seconds in results:
            if err is None:
                state = "up to date" if seconds is None else f"built in {seconds:.0f} s"
                print(f"vibro compile: {label}: {state}: {path}", file=sys.stderr, flush=True)
    if failed:
        label, _, err, _ = failed[0]
        raise UserError(f"ahead-of-time compilation of the {label} kernel failed ({err}); "
                        f"simulate keeps using the JIT kernel")
    return 0


def _label(model: str, exact: str | None) -> str:
    return f"{model} ({'exact propagator' if exact else 'numerical integrator'})"


def compile_kernel(model: str, exact: str | None, jit: bool) -> tuple[str, str, str | None, float | None]:
    """Build one kernel's AOT module (and with ``jit`` its numba cache): (label, path, error or None,
    seconds or None when it was already built).  Runs in a worker process."""
    from sim import aot, get_model
    from sim.compiled import kernels

    spec = get_model(model)
    label = _label(model, exact)
    t0 = time.perf_counter()
    existed = aot.module_path(spec.funcs, exact).exists()
    try:
        path = aot.build(spec.funcs, spec.n_bounded, exact)
        if jit:       # the signature sim.api calls with: C-contiguous arrays
            kernels(spec.funcs, spec.n_bounded, exact).compile(aot.RUN_POINT_SIGNATURE)
    except Exception as e:  # noqa: BLE001 - a compiler problem: named, and the JIT kernel still serves
        return label, "", f"{type(e).__name__}: {e}", None
    return label, str(path), None, None if existed else time.perf_counter() - t0
