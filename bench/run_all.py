"""Run every benchmark: each ``bench/bench_*.py`` module's ``main(quick)`` (or ``main()``) in turn.

``python -m bench.run_all [--quick] [--only sim,optimise]``; ``make bench`` runs the full set.
A failing benchmark is reported and the others still run; the exit code is 1 if any failed.
Benchmarks whose ``main`` parses its own arguments get the reduced profile of :data:`ARGS` (the full set
stays under ~20 minutes on 2 shared cores) or, with ``--quick``, :data:`QUICK_ARGS`.
"""
from __future__ import annotations

import argparse
import importlib
import inspect
import sys
import time
import traceback
from pathlib import Path

BENCH_DIR = Path(__file__).resolve().parent
# argparse mains: the arguments ``make bench`` gives them (reduced but honest: smaller budget / grid / point
# count than their own defaults, every method still run); ``--quick`` is smaller still
ARGS = {"bench_optimise": ["--budget", "300", "--grid", "16", "12", "12", "--initial", "200", "--rounds", "1"],
        "bench_sweep": ["--points", "256", "--peer-points", "8"], "bench_search": ["--seeds", "0"]}
QUICK_ARGS = {"bench_search": ["--budget", "60", "--seeds", "0", "--cases", "lab", "--scan", "8", "4", "4", "--refine",
                                "3", "--results", str(BENCH_DIR / "results" / "quick")],
              "bench_optimise": ["--budget", "80", "--grid", "4", "4", "4", "--initial", "60", "--rounds", "1",
                                 "--results", str(BENCH_DIR / "results" / "quick")],
              "bench_design": ["--sizes", "64", "--regressors", "gbt", "--classifiers", "gbt", "--test-interior", "128",
                               "--test-boundary", "64", "--no-doc",
                               "--out", str(BENCH_DIR / "results" / "quick" / "design.json")],
              "bench_sweep": ["--points", "32", "--peer-points", "2",
                              "--out", str(BENCH_DIR / "results" / "quick" / "sweep.json")],   # never the full results
              "bench_sweep_dask": ["--points", "256", "--repeat", "1", "--no-doc",
                                   "--out", str(BENCH_DIR / "results" / "quick" / "sweep_dask.json")]}


def modules() -> list[str]:
    return sorted(p.stem for p in BENCH_DIR.glob("bench_*.py"))


def call_main(main, quick: bool, argv: list[str] | None = None):
    """``main(quick=...)`` if main takes ``quick``; ``main(argv or [])`` if it takes ``argv`` (an argparse main:
    it gets no run_all flags, since it may not know ``--quick``, only ``argv``); else ``main()``."""
    try:
        params = inspect.signature(main).parameters
    except (TypeError, ValueError):
        params = {}
    if "quick" in params:
        return main(quick=quick)
    if "argv" in params:
        return main(list(argv or []))
    return main()


def run(names: list[str], quick: bool) -> int:
    failed = []
    saved_argv = sys.argv
    for name in names:
        print(f"\n=== bench.{name} {'(quick)' if quick else ''} ===", flush=True)
        t0 = time.perf_counter()
        try:
            sys.argv = [f"bench.{name}"]      # a main() that parses argv sees no run_all flags
            mod = importlib.import_module(f"bench.{name}")
            main = getattr(mod, "main", None)
            if main is None:
                raise AttributeError(f"bench/{name}.py has no main()")
            call_main(main, quick, (QUICK_ARGS if quick else ARGS).get(name))
        except SystemExit as e:
            if e.code not in (0, None):
                failed.append(name)
                print(f"=== bench.{name} exited with {e.code}", flush=True)
        except Exception:  # noqa: BLE001 -- one broken benchmark must not hide the others
            failed.append(name)
            traceback.print_exc()
        finally:
            sys.argv = saved_argv
        print(f"=== bench.{name} done in {time.perf_counter() - t0:.0f} s", flush=True)
    if failed:
        print(f"\nfailed: {', '.join(failed)}", flush=True)
        return 1
    print(f"\nall benchmarks done ({', '.join(names)}); results in {BENCH_DIR / 'results'}", flush=True)
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.run_all", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short versions (fewer points and repeats)")
    ap.add_argument("--only", default="", help="comma-separated subset, e.g. 'sim' or 'bench_sim,optimise'")
    args = ap.parse_args(argv)
    names = modules()
    if args.only:
        want = {w.strip() if w.strip().startswith("bench_") else f"bench_{w.strip()}" for w in args.only.split(",")}
        unknown = want - set(names)
        if unknown:
            ap.error(f"unknown benchmark(s) {sorted(unknown)}; known: {', '.join(names)}")
        names = [n for n in names if n in want]
    return run(names, args.quick)


if __name__ == "__main__":
    sys.exit(main())
