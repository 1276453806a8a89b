"""``vibro diagnose`` on a Dask cluster: wall and CPU time of one diagnosis in this process (1 simulation thread) and
on a ``LocalCluster`` of 1 and 2 single-threaded workers, the tasks it sends, the scheduler's overhead per task,
and an extrapolation to a 50-run diagnosis.

The log: a ``vibro synth`` indenter-metal dataset (sensor low-pass on, 6 runs of 8 cycles) diagnosed with a single
holdout split, the split a system with >= 8 runs gets, so its tasks are those of a 50-run diagnosis.  CPU time is the
whole process tree's (psutil: this process and the worker processes); the cluster's start and the workers' kernel
load are timed apart.  Overhead per task: no-op tasks sent the same way (the evaluator scattered once, one item
each), gathered in order.  Medians of ``--repeat`` runs.  Writes bench/results/diagnose_dask.json and the table
between the diagnose-dask markers of docs/scale.md.  Run: ``python -m bench.bench_diagnose_dask [--repeat 3]``.
"""
from __future__ import annotations

import argparse
import copy
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
DOC = ROOT / "docs" / "scale.md"
MARKERS = ("<!-- diagnose-dask:start -->", "<!-- diagnose-dask:end -->")
SETTINGS = dict(effects=["sensor_lowpass", "guide_friction"], min_runs_holdout=6, holdout_every=3, n_starts=2,
                candidate_starts=2, max_nfev=4, refine_nfev=4, n_threads=1)
"""Two candidates, two starts each: the widest batch has 4 tasks (with every effect of the system: 2 per effect)."""
TARGET_RUNS = 50


def _tree_cpu_s() -> float:
    """CPU seconds (user + system) of this process and every process below it."""
    import psutil

    me = psutil.Process()
    total = sum(me.cpu_times()[:2])
    for child in me.children(recursive=True):
        try:
            total += sum(child.cpu_times()[:2])
        except psutil.NoSuchProcess:
            pass
    return total


def _noop(shared, item):
    return item


def _overhead_per_task_s(executor, shared, n: int = 40) -> float:
    """Wall time per no-op task, sent and gathered as the diagnosis sends its tasks [s]."""
    executor.map(_noop, shared, list(range(4)))          # scatter once, outside the timing
    t = time.perf_counter()
    executor.map(_noop, shared, list(range(n)))
    return (time.perf_counter() - t) / n


def _one(ds, cfg, scheduler: str | None) -> dict:
    """One diagnosis: times, tasks and the report's numbers."""
    from pipeline.core.executors import open_executor
    from pipeline.diagnosis.model import Evaluator
    from pipeline.diagnosis.workflow import diagnose
    from sim.registry import warm

    t0 = time.perf_counter()
    with open_executor(scheduler) as ex:
        if scheduler:
            ex.client.run(warm, "indenter-metal")          # kernel loaded in every worker
        start_s = time.perf_counter() - t0
        c0, w0 = _tree_cpu_s(), time.perf_counter()
        res = diagnose(ds, cfg, log=lambda s: None, executor=ex)
        wall, cpu = time.perf_counter() - w0, _tree_cpu_s() - c0
        st = copy.deepcopy(ex.stats)                       # the diagnosis's tasks, before the probe's
        ev = res.systems[0].evaluator
        probe = Evaluator(ev.system, ev.targets, ev.sim_settings, cfg.fs_sim_hz, 1)
        overhead = _overhead_per_task_s(ex, probe)
    rep = res.report.systems[0]
    return {"wall_s": wall, "cpu_s": cpu, "start_s": start_s, "n_tasks": st.n_tasks, "n_batches": st.n_batches,
            "task_wall_s": sum(st.wall_s), "task_cpu_s": sum(st.cpu_s), "overhead_per_task_s": overhead,
            "batch_of_task": list(st.batch), "task_cpu_each_s": list(st.cpu_s),
            "result": {"verdict": rep.verdict, "selected": "+".join(rep.selected) if rep.selected else None,
                       "calibrated": rep.calibrated, "base_nrms": rep.errors.base.nrms,
                       "final_nrms": rep.errors.final.nrms},
            "n_simulations": rep.n_simulations}


def _makespan(durations: list[float], workers: int) -> float:
    """Longest-first greedy schedule of ``durations`` on ``workers`` [s]."""
    load = [0.0] * workers
    for d in sorted(durations, reverse=True):
        load[load.index(min(load))] += d
    return max(load)


def extrapolate(inline: dict, n_cal: int, n_runs: int, workers: tuple[int, ...], overhead_s: float) -> dict:
    """A ``TARGET_RUNS``-run diagnosis with the same settings and records: every residual simulates all calibration
    runs, so each task's CPU grows by (calibration runs there / here); the tasks and their batches stay (one
    holdout split); the driver's own work (held-out runs, figures) grows with all runs.  Wall per worker count:
    each batch scheduled longest-first, plus the overhead per task."""
    n_cal_50 = TARGET_RUNS - len(range(1, TARGET_RUNS, 4))             # every 4th run held out
    k = n_cal_50 / n_cal
    driver = (inline["cpu_s"] - inline["task_cpu_s"]) * TARGET_RUNS / n_runs
    batches: dict[int, list[float]] = {}
    for b, c in zip(inline["batch_of_task"], inline["task_cpu_each_s"]):
        batches.setdefault(b, []).append(c * k)
    out = {"calibration_runs": n_cal_50, "task_scale": k, "task_cpu_s": inline["task_cpu_s"] * k,
           "driver_cpu_s": driver, "n_tasks": inline["n_tasks"],
           "widest_batch": max(len(v) for v in batches.values()), "overhead_s": inline["n_tasks"] * overhead_s}
    out["wall_s"] = {w: driver + sum(_makespan(v, w) for v in batches.values()) + out["overhead_s"] for w in workers}
    return out


def table(res: dict) -> str:
    """The markdown block of docs/scale.md."""
    rows = res["runs"]
    lines = [
        f"Measured {res['created']} on {res['machine']['cpus']} cores shared with another long benchmark (load "
        f"{res['machine']['load_avg_1min']:.1f}); medians of {res['repeat']} runs; `python -m bench.bench_diagnose_dask`.",
        f"One diagnosis: {res['log']}.",
        "",
        "| where the fits ran | wall [s] | CPU, process tree [s] | CPU / wall | tasks (batches) | task CPU [s] "
        "| overhead per task [ms] | cluster start + kernel load [s] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, r in rows.items():
        lines.append(f"| {name} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | {r['cpu_s'] / r['wall_s']:.2f} | "
                     f"{r['n_tasks']} ({r['n_batches']}) | {r['task_cpu_s']:.1f} | {1e3 * r['overhead_per_task_s']:.1f} | "
                     f"{r['start_s']:.1f} |")
    ident = "identical" if res["identical"] else "NOT identical"
    e = res["extrapolation"]
    walls = ", ".join(f"{w} worker{'s' if int(w) > 1 else ''} {v / 60:.1f} min" for w, v in e["wall_s"].items())
    lines += [
        "",
        f"The report's verdict, parameters and nrms: {ident} in all three runs.  "
        f"Speed-up of 2 workers over 1: {rows['local:1']['wall_s'] / rows['local:2']['wall_s']:.2f}x in wall time.",
        "",
        f"**A {TARGET_RUNS}-run diagnosis** (same settings and records; {e['calibration_runs']} calibration runs, so "
        f"each task costs {e['task_scale']:.1f}x the CPU measured here): {e['task_cpu_s'] / 60:.1f} min of simulator "
        f"CPU in {e['n_tasks']} tasks (the widest batch {e['widest_batch']}), {e['driver_cpu_s'] / 60:.1f} min in "
        f"the command itself (held-out runs, figures), and {e['overhead_s']:.2f} s of scheduler overhead in all.  "
        f"Estimated wall: {walls}.",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3, help="runs of each configuration (medians; default 3)")
    ap.add_argument("--out", default=str(RESULTS / "diagnose_dask.json"), help="result JSON")
    ap.add_argument("--no-doc", action="store_true", help="do not write the table into docs/scale.md")
    a = ap.parse_args(argv)
    from bench import publish
    from pipeline.cli import main as vibro
    from pipeline.datasets.measured import load_dataset
    from pipeline.datasets.store import package_versions
    from pipeline.diagnosis.run import DiagnoseConfig

    with tempfile.TemporaryDirectory(prefix="vibro-bench-diagnose-") as tmp:
        data = Path(tmp) / "lp"
        assert vibro(["synth", "--out", str(data), "--system", "indenter-metal", "--effect", "sensor_lowpass",
                      "--cycles", "8", "--frequencies", "60", "80", "100", "--seed", "4", "--quiet"]) == 0
        ds = load_dataset(data)
        cfg = DiagnoseConfig(**SETTINGS)
        configs = {"this process, 1 thread": None, "local:1": "local:1", "local:2": "local:2"}
        runs: dict[str, list[dict]] = {name: [] for name in configs}
        for _ in range(a.repeat):                            # interleaved: the machine's load falls on all alike
            for name, scheduler in configs.items():
                runs[name].append(_one(ds, cfg, scheduler))
                print(f"{name}: {runs[name][-1]['wall_s']:.1f} s wall, {runs[name][-1]['cpu_s']:.1f} s CPU", flush=True)
    results = [r["result"] for rs in runs.values() for r in rs]
    med = {}
    for name, rs in runs.items():
        m = {k: statistics.median(r[k] for r in rs) for k in ("wall_s", "cpu_s", "start_s", "task_wall_s",
                                                               "task_cpu_s", "overhead_per_task_s")}
        med[name] = {**m, "n_tasks": rs[0]["n_tasks"], "n_batches": rs[0]["n_batches"],
                     "n_simulations": rs[0]["n_simulations"]}
    inline = dict(med["this process, 1 thread"])
    first = runs["this process, 1 thread"][0]
    inline.update(batch_of_task=first["batch_of_task"], task_cpu_each_s=first["task_cpu_each_s"])
    n_runs = len(ds.runs)
    n_cal = n_runs - len(range(1, n_runs, SETTINGS["holdout_every"]))
    out = {
        "log": f"indenter-metal, {n_runs} runs of 8 cycles (vibro synth, sensor low-pass), {n_cal} calibration runs; "
               f"settings {SETTINGS}",
        "repeat": a.repeat, "runs": med, "all": runs,
        "identical": all(r == results[0] for r in results),
        "extrapolation": extrapolate(inline, n_cal, n_runs, (1, 2, 4, 8), med["local:2"]["overhead_per_task_s"]),
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(), "load_avg_1min": os.getloadavg()[0]},
        "versions": package_versions(("dask", "distributed")),
        "created": time.strftime("%Y-%m-%d"),
    }
    publish(out, Path(a.out), table(out), None if a.no_doc else DOC, MARKERS)
    return out


if __name__ == "__main__":
    main()
