"""Work-precision benchmark: CPU time against label error for every model and method.

For each point (one per model, plus the drill's ``lab``) and each method, the same fixed transient and
window are run (settings min_transient = max_transient = N, window = W) and timed by interleaved
repetitions (method A, B, C, A, B, C, ...: a drift of the shared machine's speed hits every method
alike; a method under 0.1 s is timed right after an untimed call of itself, so every method is timed with warm
caches, ``HOT_BELOW_S``), on one CPU (``pin_to_one_cpu``: the old kernel's worker process shares it, so no method gains from the
faster core); the medians of process CPU time and of wall time are kept, with the load average before and after.
Label error = max relative error over rop_m_s (drill, sandstone), peak_force_n, impacts_per_cycle and
peak_decel_g against the independent reference (tests/reference_solutions.py, DOP853 rtol 1e-10 -- so
errors below ~1e-9 are the reference's own and are reported as "<= 1e-9"); on the drill also against the
exact propagator (itself checked against the reference and DOPRI5 in tests/sim/test_exact_drill.py), which
resolves errors down to ~1e-12.

Methods: the simulator's DOPRI5 kernel (``method="dopri5"``) at rtol 1e-6 ... 1e-11 (drill also 1e-12, for
the x10 target at 1e-10 label error); the exact propagator (``method="exact"``: on the drill exact in every phase,
one row; on the RIMD the hybrid of an exact free flight and DOPRI5 contact, a row per rtol); the baseline
DOPRI5 kernel of commit 33a799c (``bench/baseline.py``: unpacked from git and run in a worker process, interleaved
like the rest; drill rtol 1e-7, 1e-8, 1e-10, 1e-11, 1e-12, the reference of the x10 line; every other model at the
default rtol 1e-7, for the lean-kernel ratio); on the drill the
peers: scipy RK45 / DOP853 in a plain ``solve_ivp`` loop as a user writes it (``bench/peers_scipy.py``), CyRK
``pysolve_ivp`` (``bench/peers_cyrk.py``) and heyoka.py (``bench/peers_heyoka.py``, tol 1e-6 ... 1e-11);
on the other models scipy RK45 (rtol 1e-6, 1e-8) and DOP853 (rtol 1e-8) through the reference harness (no
plain-loop peer written for them), and on the pendulum heyoka.py too (``bench/peers_heyoka_pendulum.py``, tol 1e-6
... 1e-11; ``HEYOKA_PEERS``).  A full run also measures 1- vs 2-worker scaling of ``simulate_batch``
and of ``vibro sweep`` (:mod:`bench.scaling`), and the CPU of one warm ``vibro simulate drill --preset lab`` and of
``vibro --help`` (:mod:`bench.startup`).  Writes ``results/precision.json`` (``--quick``:
``precision_quick.json``) and the table ``results/precision.md`` (summary per error level, the x10 line,
every method, the scaling, the start-up); a full run (or ``--write-readme``) copies that table into the marked blocks of
docs/speed.md and bench/README.md, so the figures quoted there are always this run's.

Run: ``python -m bench.bench_precision [--quick] [--models drill,...] [--merge] [--scaling] [--write-readme] [--reps N]``.  Not a test: nothing asserts a timing.
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

from bench import RESULTS, drill_values, write_between_markers  # noqa: E402
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
SCIPY = (("RK45", 1e-6), ("RK45", 1e-8), ("DOP853", 1e-8))   # (method, rtol) through the reference harness
SCIPY_PLAIN = (("RK45", 1e-6), ("RK45", 1e-8), ("DOP853", 1e-8), ("DOP853", 1e-10))   # drill: plain solve_ivp loop
CYRK = (("RK45", 1e-6), ("RK45", 1e-8), ("DOP853", 1e-8), ("DOP853", 1e-10))          # drill: CyRK pysolve_ivp
HEYOKA_PEERS = {"drill": "bench.peers_heyoka", "pendulum": "bench.peers_heyoka_pendulum"}
"""model -> module of its heyoka.py peer (``values(params)``, ``build(tol)``, ``run_point(ta, values, N, W)``)."""
BASELINE = "baseline"      # method-name prefix of the old kernel (bench/baseline.py); neither simulator nor peer
DEFAULT_RTOL = 1e-7        # sim.Settings().rtol, the tolerance of the lean-kernel ratio;
                           # tests/bench/test_bench_quick.py checks the two agree
BASELINE_RTOLS = (DEFAULT_RTOL, 1e-8, 1e-10, 1e-11, 1e-12)   # drill; the other models: DEFAULT_RTOL only
TARGETS = (1e-6, 1e-8, 1e-9, 1e-10)   # label-error levels of the summary (fastest simulator method vs fastest peer);
                                      # 1e-9 = REF_FLOOR: the finest level the reference resolves on every model
HOT_BELOW_S = 0.1         # methods faster than this are timed right after an untimed call of themselves: in the
                          # interleaved loop the old kernel's worker process otherwise starts every call with caches
                          # the methods before it (seconds of scipy) evicted, while the simulator's rtol rows follow
                          # each other with warm ones
REF_FLOOR = 1e-9          # the reference's own accuracy (DOP853 rtol 1e-10)
START, END = "<!-- bench-table:start -->", "<!-- bench-table:end -->"


_WORKER = []


def _baseline_worker():
    """One worker process of the old tree per benchmark run (started on first use)."""
    if not _WORKER:
        from bench.baseline import BaselineWorker
        _WORKER.append(BaselineWorker())
    return _WORKER[0]


def _methods(model: str, preset, n: int, w: int, quick: bool) -> dict:
    """name -> zero-argument callable returning the labels dict (or a string: why the method is unavailable)."""
    import importlib

    import sim
    from tests.reference_solutions import reference_run

    fixed = {"min_transient": n, "max_transient": n, "window": w}
    out = {}
    rtols = (1e-6, 1e-8, 1e-10) if quick else RTOLS + ((1e-12,) if model == "drill" else ())
    for r in rtols:
        out[f"sim dopri5 rtol {r:.0e}"] = (lambda r=r: sim.simulate(model, preset=preset,
                                                                   settings={**fixed, "rtol": r, "method": "dopri5"}).labels)
    spec = sim.get_model(model)
    if spec.exact is not None and importlib.import_module(spec.exact).EVERY_PHASE:
        out["sim exact"] = lambda: sim.simulate(model, preset=preset, settings={**fixed, "method": "exact"}).labels
    elif spec.exact is not None:    # a hybrid (exact where linear, DOPRI5 elsewhere): its accuracy follows rtol
        for r in rtols:
            out[f"sim hybrid rtol {r:.0e}"] = (lambda r=r: sim.simulate(
                model, preset=preset, settings={**fixed, "rtol": r, "method": "exact"}).labels)
    params = {k: v for k, v in spec.resolve(preset).items() if k not in ("P", "D")}
    try:   # the baseline DOPRI5 kernel (bench/baseline.py), in a worker process
        from bench.baseline import COMMIT
        rtols_old = BASELINE_RTOLS if model == "drill" else (DEFAULT_RTOL,)
        if quick:                                           # --quick: only the x10 line's row
            rtols_old = (1e-12,) if model == "drill" else ()
        worker = _baseline_worker() if rtols_old else None
        for r in rtols_old:
            out[f"{BASELINE} dopri5 rtol {r:.0e} ({COMMIT})"] = (
                lambda r=r: worker.run(model, preset, {**fixed, "rtol": r}))
    except Exception as e:  # noqa: BLE001 -- no git history (e.g. an sdist): reported, not fatal
        out[BASELINE] = f"unavailable ({type(e).__name__}: {e})"
    if model != "drill":
        if not quick:   # no plain-loop peer for these models: scipy through the reference harness
            for meth, r in SCIPY:
                out[f"scipy {meth} rtol {r:.0e} (harness)"] = (lambda meth=meth, r=r: reference_run(
                    model, params, n, w, method=meth, rtol=r, event_subdivisions=1))
        out.update(_heyoka_methods(model, params, n, w, quick))
        return out
    p = drill_values(params)
    from bench import peers_scipy
    for meth, r in (SCIPY_PLAIN[:1] if quick else SCIPY_PLAIN):
        out[f"scipy {meth} rtol {r:.0e}"] = lambda meth=meth, r=r: peers_scipy.run_point(p, n, w, meth, r)
    try:
        from bench import peers_cyrk as C
        C.warm_up()
        for meth, r in (CYRK[:1] if quick else CYRK):
            out[f"CyRK {meth} rtol {r:.0e}"] = lambda meth=meth, r=r: C.run_point(p, n, w, meth, r)
    except Exception as e:  # noqa: BLE001 -- an optional peer that is missing is reported, not fatal
        out["CyRK"] = f"unavailable ({type(e).__name__}: {e})"
    out.update(_heyoka_methods(model, params, n, w, quick))
    return out


def _heyoka_methods(model: str, params: dict, n: int, w: int, quick: bool) -> dict:
    """The model's heyoka peer (``HEYOKA_PEERS``) at each tol: name -> callable, or "heyoka" -> why it is
    unavailable; {} for a model without one."""
    import importlib

    if model not in HEYOKA_PEERS:
        return {}
    out = {}
    try:
        H = importlib.import_module(HEYOKA_PEERS[model])
        p = H.values(params)
        for tol in ((1e-6, 1e-10) if quick else RTOLS):
            ta, _ = H.build(tol)
            out[f"heyoka tol {tol:.0e}"] = (lambda ta=ta: H.run_point(ta, p, n, w))
    except Exception as e:  # noqa: BLE001 -- an optional peer that is missing is reported, not fatal
        out["heyoka"] = f"unavailable ({type(e).__name__}: {e})"
    return out


def pin_to_one_cpu() -> tuple[set | None, int | None]:
    """Pin this process to one CPU (the last it may use) for the timed loop; returns (previous affinity, CPU).

    The old kernel runs in a worker process (``bench/baseline.py``), which inherits the pin.  Unpinned, the worker
    and this process can land on different cores of the shared 2-core machine, whose speeds differ from moment to
    moment: on 2026-11-23 the same drill run took 2.2 ms of CPU pinned to one core and 1.38 ms pinned to the other,
    at the same time.  (None, None) where the platform has no ``sched_setaffinity``."""
    if not hasattr(os, "sched_setaffinity"):
        return None, None
    before = os.sched_getaffinity(0)
    cpu = max(before)
    os.sched_setaffinity(0, {cpu})
    return before, cpu


def run(quick: bool, log=print, models: tuple[str, ...] | None = None, reps: int = 3) -> dict:
    """Time every method at every point (``models``: only these models' points), pinned to one CPU with the old
    kernel's worker (``pin_to_one_cpu``); returns the result dict."""
    import sim
    from tests.reference_solutions import reference_run

    points = POINTS[:1] + POINTS[2:3] if quick else POINTS
    if models:
        points = [pt for pt in POINTS if pt[0] in models]
        points = [pt for i, pt in enumerate(points) if not quick or i == 0]
    res = {"machine": machine_info(), "repetitions": reps, "points": []}
    affinity, res["machine"]["pinned_cpu"] = pin_to_one_cpu()
    try:
        for model, pid, preset, n, w in points:
            params = {k: v for k, v in sim.get_model(model).resolve(preset).items() if k not in ("P", "D")}
            ref = reference_run(model, params, n, w, method="DOP853", rtol=1e-10)
            meths = _methods(model, preset, n, w, quick)
            callables = {k: v for k, v in meths.items() if callable(v)}
            hot = {}
            for k, fn in callables.items():        # warm-up: kernel load, LLVM build (the baseline's compile)
                fn()
                c0 = time.process_time()
                fn()
                hot[k] = time.process_time() - c0 < HOT_BELOW_S
            cpu = {k: [] for k in callables}
            wall = {k: [] for k in callables}
            last = {}
            load0 = os.getloadavg()
            for _ in range(reps):                  # interleaved: A B C A B C ...
                for k, fn in callables.items():
                    if hot[k]:                     # same cache state for every method: each timed call follows one
                        fn()                       # untimed call of itself (see HOT_BELOW_S)
                    c0, t0 = time.process_time(), time.perf_counter()
                    got = fn()
                    w_, c_ = time.perf_counter() - t0, time.process_time() - c0
                    if isinstance(got, tuple):     # timed by its own process (the baseline worker)
                        got, c_, w_ = got
                    last[k] = got
                    wall[k].append(w_)
                    cpu[k].append(c_)
            load1 = os.getloadavg()
            rows = []
            exact = last.get("sim exact")
            for k in callables:
                err = label_error(last[k], ref, model)
                # below the reference's own ~1e-9 only the exact propagator can tell errors apart
                err_x = label_error(last[k], exact, model) if exact is not None and k != "sim exact" else None
                rows.append({"method": k, "cpu_s": statistics.median(cpu[k]), "wall_s": statistics.median(wall[k]),
                             "cpu_all": cpu[k], "label_error": err, "error_vs_exact": err_x,
                             "n_steps": last[k].get("n_steps")})      # accepted steps (the kernels' label; peers: None)
                log(f"{model:18s} {pid:12s} {k:30s} cpu {rows[-1]['cpu_s'] * 1e3:9.2f} ms  "
                    f"wall {rows[-1]['wall_s'] * 1e3:9.2f} ms  err {err:.2e}"
                    + (f"  vs exact {err_x:.2e}" if err_x is not None else ""))
            res["points"].append({"model": model, "point": pid, "transient": n, "window": w, "rows": rows,
                                  "load_avg_before": list(load0), "load_avg_after": list(load1),
                                  "unavailable": {k: v for k, v in meths.items() if not callable(v)}})
    finally:                                   # the old kernel's worker lives for this run only
        if _WORKER:
            _WORKER.pop().close()
        if affinity is not None:               # the scaling runs that follow need both cores
            os.sched_setaffinity(0, affinity)
    return res


def effective_error(pt: dict, row: dict) -> float:
    """The error a method is ranked by: on a point with the exact propagator, the distance to it (resolves
    errors to ~1e-12); the exact row itself gets its distance to the closest DOPRI5 row, the old kernel's
    included (an upper bound unless both share an error); elsewhere the error against the reference, floored
    at its accuracy."""
    by = {r["method"]: r for r in pt["rows"]}
    if "sim exact" in by:
        if row["method"] == "sim exact":
            near = [r["error_vs_exact"] for r in pt["rows"]
                    if r["method"].startswith(("sim dopri5", BASELINE)) and r["error_vs_exact"] is not None]
            return min(near) if near else row["label_error"]
        return row["error_vs_exact"]
    return max(row["label_error"], REF_FLOOR)


def summary(res: dict) -> list[dict]:
    """Per point and label-error target: the fastest simulator method and the fastest peer reaching it."""
    out = []
    for pt in res["points"]:
        exact = any(r["method"] == "sim exact" for r in pt["rows"])
        for tgt in TARGETS:
            if tgt < REF_FLOOR and not exact:
                continue                      # the reference cannot resolve that level
            ok = [r for r in pt["rows"] if math.isfinite(effective_error(pt, r)) and effective_error(pt, r) <= tgt]
            sim_ = min((r for r in ok if r["method"].startswith("sim ")), key=lambda r: r["cpu_s"], default=None)
            peer = min((r for r in ok if not r["method"].startswith(("sim ", BASELINE))), key=lambda r: r["cpu_s"],
                       default=None)
            scipy = min((r for r in ok if r["method"].startswith("scipy ")), key=lambda r: r["cpu_s"], default=None)
            out.append({"model": pt["model"], "point": pt["point"], "target": tgt,
                        "sim": sim_ and sim_["method"], "sim_cpu_s": sim_ and sim_["cpu_s"],
                        "peer": peer and peer["method"], "peer_cpu_s": peer and peer["cpu_s"],
                        "peer_over_sim": (peer["cpu_s"] / sim_["cpu_s"]) if sim_ and peer else None,
                        "scipy_over_sim": (scipy["cpu_s"] / sim_["cpu_s"]) if sim_ and scipy else None})
    return out


def _loosest(rows: list[dict], prefix: str, target: float) -> dict | None:
    """The row of ``prefix`` at the loosest rtol whose labels are within ``target`` of the exact ones."""
    ok = [r for r in rows if r["method"].startswith(prefix) and r["error_vs_exact"] is not None
          and r["error_vs_exact"] <= target]
    return max(ok, key=lambda r: float(r["method"].split("rtol ")[1].split()[0]), default=None)


def lean_vs_old(res: dict) -> list[dict]:
    """Per point, the current DOPRI5 kernel against the baseline one (33a799c), both at the default
    rtol, with their label errors (vs the exact propagator on the drill, else vs the reference); where the model has
    a hybrid propagator (exact where the model is linear, DOPRI5 elsewhere: the RIMD's contact, the indenters'
    friction reversals; what ``simulate`` runs by default there) a second row sets it against the same old kernel."""
    out = []
    for pt in res["points"]:
        by = {r["method"]: r for r in pt["rows"]}
        old = next((r for k, r in by.items() if k.startswith(f"{BASELINE} dopri5 rtol {DEFAULT_RTOL:.0e}")), None)
        for kind in ("dopri5", "hybrid"):
            new = by.get(f"sim {kind} rtol {DEFAULT_RTOL:.0e}")
            if new and old:
                out.append({"model": pt["model"], "point": pt["point"], "method": kind, "old_cpu_s": old["cpu_s"],
                            "new_cpu_s": new["cpu_s"], "ratio": old["cpu_s"] / new["cpu_s"],
                            "old_error": effective_error(pt, old), "new_error": effective_error(pt, new),
                            "old_steps": old.get("n_steps"), "new_steps": new.get("n_steps")})
    return out


def exact_vs_dopri5(res: dict, target: float = 1e-10) -> list[dict]:
    """The ×10 line: the exact propagator against the baseline DOPRI5 kernel (commit 33a799c,
    bench/baseline.py) and against the current DOPRI5 kernel, each at the loosest rtol whose
    labels are within ``target`` of the exact ones."""
    out = []
    for pt in res["points"]:
        by = {r["method"]: r for r in pt["rows"]}
        if "sim exact" not in by:
            continue
        ex = by["sim exact"]["cpu_s"]
        d = _loosest(pt["rows"], "sim dopri5", target)
        b = _loosest(pt["rows"], BASELINE, target)
        out.append({"model": pt["model"], "point": pt["point"], "exact_cpu_s": ex,
                    "dopri5": d and d["method"], "dopri5_cpu_s": d and d["cpu_s"],
                    "dopri5_error_vs_exact": d and d["error_vs_exact"], "ratio": (d["cpu_s"] / ex) if d else None,
                    "baseline": b and b["method"], "baseline_cpu_s": b and b["cpu_s"],
                    "baseline_error_vs_exact": b and b["error_vs_exact"],
                    "ratio_vs_baseline": (b["cpu_s"] / ex) if b else None})
    return out


def _fmt_err(e: float) -> str:
    if not math.isfinite(e):
        return "failed"
    return f"<= {REF_FLOOR:.0e}" if e <= REF_FLOOR else f"{e:.1e}"


def _loads(points: list[dict]) -> str:
    loads = [pt["load_avg_before"][0] for pt in points] + [pt["load_avg_after"][0] for pt in points]
    return f"{min(loads, default=0):.1f}-{max(loads, default=0):.1f}"


def _rerun(res: dict) -> list[list[str]]:
    """[model, point] of every point a ``--merge`` run re-measured."""
    return [pt for mg in res.get("merged", []) for pt in mg["points"]]


def _merge_notes(res: dict) -> list[str]:
    """One paragraph per ``--merge`` run: which points it re-measured, and how (a later one's points win)."""
    return [line for mg in res.get("merged", []) for line in _merge_note(res, mg)]


def _merge_note(res: dict, mg: dict) -> list[str]:
    rm = mg["machine"]
    keys = {(m, p) for m, p in mg["points"]}
    pts = [pt for pt in res["points"] if (pt["model"], pt["point"]) in keys]
    names = ", ".join(f"{m} `{p}`" for m, p in mg["points"])
    return [f"**Re-run points**: {names} were re-measured on {mg['date']} by `python -m bench.bench_precision "
            f"--models {','.join(mg['models'])} --merge --reps {mg['repetitions']}` ({mg['repetitions']} interleaved "
            f"repetitions, same protocol, simulator on {rm.get('sim_kernel', 'numba JIT kernels')}, load average "
            f"{rm['load_avg_at_start'][0]:.1f} at its start, {_loads(pts)} during its points, heyoka "
            f"{rm.get('heyoka', '?')}); their rows replace the full run's (the line above describes that run, and with "
            f"it every point not re-run, the scaling and the start-up).", ""]


def table(res: dict) -> str:
    """Markdown: the summary (fastest simulator method vs fastest peer per error level), the ×10 line, the
    full work-precision table (every method's CPU and wall median and label error) and the 1-/2-worker scaling."""
    m = res["machine"]
    rerun = _rerun(res)
    base = [pt for pt in res["points"] if [pt["model"], pt["point"]] not in rerun]
    flags = (" --quick" if res.get("quick") else "") + (f" --reps {res['repetitions']}" if res["repetitions"] != 3 else "")
    lines = [f"Generated by `python -m bench.bench_precision{flags}` "
             f"on {m.get('cpu', '?')} ({m.get('cpus')} cores), {res['repetitions']} interleaved repetitions, "
             f"medians of process CPU and wall time (methods under {HOT_BELOW_S:g} s timed right after an untimed call "
             f"of themselves), "
             + (f"every method pinned to CPU {m['pinned_cpu']} (the old kernel's worker process too); "
                if m.get("pinned_cpu") is not None else "unpinned; ")
             + f"simulator on {m.get('sim_kernel', 'numba JIT kernels')}; "
             f"load average {m['load_avg_at_start'][0]:.1f} at the start, "
             f"{f'{_loads(base)} during the points' if base else 'every point re-run (below)'}.  "
             f"Label error vs DOP853 rtol 1e-10 (its own accuracy ~{REF_FLOOR:.0e}); on the drill also vs the "
             f"exact propagator (resolves ~1e-12).", "", *_merge_notes(res),
             "**Fastest method reaching a label error** (drill: error vs the exact propagator; other models: vs the "
             "reference, so 1e-9, its own accuracy, is the finest level there):", "",
             "| model | point | error <= | fastest simulator method | CPU ms | fastest peer | CPU ms | peer / simulator "
             "| fastest scipy / simulator |",
             "|---|---|---|---|---|---|---|---|---|"]
    for s in summary(res):
        sim_ = f"{s['sim']} | {s['sim_cpu_s'] * 1e3:.2f}" if s["sim"] else "none | -"
        peer = f"{s['peer']} | {s['peer_cpu_s'] * 1e3:.2f}" if s["peer"] else "none | -"
        ratio = f"{s['peer_over_sim']:.1f}" if s["peer_over_sim"] else "-"
        sci = f"{s['scipy_over_sim']:.0f}" if s.get("scipy_over_sim") else "-"
        lines.append(f"| {s['model']} | {s['point']} | {s['target']:.0e} | {sim_} | {peer} | {ratio} | {sci} |")
    for x in exact_vs_dopri5(res):
        base = (f"the kernel of the day the issue was filed needs {x['baseline']} (error vs exact "
                f"{x['baseline_error_vs_exact']:.1e}) = {x['baseline_cpu_s'] * 1e3:.2f} ms: **×{x['ratio_vs_baseline']:.1f}**"
                if x.get("baseline") else "the kernel of the day the issue was filed was not run or reached no 1e-10")
        cur = (f"the current DOPRI5 kernel needs {x['dopri5']} (error vs exact {x['dopri5_error_vs_exact']:.1e}) "
               f"= {x['dopri5_cpu_s'] * 1e3:.2f} ms: ×{x['ratio']:.1f}"
               if x["dopri5"] else "no current DOPRI5 rtol in the run reaches 1e-10")
        lines += ["", f"**×10 target, {x['model']} `{x['point']}` at 1e-10 label error**: exact propagator "
                  f"{x['exact_cpu_s'] * 1e3:.2f} ms CPU; {base}; {cur}."]
    lean = lean_vs_old(res)
    if lean:
        lines += ["", f"**Lean kernel (item 2), rtol {DEFAULT_RTOL:.0e} (the default)**: the DOPRI5 kernel of the day the "
                  "issue was filed (`bench/baseline.py`) against the current one, CPU ms and label error (drill: vs the "
                  "exact propagator) and accepted steps (`n_steps`):", "",
                  "| model | point | old kernel | current | current kernel | old / current | steps old / current |",
                  "|---|---|---|---|---|---|---|"]
        for x in lean:
            steps = f"{x.get('old_steps')} / {x.get('new_steps')}" if x.get("old_steps") is not None else "n/a"
            lines.append(f"| {x['model']} | {x['point']} | {x['old_cpu_s'] * 1e3:.2f} ({_fmt_err(x['old_error'])}) | "
                         f"{x.get('method', 'dopri5')} | {x['new_cpu_s'] * 1e3:.2f} ({_fmt_err(x['new_error'])}) | "
                         f"×{x['ratio']:.2f} | {steps} |")
    lines += ["", "**Every method** (scipy rows on the drill: a plain `solve_ivp` loop, `bench/peers_scipy.py`; on the "
              "other models: the reference harness `tests/reference_solutions.py` with solve_ivp's step-end event "
              "check, which restarts every cycle):", "",
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
    if res.get("scaling"):
        from bench.scaling import table as scaling_table
        sc = res["scaling"]
        lines += ["", f"**Two-core scaling** ({sc.get('reps_note', '')}; load average {sc['load_avg_before'][0]:.1f} "
                  f"before, {sc['load_avg_after'][0]:.1f} after; sweep CPU includes the interpreter start and the "
                  f"kernel load, its points/s is the sweep's own sims/s):", "", scaling_table(sc).rstrip("\n")]
    if res.get("startup"):
        from bench.startup import table as startup_table
        st = res["startup"]
        lines += ["", f"**Start-up** (`bench/startup.py`: one command in a fresh interpreter, warm kernel cache; medians of "
                  f"{st['reps']} interleaved runs, process CPU = user + sys; load average {st['load_avg_before'][0]:.1f} "
                  f"before, {st['load_avg_after'][0]:.1f} after):", "", startup_table(st).rstrip("\n")]
    return "\n".join(lines) + "\n"


def write_readmes(md: str) -> list[str]:
    """Replace the text between the bench-table markers in docs/speed.md and bench/README.md."""
    return write_between_markers(ROOT, ("docs/speed.md", "bench/README.md"), START, END, md)


def run_scaling(quick: bool) -> dict:
    """1- vs 2-worker scaling of simulate_batch and of a sweep (see :mod:`bench.scaling`)."""
    from bench import scaling

    load0 = os.getloadavg()
    n_b, r_b, n_s, r_s = (32, 1, 64, 1) if quick else (128, 3, 512, 2)
    out = {"batch": scaling.batch_scaling(n_b, r_b), "sweep": scaling.sweep_scaling(n_s, r_s)}
    out.update(load_avg_before=list(load0), load_avg_after=list(os.getloadavg()),
               reps_note=f"medians of {r_b} (batch) / {r_s} (sweep) interleaved repetitions")
    return out


def sim_kernel_kind(models) -> str:
    """Which kernel ``sim.simulate`` ran on (the benchmark calls it on the main thread): the ahead-of-time modules
    when every model's are built for the current sources (``vibro compile``), else numba's JIT kernels."""
    import sim
    from sim.api import _main_thread_aot       # the rule sim.simulate applies (VIBRO_NO_AOT, built modules)
    from sim.registry import kernel_variants

    specs = [sim.get_model(m) for m in set(models)]
    if not all(_main_thread_aot(s, e) is not None for s in specs for e in kernel_variants(s)):
        return "numba JIT kernels"
    return "ahead-of-time kernels (vibro compile; bit-identical to the JIT kernels)"


def main(quick: bool = False, write_readme: bool | None = None, models: tuple[str, ...] | None = None,
         scaling: bool | None = None, out_dir: Path | None = None, reps: int = 3, merge: bool = False) -> dict:
    """Run, save to ``out_dir`` (default bench/results), and (by default for a full run, as under
    ``make bench``) rewrite the tables in docs/speed.md and bench/README.md.  ``scaling`` defaults to on for a
    full run.  A ``models`` subset is saved as ``precision_subset.json/.md`` and, unless asked, neither measures
    the scaling nor touches the docs: the full run's figures stay where they are quoted.  With ``merge`` the
    subset's points also replace their namesakes in ``precision.json`` (the full run's) and the merged table is
    written as ``precision.md`` (and into the docs with ``write_readme``), with a note naming the re-run points."""
    full = not quick and not models
    if merge and (quick or not models):
        raise ValueError("merge: re-run a --models subset at the full setting (not --quick) into precision.json")
    res = run(quick, models=models, reps=reps)
    res["quick"] = quick
    res["machine"]["sim_kernel"] = sim_kernel_kind(p["model"] for p in res["points"])
    if scaling or (scaling is None and full):
        res["scaling"] = run_scaling(quick)
        from bench.startup import startup

        res["startup"] = startup(reps=2 if quick else 5)
    out_dir = Path(out_dir) if out_dir else RESULTS
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = "precision_quick" if quick else ("precision" if full else "precision_subset")
    md = _save(res, out_dir, stem)
    if merge:
        res = merged(json.loads((out_dir / "precision.json").read_text()), res, models)
        md = _save(res, out_dir, "precision")
    if write_readme or (write_readme is None and full):
        print("table written into", ", ".join(write_readmes(md)) or "no file (markers missing)")
    return res


def _save(res: dict, out_dir: Path, stem: str) -> str:
    """Add the derived tables to ``res``, write ``stem``.json/.md into ``out_dir``; returns the markdown."""
    res["summary"] = summary(res)
    res["exact_vs_dopri5"] = exact_vs_dopri5(res)
    res["lean_vs_old"] = lean_vs_old(res)
    (out_dir / f"{stem}.json").write_text(json.dumps(res, indent=1))
    md = table(res)
    (out_dir / f"{stem}.md").write_text(md)
    return md


def merged(full: dict, sub: dict, models: tuple[str, ...]) -> dict:
    """The full run ``full`` with the points of the subset run ``sub`` in place of its own (new points appended),
    and a note of the re-run (``merged``: its models, points, date, repetitions and machine)."""
    new = {(pt["model"], pt["point"]): pt for pt in sub["points"]}
    new_keys = set(new)
    pts = [new.pop((pt["model"], pt["point"]), pt) for pt in full["points"]] + list(new.values())
    note = {"models": list(models), "points": [[pt["model"], pt["point"]] for pt in sub["points"]],
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "repetitions": sub["repetitions"],
            "machine": sub["machine"]}
    earlier = [{**mg, "points": [q for q in mg["points"] if tuple(q) not in new_keys]} for mg in full.get("merged", [])]
    return {**full, "points": pts, "merged": [mg for mg in earlier if mg["points"]] + [note]}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two points, three rtols, fewer peers, no scaling (development)")
    ap.add_argument("--models", default="", help="comma-separated models to run (default: all points); a subset is "
                    "saved as results/precision_subset.json/.md and leaves the docs' tables alone unless --write-readme")
    ap.add_argument("--scaling", action="store_true", default=None, help="also run the 1-/2-worker scaling (default for a full run, not for --quick or --models)")
    ap.add_argument("--write-readme", action="store_true", default=None,
                    help="copy the table into docs/speed.md and bench/README.md (default for a full run)")
    ap.add_argument("--no-write-readme", dest="write_readme", action="store_false",
                    help="leave the docs' tables alone (e.g. a --models subset)")
    ap.add_argument("--out-dir", type=Path, help="where precision.json/.md go (default bench/results)")
    ap.add_argument("--merge", action="store_true", help="with --models: put the re-run points into the full "
                    "run's results/precision.json/.md in place of theirs (a note in the table names them)")
    ap.add_argument("--reps", type=int, default=3, help="interleaved repetitions per method (default 3; medians)")
    a = ap.parse_args()
    if a.reps < 1:
        ap.error("--reps must be at least 1")
    main(a.quick, a.write_readme, tuple(m for m in a.models.split(",") if m) or None, a.scaling, out_dir=a.out_dir,
         reps=a.reps, merge=a.merge)
