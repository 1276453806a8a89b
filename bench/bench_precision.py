"""Work-precision benchmark (issue 16): CPU time against label error for every model and method.

For each point (one per model, plus the drill's ``lab``) and each method, the same fixed transient and
window are run (settings min_transient = max_transient = N, window = W) and timed by interleaved
repetitions (method A, B, C, A, B, C, ...: a drift of the shared machine's speed hits every method
alike); the medians of process CPU time and of wall time are kept, with the load average before and after.
Label error = max relative error over rop_m_s (drill, sandstone), peak_force_n, impacts_per_cycle and
peak_decel_g against the independent reference (tests/reference_solutions.py, DOP853 rtol 1e-10 -- so
errors below ~1e-9 are the reference's own and are reported as "<= 1e-9"); on the drill also against the
exact propagator (itself checked against the reference and DOPRI5 in tests/test_exact_drill.py), which
resolves errors down to ~1e-12.

Methods: the simulator's DOPRI5 kernel (``method="dopri5"``) at rtol 1e-6 ... 1e-11; the exact propagator
(``method="exact"``, drill only); scipy RK45 (rtol 1e-6, 1e-8) and DOP853 (rtol 1e-8) through the reference
harness with solve_ivp's step-end event check (``event_subdivisions=1``); heyoka.py (drill, tol 1e-6 ... 1e-11)
when installed.  Writes ``results/precision.json`` (``--quick``: ``precision_quick.json``) and the table
``results/precision.md``; ``--write-readme`` copies that table into the marked blocks of README.md and
bench/README.md, so the figures quoted there are always this run's.

Run: ``python -m bench.bench_precision [--quick] [--write-readme]``.  Not a test: nothing asserts a timing.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench import RESULTS, drill_values  # noqa: E402
from bench.bench_sim import label_error, machine_info  # noqa: E402

POINTS = [  # (model, point id, preset, transient N, window W)
    ("drill", "lab", "lab", 60, 16),
    ("drill", "default", None, 60, 16),
    ("indenter-metal", "table1-60hz", "table1-60hz", 40, 10),
    ("indenter-sandstone", "table1-60hz", "table1-60hz", 40, 10),
    ("pendulum", "default", None, 40, 10),
    ("rimd", "default", None, 40, 10),
]
RTOLS = (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11)
SCIPY = (("RK45", 1e-6), ("RK45", 1e-8), ("DOP853", 1e-8))   # (method, rtol) through solve_ivp
REF_FLOOR = 1e-9          # the reference's own accuracy (DOP853 rtol 1e-10)
START, END = "<!-- bench-table:start -->", "<!-- bench-table:end -->"


def _methods(model: str, preset, n: int, w: int, quick: bool) -> dict:
    """name -> zero-argument callable returning the labels dict."""
    import sim
    from tests.reference_solutions import reference_run

    fixed = {"min_transient": n, "max_transient": n, "window": w}
    out = {}
    rtols = (1e-6, 1e-8, 1e-10) if quick else RTOLS
    for r in rtols:
        out[f"sim dopri5 rtol {r:.0e}"] = (lambda r=r: sim.simulate(model, preset=preset,
                                                                   settings={**fixed, "rtol": r, "method": "dopri5"}).labels)
    if sim.get_model(model).exact is not None:
        out["sim exact"] = lambda: sim.simulate(model, preset=preset, settings={**fixed, "method": "exact"}).labels
    params = {k: v for k, v in sim.get_model(model).resolve(preset).items() if k not in ("P", "D")}
    if not quick:
        for meth, r in SCIPY:
            out[f"scipy {meth} rtol {r:.0e}"] = (lambda meth=meth, r=r: reference_run(
                model, params, n, w, method=meth, rtol=r, event_subdivisions=1))
    if model == "drill":
        try:
            from bench import peers_heyoka as H
            for tol in ((1e-6, 1e-10) if quick else RTOLS):
                ta, _ = H.build(tol)
                out[f"heyoka tol {tol:.0e}"] = (lambda ta=ta: H.run_point(ta, drill_values(params), n, w))
        except Exception as e:  # noqa: BLE001 -- an optional peer that is missing is reported, not fatal
            out["heyoka"] = f"unavailable ({type(e).__name__}: {e})"
    return out


def run(quick: bool, log=print) -> dict:
    import sim
    from tests.reference_solutions import reference_run

    reps = 3
    points = POINTS[:1] + POINTS[2:3] if quick else POINTS
    res = {"machine": machine_info(), "repetitions": reps, "points": []}
    for model, pid, preset, n, w in points:
        params = {k: v for k, v in sim.get_model(model).resolve(preset).items() if k not in ("P", "D")}
        ref = reference_run(model, params, n, w, method="DOP853", rtol=1e-10)
        meths = _methods(model, preset, n, w, quick)
        callables = {k: v for k, v in meths.items() if callable(v)}
        for fn in callables.values():          # warm-up: kernel load, LLVM build
            fn()
        cpu = {k: [] for k in callables}
        wall = {k: [] for k in callables}
        last = {}
        load0 = os.getloadavg()
        for _ in range(reps):                  # interleaved: A B C A B C ...
            for k, fn in callables.items():
                c0, t0 = time.process_time(), time.perf_counter()
                last[k] = fn()
                wall[k].append(time.perf_counter() - t0)
                cpu[k].append(time.process_time() - c0)
        load1 = os.getloadavg()
        rows = []
        exact = last.get("sim exact")
        for k in callables:
            err = label_error(last[k], ref, model)
            # below the reference's own ~1e-9 only the exact propagator can tell errors apart
            err_x = label_error(last[k], exact, model) if exact is not None and k != "sim exact" else None
            rows.append({"method": k, "cpu_s": statistics.median(cpu[k]), "wall_s": statistics.median(wall[k]),
                         "cpu_all": cpu[k], "label_error": err, "error_vs_exact": err_x})
            log(f"{model:18s} {pid:12s} {k:26s} cpu {rows[-1]['cpu_s'] * 1e3:9.2f} ms  "
                f"wall {rows[-1]['wall_s'] * 1e3:9.2f} ms  err {err:.2e}"
                + (f"  vs exact {err_x:.2e}" if err_x is not None else ""))
        res["points"].append({"model": model, "point": pid, "transient": n, "window": w, "rows": rows,
                              "load_avg_before": list(load0), "load_avg_after": list(load1),
                              "unavailable": {k: v for k, v in meths.items() if not callable(v)}})
    return res


def _fmt_err(e: float) -> str:
    if not math.isfinite(e):
        return "failed"
    return f"<= {REF_FLOOR:.0e}" if e <= REF_FLOOR else f"{e:.1e}"


def table(res: dict) -> str:
    """Markdown table: per point, every method's CPU and wall median and label error."""
    m = res["machine"]
    lines = [f"Generated by `python -m bench.bench_precision{' --quick' if res.get('quick') else ''}` "
             f"on {m.get('cpu', '?')} ({m.get('cpus')} cores), {res['repetitions']} interleaved repetitions, "
             f"medians; load average {m['load_avg_at_start'][0]:.1f} at the start.  "
             f"Label error vs DOP853 rtol 1e-10 (its own accuracy ~{REF_FLOOR:.0e}).", "",
             "| model | point | method | CPU ms | wall ms | label error | vs exact (drill) |",
             "|---|---|---|---|---|---|---|"]
    for pt in res["points"]:
        for r in pt["rows"]:
            ex = r.get("error_vs_exact")
            lines.append(f"| {pt['model']} | {pt['point']} | {r['method']} | {r['cpu_s'] * 1e3:.2f} | "
                         f"{r['wall_s'] * 1e3:.2f} | {_fmt_err(r['label_error'])} | "
                         f"{'' if ex is None else f'{ex:.1e}'} |")
        for k, why in pt["unavailable"].items():
            lines.append(f"| {pt['model']} | {pt['point']} | {k} | - | - | {why} | |")
    return "\n".join(lines) + "\n"


def write_readmes(md: str) -> list[str]:
    """Replace the text between the bench-table markers in README.md and bench/README.md."""
    done = []
    for path in (ROOT / "README.md", ROOT / "bench" / "README.md"):
        text = path.read_text()
        if START in text and END in text:
            a = text.index(START) + len(START)
            b = text.index(END)
            path.write_text(text[:a] + "\n" + md + text[b:])
            done.append(str(path.relative_to(ROOT)))
    return done


def main(quick: bool = False, write_readme: bool | None = None) -> dict:
    """Run, save, and (by default for a full run, as under ``make bench``) rewrite the README tables."""
    res = run(quick)
    res["quick"] = quick
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / ("precision_quick.json" if quick else "precision.json")).write_text(json.dumps(res, indent=1))
    md = table(res)
    (RESULTS / ("precision_quick.md" if quick else "precision.md")).write_text(md)
    if write_readme or (write_readme is None and not quick):
        print("table written into", ", ".join(write_readmes(md)) or "no file (markers missing)")
    return res


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two points, three rtols, no scipy (development)")
    ap.add_argument("--write-readme", action="store_true", default=None,
                    help="copy the table into README.md and bench/README.md (default for a full run)")
    a = ap.parse_args()
    main(a.quick, a.write_readme)
