"""Simulator benchmark: the jitted simulator against scipy RK45 and against the strongest peers.

For each model of ``sim.model_names()`` that imports, a few representative points are run with the SAME
fixed transient and window (settings min_transient = max_transient = N, window = W) by
  * the jitted simulator (``sim.simulate``; warm median of >= 3 repeats, first call timed separately),
  * scipy RK45 at rtol 1e-6 with event location (``tests.reference_solutions.reference_run(method="RK45",
    rtol=1e-6)`` -- what a user would otherwise write; its events are searched on 16 sub-intervals of each
    step, and in the full run also ``event_subdivisions=1``, solve_ivp's own step-end sign check),
  * the tight reference (DOP853, rtol 1e-10, computed once per point) that gives every label error.
Label error = max relative error over rop_m_s (drill, sandstone), peak_force_n, impacts_per_cycle and
peak_decel_g.  On the drill points also the peers: heyoka.py (Taylor + events, :mod:`bench.peers_heyoka`)
and CyRK (``pysolve_ivp`` + events, :mod:`bench.peers_cyrk`).  Batch: 64 drill points (one frequency, F0 x Fs
grid) through ``sim.simulate_batch`` with 1 and 2 threads, heyoka's per-point loop and ensemble mode, CyRK.
Writes ``bench/results/sim.json``.  Not a test: nothing here asserts a timing.

Run: ``python -m bench.bench_sim [--quick]`` (or ``make bench`` for every benchmark).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:            # tests/ (the reference) is not an installed package
    sys.path.insert(0, str(ROOT))

from bench import RESULTS, drill_values  # noqa: E402

RTOL_USER = 1e-6
COMPARED = ("rop_m_s", "peak_force_n", "impacts_per_cycle", "peak_decel_g")

# model -> list of (point id, preset, overrides); transient / window cycles per model
POINTS = {
    "drill": [("default", None, {}),
              ("lab", "lab", {}),
              ("gap-p2", None, {"frequency_hz": 164.5399032646247, "amplitude_n": 1213.6447136247984,
                                "static_force_n": 1001.9234472396665, "gap_m": 5e-4})],
    "indenter-metal": [("table1-60hz", "table1-60hz", {}), ("table1-90hz", "table1-90hz", {})],
    "indenter-sandstone": [("table1-60hz", "table1-60hz", {}), ("table1-90hz", "table1-90hz", {})],
    "pendulum": [("default", None, {})],
    "rimd": [("default", None, {})],
}
CYCLES = {"drill": (60, 16), "indenter-metal": (40, 10), "indenter-sandstone": (40, 10),
          "pendulum": (40, 10), "rimd": (40, 10)}


def machine_info() -> dict:
    import numba
    import scipy

    info = {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count(),
            "numpy": np.__version__, "numba": numba.__version__, "scipy": scipy.__version__,
            "load_avg_at_start": list(os.getloadavg())}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    for mod in ("heyoka", "CyRK"):
        try:
            info[mod] = __import__(mod).__version__
        except Exception as e:  # noqa: BLE001 -- a missing peer is reported, not fatal
            info[mod] = f"unavailable ({type(e).__name__}: {e})"
    return info


def label_error(got: dict, ref: dict, model: str) -> float:
    """Max relative error of the compared labels (rop only where the model progresses)."""
    errs = []
    for k in COMPARED:
        if k == "rop_m_s" and model not in ("drill", "indenter-sandstone"):
            continue
        g, r = got.get(k), ref.get(k)
        if g is None or r is None:
            return math.inf
        errs.append(abs(float(g) - float(r)) / max(abs(float(r)), 1e-12))
    return max(errs)


def label_errors(got: dict, ref: dict, model: str) -> dict:
    """Relative error of each compared label (which one dominates :func:`label_error`)."""
    out = {}
    for k in COMPARED:
        if k == "rop_m_s" and model not in ("drill", "indenter-sandstone"):
            continue
        g, r = got.get(k), ref.get(k)
        out[k] = math.inf if g is None or r is None else abs(float(g) - float(r)) / max(abs(float(r)), 1e-12)
    return out




def _timed(fn, repeats: int):
    """Median wall time of ``repeats`` calls, all wall times, last result.  The CPU time of each call
    (process CPU, valid for single-threaded calls) is kept in ``_timed.cpu`` -- on a machine shared with
    other jobs the wall time of a call includes waiting for a core, its CPU time does not."""
    times, cpus, out = [], [], None
    for _ in range(repeats):
        c0, t0 = time.process_time(), time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    _timed.cpu = statistics.median(cpus)
    return statistics.median(times), times, out


def _ref_params(spec, preset, overrides) -> dict:
    return {k: v for k, v in spec.resolve(preset, **overrides).items() if k not in ("P", "D")}


def cold_compile_seconds(model: str) -> float | None:
    """Wall time of a first ``simulate`` with an empty kernel cache (fresh process, temporary
    VIBRO_KERNEL_DIR, so the project's cache is left alone)."""
    code = ("import time, sim; t=time.perf_counter(); "
            f"sim.simulate({model!r}, settings={{'min_transient': 1, 'max_transient': 1, 'window': 2}}); "
            "print(time.perf_counter()-t)")
    with tempfile.TemporaryDirectory(prefix="vibro-bench-kernels-") as d:
        env = dict(os.environ, VIBRO_KERNEL_DIR=d, NUMBA_CACHE_DIR=d)
        try:
            r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=900,
                               cwd=str(ROOT))
            return float(r.stdout.strip().splitlines()[-1])
        except Exception:  # noqa: BLE001
            return None


def bench_points(quick: bool, log) -> tuple[list[dict], dict]:
    import sim
    from tests.reference_solutions import reference_run

    rows, first_call = [], {}
    for model in sim.model_names():
        try:
            spec = sim.get_model(model)
        except Exception as e:  # noqa: BLE001 -- a model being added elsewhere may not import yet
            log(f"  {model}: skipped ({type(e).__name__}: {e})")
            continue
        N, W = CYCLES.get(model, (40, 10))
        settings = {"min_transient": N, "max_transient": N, "window": W}
        pts = POINTS.get(model, [("default", None, {})])
        if quick:
            pts = pts[:1]
        for pid, preset, ov in pts:
            try:
                kw = dict(preset=preset, settings=settings, **ov)
                if model not in first_call:
                    t0 = time.perf_counter()
                    sim.simulate(model, **kw)
                    first_call[model] = time.perf_counter() - t0
                t_jit, jit_times, res = _timed(lambda: sim.simulate(model, **kw), 3 if quick else 5)
                c_jit = _timed.cpu
                jit = res.labels
                rp = _ref_params(spec, preset, ov)
                ref = reference_run(model, rp, N, W, method="DOP853", rtol=1e-10)
                _, _, rk = _timed(lambda: reference_run(model, rp, N, W, method="RK45", rtol=RTOL_USER), 1)
                c_rk = _timed.cpu
                row = {"model": model, "point": pid, "preset": preset, "overrides": ov, "transient": N, "window": W,
                       "status_jit": jit["status"], "t_jit_s": t_jit, "t_jit_all_s": jit_times,
                       "t_ref_dop853_s": ref["wall_s"], "t_rk45_s": rk["wall_s"],
                       "ratio_rk45": rk["wall_s"] / t_jit, "cpu_jit_s": c_jit, "cpu_rk45_s": c_rk,
                       "cpu_ratio_rk45": c_rk / c_jit,
                       "err_jit": label_error(jit, ref, model), "err_rk45": label_error(rk, ref, model),
                       "errs_jit": label_errors(jit, ref, model), "errs_rk45": label_errors(rk, ref, model),
                       "labels_ref": {k: ref[k] for k in COMPARED}, "labels_jit": {k: jit[k] for k in COMPARED},
                       "labels_rk45": {k: rk[k] for k in COMPARED}, "n_events_ref": ref["n_events"],
                       "n_steps_jit": jit["n_steps"]}
                if not quick:
                    rk1 = reference_run(model, rp, N, W, method="RK45", rtol=RTOL_USER, event_subdivisions=1)
                    row.update(t_rk45_plain_s=rk1["wall_s"], ratio_rk45_plain=rk1["wall_s"] / t_jit,
                               err_rk45_plain=label_error(rk1, ref, model))
                rows.append(row)
                log(f"  {model:18s} {pid:12s} t_jit {t_jit * 1e3:8.2f} ms  t_rk45 {rk['wall_s']:7.2f} s  "
                    f"x{row['ratio_rk45']:5.0f} (CPU x{row['cpu_ratio_rk45']:5.0f})  err_jit {row['err_jit']:.1e}  err_rk45 {row['err_rk45']:.1e}")
            except Exception as e:  # noqa: BLE001 -- report, keep benchmarking the rest
                log(f"  {model} {pid}: FAILED ({type(e).__name__}: {e})")
                rows.append({"model": model, "point": pid, "error": f"{type(e).__name__}: {e}"})
    return rows, first_call


def bench_peers(rows: list[dict], quick: bool, log) -> dict:
    """heyoka and CyRK on the drill points of ``rows`` (same transient / window)."""
    import sim

    spec = sim.get_model("drill")
    out = {"points": []}
    hy_ta = {}
    try:
        from bench import peers_heyoka as ph
        for name, tol in (("heyoka", None), ("heyoka_tol1e-10", 1e-10)):
            ta, tc = ph.build(tol=tol)
            hy_ta[name] = ta
            out[f"{name}_compile_s"] = tc
        log(f"  heyoka JIT compile: {out['heyoka_compile_s']:.2f} s (tol eps), "
            f"{out['heyoka_tol1e-10_compile_s']:.2f} s (tol 1e-10)")
    except Exception as e:  # noqa: BLE001
        out["heyoka_error"] = f"{type(e).__name__}: {e}"
        log(f"  heyoka unavailable: {out['heyoka_error']}")
    cy = None
    try:
        from bench import peers_cyrk as cy
        t0 = time.perf_counter()
        cy.warm_up()
        out["cyrk_numba_compile_s"] = time.perf_counter() - t0
    except Exception as e:  # noqa: BLE001
        cy = None
        out["cyrk_error"] = f"{type(e).__name__}: {e}"
        log(f"  CyRK unavailable: {out['cyrk_error']}")
    for row in rows:
        if row.get("model") != "drill" or "error" in row:
            continue
        p = drill_values(spec.resolve(row["preset"], **row["overrides"]))
        N, W = row["transient"], row["window"]
        ref = row["labels_ref"]
        pr = {"point": row["point"], "t_jit_s": row["t_jit_s"], "cpu_jit_s": row["cpu_jit_s"], "err_jit": row["err_jit"]}
        reps = 3 if quick else 5
        for name, ta in hy_ta.items():
            try:
                t, _, lab = _timed(lambda: ph.run_point(ta, p, N, W), reps)
                pr[f"t_{name}_s"], pr[f"err_{name}"] = t, label_error(lab, ref, "drill")
                pr[f"ratio_{name}_over_jit"] = t / row["t_jit_s"]
                pr[f"cpu_ratio_{name}_over_jit"] = _timed.cpu / row["cpu_jit_s"]
            except Exception as e:  # noqa: BLE001
                pr[f"{name}_error"] = f"{type(e).__name__}: {e}"
        if cy is not None:
            try:
                t, _, lab = _timed(lambda: cy.run_point(p, N, W), 1 if quick else 3)
                pr["t_cyrk_s"], pr["err_cyrk"] = t, label_error(lab, ref, "drill")
                pr["ratio_cyrk_over_jit"] = t / row["t_jit_s"]
                pr["cpu_ratio_cyrk_over_jit"] = _timed.cpu / row["cpu_jit_s"]
            except Exception as e:  # noqa: BLE001
                pr["cyrk_error"] = f"{type(e).__name__}: {e}"
        out["points"].append(pr)
        log("  drill {:10s} jit {:7.2f} ms | heyoka {} | heyoka tol1e-10 {} | CyRK {}".format(
            row["point"], row["t_jit_s"] * 1e3,
            *(f"{pr[f't_{n}_s'] * 1e3:7.2f} ms (x{pr[f'ratio_{n}_over_jit']:.2f}, err {pr[f'err_{n}']:.1e})"
              + f" CPU x{pr[f'cpu_ratio_{n}_over_jit']:.2f}" if f"t_{n}_s" in pr else "n/a" for n in ("heyoka", "heyoka_tol1e-10", "cyrk"))))
    out["_ta"] = hy_ta
    return out


def bench_batch(quick: bool, hy_ta: dict, log) -> dict:
    """64 drill points at one frequency (F0 x Fs grid, default physical parameters), fixed transient/window."""
    import sim

    n_side = 4 if quick else 8
    N, W = CYCLES["drill"]
    settings = {"min_transient": N, "max_transient": N, "window": W}
    table = [{"amplitude_n": a, "static_force_n": s} for a in np.linspace(800.0, 2400.0, n_side)
             for s in np.linspace(200.0, 1200.0, n_side)]
    out = {"n_points": len(table), "transient": N, "window": W, "frequency_hz": 200.0, "cpus": os.cpu_count()}
    sim.simulate_batch("drill", table[:2], settings=settings, n_threads=1)     # warm
    reps = 2 if quick else 3
    for nt in (1, 2):
        t, _, df = _timed(lambda: sim.simulate_batch("drill", table, settings=settings, n_threads=nt), reps)
        out[f"t_batch_{nt}thread_s"] = t
        out[f"per_point_{nt}thread_ms"] = 1e3 * t / len(table)
        out[f"cpu_over_wall_{nt}thread"] = _timed.cpu / t   # ~nt on an idle machine; << 1 when oversubscribed
    out["speedup_2_threads"] = out["t_batch_1thread_s"] / out["t_batch_2thread_s"]
    log(f"  simulate_batch {len(table)} pts: 1 thread {out['t_batch_1thread_s']:.2f} s, 2 threads "
        f"{out['t_batch_2thread_s']:.2f} s -> speed-up x{out['speedup_2_threads']:.2f}")
    spec = sim.get_model("drill")
    pts = [drill_values(spec.resolve(None, **r)) for r in table]
    ta = hy_ta.get("heyoka")
    if ta is not None:
        from bench import peers_heyoka as ph
        t, _, _ = _timed(lambda: [ph.run_point(ta, p, N, W) for p in pts], reps)
        out["t_heyoka_loop_s"] = t
        t, _, _ = _timed(lambda: ph.run_ensemble(ta, pts, N, W), reps)
        out["t_heyoka_ensemble_s"] = t
        out["heyoka_ensemble_speedup_over_loop"] = out["t_heyoka_loop_s"] / t
        out["ratio_heyoka_ensemble_over_jit_batch_2thread"] = t / out["t_batch_2thread_s"]
        log(f"  heyoka loop {out['t_heyoka_loop_s']:.2f} s, ensemble {t:.2f} s "
            f"(x{out['heyoka_ensemble_speedup_over_loop']:.2f} over its loop; "
            f"{out['ratio_heyoka_ensemble_over_jit_batch_2thread']:.2f} x the jitted batch time)")
    try:
        from bench import peers_cyrk as cy
        sub = pts if not quick else pts[:4]
        t0 = time.perf_counter()
        for p in sub:
            cy.run_point(p, N, W)
        out["t_cyrk_loop_per_point_ms"] = 1e3 * (time.perf_counter() - t0) / len(sub)
        log(f"  CyRK loop {out['t_cyrk_loop_per_point_ms']:.1f} ms/point")
    except Exception as e:  # noqa: BLE001
        out["cyrk_error"] = f"{type(e).__name__}: {e}"
    return out


def _median(xs):
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    return statistics.median(xs) if xs else None


def write_json(path: Path, obj) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        json.dump(obj, fh, indent=1, default=lambda o: o.item() if hasattr(o, "item") else str(o))
    os.replace(tmp, path)


def main(quick: bool = False) -> dict:
    def log(msg):
        print(msg, flush=True)

    t_start = time.perf_counter()
    log(f"bench_sim ({'quick' if quick else 'full'}): jitted simulator vs scipy RK45 rtol {RTOL_USER:g} "
        "(label errors vs DOP853 rtol 1e-10)")
    info = machine_info()
    rows, first_call = bench_points(quick, log)
    log("  peers on the drill points (same transient/window):")
    peers = bench_peers(rows, quick, log)
    hy_ta = peers.pop("_ta")
    log("  batch:")
    batch = bench_batch(quick, hy_ta, log)
    ok = [r for r in rows if "error" not in r]
    summary = {"median_ratio_rk45": _median([r["ratio_rk45"] for r in ok]),
               "median_cpu_ratio_rk45": _median([r["cpu_ratio_rk45"] for r in ok]),
               "min_cpu_ratio_rk45": min((r["cpu_ratio_rk45"] for r in ok), default=None),
               "points_meeting_200x_cpu": sum(r["cpu_ratio_rk45"] >= 200 for r in ok),
               "min_ratio_rk45": min((r["ratio_rk45"] for r in ok), default=None),
               "points_meeting_200x": sum(r["ratio_rk45"] >= 200 for r in ok),
               "points_jit_error_le_rk45": sum(r["err_jit"] <= r["err_rk45"] for r in ok),
               "n_points": len(ok),
               "per_model_median_ratio_rk45": {m: _median([r["ratio_rk45"] for r in ok if r["model"] == m])
                                               for m in dict.fromkeys(r["model"] for r in ok)}}
    for n in ("heyoka", "heyoka_tol1e-10", "cyrk"):
        summary[f"median_ratio_{n}_over_jit"] = _median([p.get(f"ratio_{n}_over_jit") for p in peers["points"]])
        summary[f"median_cpu_ratio_{n}_over_jit"] = _median([p.get(f"cpu_ratio_{n}_over_jit")
                                                             for p in peers["points"]])
    if not quick:
        summary["median_ratio_rk45_plain"] = _median([r.get("ratio_rk45_plain") for r in ok])
        summary["cold_compile_drill_s"] = cold_compile_seconds("drill")
    log("\n{:18s} {:12s} {:>10s} {:>9s} {:>8s} {:>10s} {:>9s} {:>9s}".format(
        "model", "point", "t_jit ms", "t_rk45 s", "ratio", "CPU ratio", "err_jit", "err_rk45"))
    for r in ok:
        log("{:18s} {:12s} {:10.2f} {:9.2f} {:8.0f} {:10.0f} {:9.1e} {:9.1e}".format(
            r["model"], r["point"], r["t_jit_s"] * 1e3, r["t_rk45_s"], r["ratio_rk45"], r["cpu_ratio_rk45"],
            r["err_jit"], r["err_rk45"]))
    log(f"median CPU-time ratio vs RK45: x{summary['median_cpu_ratio_rk45']:.0f} (min x{summary['min_cpu_ratio_rk45']:.0f}); "
        f">= 200x at {summary['points_meeting_200x_cpu']}/{summary['n_points']} points (CPU time)")
    log(f"median speed ratio vs RK45: x{summary['median_ratio_rk45']:.0f} (min x{summary['min_ratio_rk45']:.0f}); "
        f">= 200x at {summary['points_meeting_200x']}/{summary['n_points']} points; jit label error <= RK45's at "
        f"{summary['points_jit_error_le_rk45']}/{summary['n_points']}")
    for n, lab in (("heyoka", "heyoka (tol eps)"), ("heyoka_tol1e-10", "heyoka (tol 1e-10)"), ("cyrk", "CyRK")):
        v = summary[f"median_ratio_{n}_over_jit"]
        if v is not None:
            log(f"{lab}: median time / jitted time = {v:.2f} (CPU {summary[f'median_cpu_ratio_{n}_over_jit']:.2f})")
    log(f"simulate_batch 2-thread speed-up: x{batch['speedup_2_threads']:.2f} (process CPU/wall with 2 threads: "
        f"{batch['cpu_over_wall_2thread']:.2f}; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs)")
    log(f"first call per model (compile or cache load), s: " + ", ".join(f"{m} {t:.1f}" for m, t in first_call.items()))
    if summary.get("cold_compile_drill_s") is not None:
        log(f"cold compile (empty cache) drill: {summary['cold_compile_drill_s']:.1f} s")
    result = {"benchmark": "sim", "quick": quick, "machine": info, "rtol_user_baseline": RTOL_USER,
              "compared_labels": list(COMPARED), "first_call_s": first_call, "points": rows, "peers": peers,
              "batch": batch, "summary": summary, "wall_s": time.perf_counter() - t_start,
              "date": time.strftime("%Y-%m-%d %H:%M:%S")}
    write_json(RESULTS / ("sim_quick.json" if quick else "sim.json"), result)
    log(f"wrote {RESULTS / ('sim_quick.json' if quick else 'sim.json')} ({result['wall_s']:.0f} s)")
    return result


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one point per model, fewer repeats")
    main(ap.parse_args().quick)
