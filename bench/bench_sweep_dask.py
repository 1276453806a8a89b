"""``vibro sweep`` on a Dask cluster, sized for 100 000 points: where the time goes per point and per task, measured on
this machine, and extrapolated to clusters of 8, 32 and 128 single-threaded workers.

Measured, interleaved, medians of ``--repeat`` runs of the default sweep (drill ``lab``, Sobol'), each at chunk sizes
8 and 64:
  local    ``run_sweep`` with one local thread: the simulator's CPU per point and per chunk (process CPU between
           writes, solved from the two chunk sizes);
  dask     ``run_sweep`` on a warmed 2-worker ``local:2`` cluster: wall, the process tree's CPU (psutil: this process,
           which here also runs the scheduler, and the worker processes), tasks.
Every run's chunk writes are timed where the runner makes them (the client's write of one chunk: Arrow table, Parquet,
checksum sidecar, two fsyncs).  Overhead per task: the CPU beyond the simulation and the writes, and, from the two
chunk sizes (same points, same fixed costs), its slope per task.  The resume scan and the final status count are
timed per chunk on each finished dataset.  Writes bench/results/sweep_dask.json and the block between the
sweep-dask markers of docs/scale.md.  Run: ``python -m bench.bench_sweep_dask [--points 2048] [--repeat 3]``.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from bench.bench_diagnose_dask import _tree_cpu_s

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
DOC = ROOT / "docs" / "scale.md"
MARKERS = ("<!-- sweep-dask:start -->", "<!-- sweep-dask:end -->")
CHUNKS = (8, 64)                 # measured; 64 is params.yaml's sweep.chunk_size default
TARGET_POINTS = 100_000
WORKERS = (8, 32, 128)
PLAN_CHUNKS = (8, 64, 512)       # 512: extrapolated write cost
OVERHEAD_SHARE = 0.01            # scheduler + worker CPU per task at most this share of the task's simulation
CLIENT_BUSY = 0.5                # the client's loop busy at most this share of the time (headroom for bursts)
WRITE_SIZES = (8, 64, 512, 2048)  # chunk writes timed on their own (capped at the points)
CHUNKS_PER_WORKER = 10           # the last wave idles at most about one chunk per worker: <= 1/10 of the run


@dataclass
class TimedWrites:
    """A sweep backend around ``inner`` that times each chunk write the runner hands it (wall and this thread's CPU)
    and the process CPU between writes (with a local one-thread backend: the chunk's simulation)."""

    inner: object
    writes: list[tuple[float, float]] = field(default_factory=list)     # (wall_s, cpu_s) per chunk
    gaps_cpu_s: list[float] = field(default_factory=list)

    @property
    def description(self) -> str:
        return self.inner.description

    @property
    def extra_packages(self) -> tuple[str, ...]:
        return self.inner.extra_packages

    def run(self, spec, chunks, write) -> None:
        mark = time.process_time()

        def timed(k, rows):
            nonlocal mark
            c0, w0, t0 = time.process_time(), time.perf_counter(), time.thread_time()
            self.gaps_cpu_s.append(c0 - mark)
            write(k, rows)
            self.writes.append((time.perf_counter() - w0, time.thread_time() - t0))
            mark = time.process_time()

        self.inner.run(spec, chunks, timed)


def _self_cpu_s() -> float:
    """CPU seconds (user + system) of this process alone."""
    import psutil

    return sum(psutil.Process().cpu_times()[:2])


def _scan_per_chunk_s(out: Path, spec) -> dict:
    """The per-chunk reads of a finished dataset: the resume scan (checksum + footer) and the final status count."""
    from pipeline.datasets.store import _existing_chunks, status_counts

    t = time.perf_counter()
    assert len(_existing_chunks(out, spec)) == spec.n_chunks
    scan = time.perf_counter() - t
    t = time.perf_counter()
    status_counts(out)
    return {"resume_scan_s": scan / spec.n_chunks, "status_count_s": (time.perf_counter() - t) / spec.n_chunks}


def write_path(df, model: str, out: Path, sizes: tuple[int, ...], repeat: int = 15) -> dict[int, float]:
    """Median wall time of the client's write of one chunk of each size (Arrow table, Parquet, checksum, fsyncs) [s],
    the sizes interleaved, into ``out``."""
    from pipeline.datasets.store import _to_table, _write_chunk

    times: dict[int, list[float]] = {c: [] for c in sizes}
    for i in range(repeat):
        for j, c in enumerate(sizes):
            t = time.perf_counter()
            _write_chunk(out, i * len(sizes) + j, _to_table(df.iloc[:c], model, {"vibro.chunk": i}))
            times[c].append(time.perf_counter() - t)
    return {c: statistics.median(v) for c, v in times.items()}


def _one(spec, backend, out: Path, workers: int) -> dict:
    """One sweep into ``out`` (overwritten): times, CPU split this process / workers, writes, per-chunk reads."""
    from pipeline.datasets.runner import run_sweep
    from pipeline.datasets.store import load_dataset

    timed = TimedWrites(backend)
    tree0, me0, w0 = _tree_cpu_s(), _self_cpu_s(), time.perf_counter()
    run_sweep(spec, out, backend=timed, progress=False, overwrite=True)
    wall, tree, me = time.perf_counter() - w0, _tree_cpu_s() - tree0, _self_cpu_s() - me0
    return {"wall_s": wall, "cpu_s": tree, "client_cpu_s": me, "workers_cpu_s": tree - me, "workers": workers,
            "n_tasks": spec.n_chunks, "chunk_size": spec.chunk_size, "gaps_cpu_s": sum(timed.gaps_cpu_s),
            "write_wall_s": statistics.median(w for w, _ in timed.writes),
            "write_cpu_s": statistics.median(c for _, c in timed.writes),
            "writes_cpu_s": sum(c for _, c in timed.writes), **_scan_per_chunk_s(out, spec),
            "_df": load_dataset(out)}


def measure(n_points: int, repeat: int, log=print) -> dict:
    """The interleaved runs (one local thread and ``local:2``, each at every chunk size of CHUNKS) and their medians.

    The local runs give the simulation's CPU per chunk (process CPU between writes) = fixed + per point x points,
    solved from the two chunk sizes, and the write of a chunk by a client that has a core to itself."""
    from pipeline.core.dask_client import connect
    from pipeline.datasets.compute import compute_chunk
    from pipeline.datasets.dask_backend import DaskBackend
    from pipeline.datasets.runner import LocalBackend
    from pipeline.datasets.spec import design_points, make_spec

    specs = {c: make_spec(None, n_points=n_points, chunk_size=c) for c in CHUNKS}
    spec = specs[CHUNKS[0]]
    one = design_points(spec).iloc[:1]
    compute_chunk(spec.model, spec.preset, spec.settings, spec.fixed, one, 1)            # kernel loaded here
    names = {f"{where}, chunk {c}": (specs[c], w)
             for where, w in (("local 1 thread", 1), ("local:2", 2)) for c in CHUNKS}
    runs: dict[str, list[dict]] = {name: [] for name in names}
    identical = True
    t0 = time.perf_counter()
    with connect("local:2") as client, tempfile.TemporaryDirectory(prefix="vibro-bench-sweep-dask-") as tmp:
        client.run(compute_chunk, spec.model, spec.preset, spec.settings, spec.fixed, one, 1)   # and in each worker
        start_s = time.perf_counter() - t0
        address = client.scheduler.address
        ref = None
        for i in range(repeat):                          # interleaved; every other round in reverse order
            for name in (list(names) if i % 2 == 0 else list(reversed(names))):
                sp, w = names[name]
                backend = LocalBackend(1) if w == 1 else DaskBackend(address)
                r = _one(sp, backend, Path(tmp) / f"run-{w}-{sp.chunk_size}", w)
                df = r.pop("_df")
                ref = df if ref is None else ref
                identical &= bool(df.equals(ref))
                runs[name].append(r)
                log(f"{name}: {r['wall_s']:.2f} s wall, {r['cpu_s']:.2f} s CPU, write {1e3 * r['write_wall_s']:.1f} ms")
        writes = write_path(ref, spec.model, Path(tmp) / "writes", tuple(c for c in WRITE_SIZES if c <= n_points))
    med = {name: {k: statistics.median(r[k] for r in rs) for k in rs[0]} for name, rs in runs.items()}
    (c1, g1), (c2, g2) = ((c, med[f"local 1 thread, chunk {c}"]["gaps_cpu_s"] / specs[c].n_chunks) for c in CHUNKS)
    per_point = (g2 - g1) / (c2 - c1)                    # CPU of one chunk = fixed + per_point x points
    fixed = g1 - per_point * c1
    for m in med.values():
        sim = fixed * m["n_tasks"] + per_point * n_points
        m["sim_cpu_s"] = sim
        local = m["workers"] == 1
        own = m["client_cpu_s"] - m["writes_cpu_s"] - (sim if local else 0.0)
        m["client_overhead_per_task_s"] = own / m["n_tasks"]
        m["worker_overhead_per_task_s"] = 0.0 if local else (m["workers_cpu_s"] - sim) / m["n_tasks"]
        m["idle_per_task_s"] = (m["workers"] * m["wall_s"] - sim) / m["n_tasks"]
    lo, hi = (med[f"local:2, chunk {c}"] for c in CHUNKS)
    dn = lo["n_tasks"] - hi["n_tasks"]
    client = [r["client_cpu_s"] - r["writes_cpu_s"] for r in (lo, hi)]
    slope = {"client_cpu_per_task_s": (client[0] - client[1]) / dn,
             "workers_cpu_per_task_s": (lo["workers_cpu_s"] - hi["workers_cpu_s"]) / dn - fixed}
    return {"n_points": n_points, "repeat": repeat, "sim_cpu_per_point_s": per_point, "sim_cpu_per_chunk_s": fixed,
            "cluster_start_s": start_s, "write_s": writes, "runs": med, "all": runs, "per_task_slope": slope,
            "identical": identical}


def write_line(m: dict) -> tuple[float, float]:
    """(fixed [s], per point [s]) of a chunk write: least squares through the timed write sizes."""
    import numpy as np

    c, w = np.array([[k, v] for k, v in m["write_s"].items()], dtype=float).T
    b, a = np.polyfit(c, w, 1)
    return float(a), max(float(b), 0.0)


def extrapolate(m: dict, n: int = TARGET_POINTS) -> dict:
    """``n`` points on W single-threaded workers and one client, from the measured per-point and per-task costs.

    Workers: (simulation, its fixed cost per chunk, their Dask overhead per task) / W.  Client (here also the
    scheduler): per task its CPU beyond writes plus one chunk write, one after another.  Wall: the slower of the two,
    plus one chunk's simulation (the last wave) and the final status count.  Chunk sizes: the smallest with overhead
    <= OVERHEAD_SHARE and client busy <= CLIENT_BUSY, the largest leaving CHUNKS_PER_WORKER chunks per worker."""
    s, f = m["sim_cpu_per_point_s"], m["sim_cpu_per_chunk_s"]
    sl = m["per_task_slope"]
    o_c, o_w = max(sl["client_cpu_per_task_s"], 0.0), max(sl["workers_cpu_per_task_s"], 0.0)
    runs = [r for r in m["runs"].values() if r["workers"] > 1]
    scan = statistics.median(r["resume_scan_s"] for r in runs)
    count = statistics.median(r["status_count_s"] for r in runs)
    a, b = write_line(m)
    task_over = f + o_w + o_c
    rows = []
    for w in WORKERS:
        for c in PLAN_CHUNKS:
            tasks = math.ceil(n / c)
            workers_s = (n * s + tasks * (f + o_w)) / w
            client_s = tasks * (o_c + (a + b * c))
            rows.append({"workers": w, "chunk": c, "tasks": tasks, "chunks_per_worker": tasks / w,
                         "workers_s": workers_s, "client_s": client_s, "client_busy": client_s / workers_s,
                         "overhead_share": task_over / (c * s), "overhead_total_s": tasks * task_over,
                         "overhead_per_worker_s": tasks * (f + o_w) / w,
                         "wall_s": max(workers_s, client_s) + c * s + tasks * count, "resume_scan_s": tasks * scan})
    bounds = {}
    for w in WORKERS:
        room = CLIENT_BUSY * s / w - b
        bounds[w] = {"min_overhead": task_over / (OVERHEAD_SHARE * s),
                     "min_client": (o_c + a) / room if room > 0 else math.inf,
                     "max_tail": n / (CHUNKS_PER_WORKER * w)}
    return {"points": n, "sim_cpu_s": n * s, "client_cpu_per_task_s": o_c, "worker_cpu_per_task_s": o_w,
            "sim_cpu_per_chunk_s": f, "write_fixed_s": a, "write_per_point_s": b, "resume_scan_per_chunk_s": scan,
            "status_count_per_chunk_s": count, "rows": rows, "bounds": bounds,
            "workers_one_client_feeds": {c: (c * s + f + o_w) / (o_c + (a + b * c)) for c in PLAN_CHUNKS}}


def table(res: dict) -> str:
    """The markdown block of docs/scale.md."""
    m, e, mach = res["measured"], res["extrapolation"], res["machine"]
    lines = [
        f"Measured {res['created']} on {mach['cpus']} cores shared with another long benchmark (load "
        f"{mach['load_avg_1min']:.1f} at start: every time here is inflated alike); medians of {m['repeat']} "
        f"interleaved runs; `python -m bench.bench_sweep_dask`.  The default sweep (drill `lab`, Sobol'), "
        f"{m['n_points']} points; `local:2` warmed (kernel loaded) beforehand; results identical in every run: "
        f"{'yes' if m['identical'] else 'NO'}.",
        "",
        "| where | chunk | tasks | wall [s] | CPU, process tree [s] | CPU / wall | simulation CPU [s] "
        "| client + scheduler CPU per task [ms] | worker CPU per task beyond simulation [ms] "
        "| worker time not simulating per task [ms] | one chunk write, wall (CPU) [ms] | resume scan per chunk [ms] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in m["runs"].items():
        where = name.split(",")[0]
        wo = "—" if r["workers"] == 1 else f"{1e3 * r['worker_overhead_per_task_s']:.1f}"
        lines.append(f"| {where} | {r['chunk_size']:.0f} | {r['n_tasks']:.0f} | {r['wall_s']:.2f} | {r['cpu_s']:.2f} | "
                     f"{r['cpu_s'] / r['wall_s']:.2f} | {r['sim_cpu_s']:.2f} | {1e3 * r['client_overhead_per_task_s']:.1f} | "
                     f"{wo} | {1e3 * r['idle_per_task_s']:.1f} | {1e3 * r['write_wall_s']:.1f} "
                     f"({1e3 * r['write_cpu_s']:.1f}) | {1e3 * r['resume_scan_s']:.2f} |")
    sl = m["per_task_slope"]
    sizes = ", ".join(f"{1e3 * v:.1f} ms at {k} points" for k, v in m["write_s"].items())
    lines += [
        "",
        f"Simulator (one thread; from the local runs' CPU per chunk at the two sizes): "
        f"**{1e3 * m['sim_cpu_per_point_s']:.2f} ms "
        f"CPU per point** plus {1e3 * m['sim_cpu_per_chunk_s']:.1f} ms per chunk (one `compute_chunk` call).  Per task "
        f"on `local:2`, from the two chunk sizes (the CPU difference over the task difference): client + scheduler "
        f"**{1e3 * sl['client_cpu_per_task_s']:.1f} ms** beyond its writes, workers "
        f"**{1e3 * sl['workers_cpu_per_task_s']:.1f} ms** "
        f"beyond `compute_chunk`.  The client's write of one chunk, timed on its own: {sizes} (wall, two fsyncs "
        f"included; the line {1e3 * e['write_fixed_s']:.1f} ms + {1e3 * e['write_per_point_s']:.4f} ms per point).  "
        f"Starting `local:2` and loading the kernel: {m['cluster_start_s']:.1f} s.",
        "",
        f"**{TARGET_POINTS:,}".replace(",", " ") + f" points, extrapolated** ({e['sim_cpu_s'] / 60:.1f} min of "
        f"simulator CPU; one client writing every chunk; workers single-threaded):",
        "",
        "| workers | chunk | tasks | chunks per worker | overhead share | overhead in all [s] (per worker) "
        "| workers' time [s] | client's time [s] | client busy | wall [s] | resume scan [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in e["rows"]:
        lines.append(f"| {r['workers']} | {r['chunk']} | {r['tasks']} | {r['chunks_per_worker']:.1f} | "
                     f"{100 * r['overhead_share']:.1f}% | {r['overhead_total_s']:.1f} ({r['overhead_per_worker_s']:.2f}) | "
                     f"{r['workers_s']:.1f} | {r['client_s']:.1f} | {100 * r['client_busy']:.0f}% | "
                     f"{r['wall_s']:.1f} | {r['resume_scan_s']:.1f} |")
    lines.append("")
    feeds = ", ".join(f"{v:.1f} at chunk {c}" for c, v in e["workers_one_client_feeds"].items())
    lines.append(f"Workers one client keeps busy (its time per task = the task's simulation): {feeds}.")
    for w, bd in e["bounds"].items():
        lo = max(bd["min_overhead"], bd["min_client"])
        if math.isinf(bd["min_client"]):
            verdict = "one client cannot keep them busy at any chunk size (its write per point alone is too slow)"
        elif lo <= bd["max_tail"]:
            verdict = f"chunk {math.ceil(lo)} to {math.floor(bd['max_tail'])}"
        else:
            verdict = f"no chunk size does all three (>= {lo:.0f} and <= {bd['max_tail']:.0f})"
        client = "at no chunk size" if math.isinf(bd["min_client"]) else f"from chunk {bd['min_client']:.0f}"
        lines.append(f"{w} workers: overhead <= {100 * OVERHEAD_SHARE:.0f}% from chunk {bd['min_overhead']:.0f}, "
                     f"client busy <= {100 * CLIENT_BUSY:.0f}% {client}, "
                     f">= {CHUNKS_PER_WORKER} chunks per worker up to chunk {bd['max_tail']:.0f}: {verdict}.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=2048, help="points of the default sweep per run (default 2048)")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each configuration (medians; default 3)")
    ap.add_argument("--out", default=str(RESULTS / "sweep_dask.json"), help="result JSON")
    ap.add_argument("--no-doc", action="store_true", help="do not write the table into docs/scale.md")
    a = ap.parse_args(argv)
    from bench import publish
    from pipeline.datasets.store import package_versions

    load = os.getloadavg()[0]
    measured = measure(a.points, a.repeat)
    out = {"measured": measured, "extrapolation": extrapolate(measured),
           "machine": {"cpus": os.cpu_count(), "platform": platform.platform(), "load_avg_1min": load,
                       "load_avg_1min_end": os.getloadavg()[0]},
           "versions": package_versions(("dask", "distributed", "psutil")), "created": time.strftime("%Y-%m-%d")}
    publish(out, Path(a.out), table(out), None if a.no_doc else DOC, MARKERS)
    return out


if __name__ == "__main__":
    main()
