"""Two-core scaling: ``sim.simulate_batch`` with n_threads = 1 and 2, and ``vibro sweep`` with
``--workers 1`` and ``2``, as CPU time per point and throughput (points per wall second).

``simulate_batch``: the same drill ``lab`` table (a frequency x amplitude grid of the lab space) is run with
1 and 2 threads, interleaved (1, 2, 1, 2, ...), after a warm-up; process CPU time (all threads) and wall
time per call, medians.  ``sweep``: ``python -m pipeline.cli sweep`` in a subprocess on a small Sobol'
spec into a temporary directory (``--overwrite --no-mlflow --quiet``), interleaved the same way; the
sweep's own wall time and sims/s come from its ``--metrics`` file (simulation only), the subprocess'
CPU time (``RUSAGE_CHILDREN``) and wall time include the interpreter start and the kernel load.
Used by :mod:`bench.bench_precision` (its generated table holds these rows); not a benchmark module
of its own.
"""
from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _lab_table(n: int):
    import numpy as np
    import pandas as pd

    from sim.models.drill import LAB_SPACE

    (f_lo, f_hi), (a_lo, a_hi) = (LAB_SPACE["frequency_hz"][:2], LAB_SPACE["amplitude_n"][:2])
    k = int(round(n ** 0.5))
    ff, aa = np.meshgrid(np.linspace(f_lo, f_hi, k), np.linspace(a_lo, a_hi, n // k), indexing="ij")
    return pd.DataFrame({"frequency_hz": ff.ravel(), "amplitude_n": aa.ravel()})


def batch_scaling(n_points: int = 64, reps: int = 3) -> dict:
    """simulate_batch of ``n_points`` drill ``lab`` points at 1 and 2 threads."""
    import sim

    table = _lab_table(n_points)
    sim.simulate_batch("drill", table.iloc[:2], preset="lab", n_threads=1)    # warm-up (kernel load)
    cpu = {1: [], 2: []}
    wall = {1: [], 2: []}
    for _ in range(reps):
        for nt in (1, 2):
            c0, t0 = time.process_time(), time.perf_counter()
            sim.simulate_batch("drill", table, preset="lab", n_threads=nt)
            wall[nt].append(time.perf_counter() - t0)
            cpu[nt].append(time.process_time() - c0)
    n = len(table)
    return {"what": f"sim.simulate_batch, drill lab, {n} points (frequency x amplitude grid), default settings",
            "n_points": n, "reps": reps,
            "rows": [{"workers": nt, "cpu_s": statistics.median(cpu[nt]), "wall_s": statistics.median(wall[nt]),
                      "cpu_ms_per_point": 1e3 * statistics.median(cpu[nt]) / n,
                      "points_per_s": n / statistics.median(wall[nt]), "wall_all": wall[nt]} for nt in (1, 2)]}


def _sweep_once(out: Path, n_points: int, workers: int) -> dict:
    metrics = out.parent / f"metrics-{workers}.json"
    cmd = [sys.executable, "-m", "pipeline.cli", "sweep", "--out", str(out), "--n-points", str(n_points),
           "--workers", str(workers), "--metrics", str(metrics), "--overwrite", "--no-mlflow", "--quiet"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"vibro sweep --workers {workers} failed: {proc.stderr.strip().splitlines()[-1:]}")
    m = json.loads(metrics.read_text())
    return {"process_wall_s": wall, "process_cpu_s": (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime),
            "sweep_wall_s": float(m.get("wall_time_s") or m.get("wall_s") or float("nan")),
            "sims_per_s": float(m.get("sims_per_s") or float("nan"))}


def sweep_scaling(n_points: int = 256, reps: int = 2) -> dict:
    """``vibro sweep`` (default spec: drill ``lab``, Sobol') of ``n_points`` at ``--workers`` 1 and 2."""
    runs = {1: [], 2: []}
    with tempfile.TemporaryDirectory(prefix="vibro-bench-scaling-") as tmp:
        for _ in range(reps):
            for w in (1, 2):
                runs[w].append(_sweep_once(Path(tmp) / f"sweep-{w}", n_points, w))
    rows = []
    for w in (1, 2):
        med = {k: statistics.median(r[k] for r in runs[w]) for k in runs[w][0]}
        rows.append({"workers": w, **med, "cpu_ms_per_point": 1e3 * med["process_cpu_s"] / n_points,
                     "points_per_s": med["sims_per_s"]})
    return {"what": f"python -m pipeline.cli sweep (default spec: drill lab, Sobol'), {n_points} points",
            "n_points": n_points, "reps": reps, "rows": rows}


def table(res: dict) -> str:
    """Markdown rows of the scaling results (batch and sweep)."""
    lines = ["| what | workers | CPU ms per point | points per s | wall s | speed-up |", "|---|---|---|---|---|---|"]
    for key in ("batch", "sweep"):
        r = res.get(key)
        if not r:
            continue
        base = r["rows"][0]["points_per_s"]
        for row in r["rows"]:
            wall = row.get("wall_s", row.get("sweep_wall_s"))
            lines.append(f"| {r['what']} | {row['workers']} | {row['cpu_ms_per_point']:.2f} | {row['points_per_s']:.0f} | "
                         f"{wall:.2f} | {row['points_per_s'] / base:.2f} |")
    return "\n".join(lines) + "\n"
