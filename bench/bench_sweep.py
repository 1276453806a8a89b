"""Throughput of ``vibro sweep``: simulations per second for the default sweep (drill ``lab``
preset, Sobol' over LAB_SPACE, default settings) on this machine.

  local   run_sweep on local cores (threads over the GIL-free numba kernel)
  dask    run_sweep on a 2-worker ``LocalCluster`` (worker processes, 1 thread each); workers are
          warmed (kernel loaded) before timing, the cold start is reported separately
  peer    a plain ``multiprocessing.Pool`` (one process per core) around scipy ``solve_ivp``
          (``tests.reference_solutions.reference_run``, RK45, rtol 1e-6, event location) on the first
          ``--peer-points`` points, each with the transient length the fast simulator found for it and
          the same 32-cycle window; ROP agreement with the fast simulator is reported too.

Writes bench/results/sweep.json.  Run: ``python -m bench.bench_sweep [--points 512] [--peer-points 16]``.
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"


def _peer_one(args: tuple[dict, int, int]) -> tuple[float | None, str, float]:
    """One scipy reference run (in a pool process): (rop_m_s, status, wall_s)."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from tests.reference_solutions import reference_run

    params, transient, window = args
    t = time.perf_counter()
    try:
        r = reference_run("drill", params, transient, window, method="RK45", rtol=1e-6)
        return r.get("rop_m_s"), str(r.get("status", "ok")), time.perf_counter() - t
    except Exception as e:  # noqa: BLE001 - a failed peer run is counted, not fatal
        return None, f"failed: {type(e).__name__}", time.perf_counter() - t


def bench_local(spec, workdir: Path) -> dict:
    from pipeline.datasets.compute import compute_chunk
    from pipeline.datasets.runner import run_sweep
    from pipeline.datasets.spec import design_points
    from pipeline.datasets.store import load_dataset

    compute_chunk(spec.model, spec.preset, spec.settings, spec.fixed, design_points(spec).iloc[:1])  # load kernel
    s = run_sweep(spec, workdir / "local", progress=True)
    return {"sims_per_s": s.sims_per_s, "wall_s": s.wall_time_s, "threads": os.cpu_count(),
            "status_counts": s.status_counts, "_df": load_dataset(workdir / "local")}


def bench_dask(spec, workdir: Path, n_workers: int = 2) -> dict:
    from distributed import Client, LocalCluster

    from pipeline.datasets.compute import compute_chunk
    from pipeline.datasets.dask_backend import DaskBackend
    from pipeline.datasets.runner import run_sweep
    from pipeline.datasets.spec import design_points
    from pipeline.datasets.store import load_dataset

    t0 = time.perf_counter()
    with LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        one = design_points(spec).iloc[:1]
        client.run(compute_chunk, spec.model, spec.preset, spec.settings, spec.fixed, one, 1)   # warm every worker
        cold = time.perf_counter() - t0
        s = run_sweep(spec, workdir / "dask", backend=DaskBackend(cluster.scheduler_address), progress=True)
    return {"sims_per_s": s.sims_per_s, "wall_s": s.wall_time_s, "workers": n_workers,
            "cluster_start_and_warm_s": round(cold, 2), "_df": load_dataset(workdir / "dask")}


def bench_peer(spec, df, n: int, processes: int) -> dict:
    import sim

    mspec = sim.get_model(spec.model)
    jobs = []
    for _, row in df.iloc[:n].iterrows():
        params = mspec.resolve(spec.preset, **spec.fixed, **{k: float(row[k]) for k in spec.vary})   # complete dict
        jobs.append((params, int(row["transient_cycles"]), int(spec.settings["window"])))
    t = time.perf_counter()
    ctx = mp.get_context("spawn")
    with ctx.Pool(processes) as pool:
        res = pool.map(_peer_one, jobs)
    wall = time.perf_counter() - t
    fast = df["rop_m_s"].to_numpy()[:n]
    rel = [abs(r - f) / max(abs(f), 1e-12) for (r, _, _), f in zip(res, fast) if r is not None and np.isfinite(f)]
    return {"sims_per_s": n / wall, "wall_s": round(wall, 2), "points": n, "processes": processes,
            "method": "solve_ivp RK45 rtol=1e-6 + event location (tests/reference_solutions.py)",
            "failed": sum(r is None for r, _, _ in res),
            "rop_rel_diff_median": float(np.median(rel)) if rel else None,
            "rop_rel_diff_max": float(np.max(rel)) if rel else None}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=512, help="points of the default sweep to time (default 512)")
    ap.add_argument("--peer-points", type=int, default=16, help="points run by the scipy peer (default 16)")
    ap.add_argument("--out", default=str(RESULTS / "sweep.json"), help="result JSON")
    a = ap.parse_args(argv)
    from vibrobase.files import atomic_write_json
    from pipeline.datasets.spec import make_spec
    from pipeline.datasets.store import package_versions

    spec = make_spec(None, n_points=a.points)          # the default sweep (drill lab, LAB_SPACE, its design)
    with tempfile.TemporaryDirectory(prefix="vibro-bench-sweep-") as tmp:
        tmp = Path(tmp)
        local = bench_local(spec, tmp)
        dask = bench_dask(spec, tmp)
        ldf, ddf = local.pop("_df"), dask.pop("_df")
        identical = bool(ldf.equals(ddf))
        peer = bench_peer(spec, ldf, min(a.peer_points, a.points), os.cpu_count() or 1)
    out = {
        "sweep": {"model": spec.model, "preset": spec.preset, "design": spec.design, "n_points": spec.n_points,
                  "vary": {k: [r.low, r.high] for k, r in spec.vary.items()}, "window": spec.settings["window"],
                  "fingerprint": spec.fingerprint},
        "local": local, "dask_localcluster": dask, "peer_multiprocessing_scipy": peer,
        "dask_identical_to_local": identical,
        "ratios": {"local_over_peer": local["sims_per_s"] / peer["sims_per_s"],
                   "dask_over_peer": dask["sims_per_s"] / peer["sims_per_s"],
                   "dask_over_local": dask["sims_per_s"] / local["sims_per_s"]},
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                    "load_avg_1min": os.getloadavg()[0]},
        "versions": package_versions(("dask", "distributed")),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S"),
    }
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(Path(a.out), out)
    r = out["ratios"]
    print(f"default sweep ({spec.n_points} points, drill lab): local {local['sims_per_s']:.1f} sims/s, "
          f"dask 2-worker LocalCluster {dask['sims_per_s']:.1f} sims/s (identical: {identical}), "
          f"scipy peer {peer['sims_per_s']:.2f} sims/s")
    print(f"ratios: local/peer {r['local_over_peer']:.0f}x, dask/peer {r['dask_over_peer']:.0f}x, "
          f"dask/local {r['dask_over_local']:.2f}; peer ROP rel. diff median {peer['rop_rel_diff_median']}")
    print(f"written {a.out}")
    return out


if __name__ == "__main__":
    main()
