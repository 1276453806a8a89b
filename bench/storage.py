"""What the optuna storage costs per trial, against what the simulator costs: ``python -m bench.storage [--quick]``.

Writes ``bench/results/storage.json`` and the table of docs/scale.md (between its ``storage-table`` markers).

- **storage cost per trial**: one worker runs ``study.run_study`` (the loop of ``vibro optimise``, with the guard
  of each storage: flock files for SQLite, heartbeat guard for PostgreSQL and the journal file) on an objective
  that costs nothing and the random sampler (nothing to compute), so the wall time per trial is the storage's:
  counting, asking, heartbeat, labels, constraints and telling.  Batch sizes 1 and 8; timed per quarter of the
  study, since a worker reads the study's trials before every batch.
- **one heartbeat**: the time of one ``record_heartbeat`` call.
- **PostgreSQL server CPU per trial**: CPU seconds of the cluster's processes over the run, per trial: the
  server's share, which all workers load together.
- **simulator per trial**: the drill ``lab`` evaluator of ``vibro optimise --simulator`` on one thread.

PostgreSQL is a throw-away local cluster (bench/servers.py, fsync off, over TCP on 127.0.0.1): a networked
server adds its round-trip time to every call.  The journal file is on the local disk.
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from bench import RESULTS, write_block

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "scale.md"
START, END = "<!-- storage-table:start -->", "<!-- storage-table:end -->"
STUDY_TRIALS, WORKERS = 2000, 32
"""The study the docs size: 2000 trials over 32 workers."""


def _free(X: pd.DataFrame) -> pd.DataFrame:
    return pd.DataFrame({"status": "ok", "rop_m_s": X.iloc[:, 0].to_numpy()})


def storage_cost(url: str, n_trials: int, batch: int) -> dict:
    """Seconds per trial of the study loop on ``url`` with a free objective and the random sampler."""
    import optuna

    from pipeline.optimise.constraints import Constraints
    from pipeline.optimise.coordination import guard_for
    from pipeline.optimise.space import Space
    from pipeline.optimise.study import open_study, run_study

    name = f"bench-{batch}-{time.monotonic_ns()}"
    sampler = optuna.samplers.RandomSampler(seed=0)
    study = open_study(url, name, [("rop_m_s", "maximize")], sampler, {"bench": 1}, heartbeat_s=10)
    space = Space({"x": (0.0, 1.0), "y": (0.0, 1.0), "z": (0.0, 1.0)})
    quarters = []          # seconds per trial in each quarter of the study: does the cost grow with its size?
    for q in range(1, 5):
        t0 = time.perf_counter()
        run_study(study, _free, space, Constraints(), [("rop_m_s", "maximize")], n_trials * q // 4, batch,
                  progress=False, guard=guard_for(url))
        quarters.append((time.perf_counter() - t0) / (n_trials // 4))
    beat = np.nan
    if hasattr(study._storage, "record_heartbeat") and study._storage.get_heartbeat_interval():
        running = guard_for(url).ask(study, space.distributions())     # a heartbeat is for a running trial
        t1 = time.perf_counter()
        for _ in range(20):
            study._storage.record_heartbeat(running._trial_id)
        beat = (time.perf_counter() - t1) / 20
        study.tell(running, state=optuna.trial.TrialState.FAIL)
    return {"s_per_trial": float(np.mean(quarters)), "quarters_s_per_trial": quarters, "heartbeat_s": beat}


def simulator_cost(n: int) -> float:
    """Seconds per trial of the drill lab simulator on one thread (the study's evaluator)."""
    from pipeline.optimise.evaluators import SimulatorEvaluator
    from pipeline.optimise.space import default_space

    space = default_space("drill", "lab")
    rng = np.random.default_rng(0)
    X = pd.DataFrame({k: rng.uniform(lo, hi, n) for k, (lo, hi) in space.ranges.items()})
    ev = SimulatorEvaluator("drill", "lab", n_threads=1)
    ev(X.head(2))                                   # compile / load the kernel
    t0 = time.perf_counter()
    ev(X)
    return (time.perf_counter() - t0) / n


def _cluster_cpu(pg) -> float:
    """CPU seconds used so far by the processes of the local PostgreSQL cluster."""
    import psutil

    pid = int((pg.dir / "data" / "postmaster.pid").read_text().split()[0])
    root = psutil.Process(pid)
    t = root.cpu_times()
    total = t.children_user + t.children_system     # connections that ended: their time is the postmaster's now
    for p in [root, *root.children(recursive=True)]:
        try:
            t = p.cpu_times()
            total += t.user + t.system
        except psutil.Error:
            continue
    return total


def measure(quick: bool) -> dict:
    from bench.bench_sim import machine_info
    from bench.servers import LocalPostgres, postgres_missing

    n = 100 if quick else 400
    out = {"machine": machine_info(), "n_trials": n, "engines": {}}
    out["simulator_s_per_trial"] = simulator_cost(32 if quick else 128)
    with tempfile.TemporaryDirectory() as tmp:
        urls = {"sqlite": f"sqlite:///{tmp}/bench.db", "journal": f"journal://{tmp}/bench.log"}
        why = postgres_missing()
        pg = None if why else LocalPostgres().start()
        try:
            if pg is not None:
                urls["postgresql"] = pg.new_database("bench")
            else:
                out["postgresql_skipped"] = why
            for engine, url in urls.items():
                for batch in (1, 8):
                    cpu0 = _cluster_cpu(pg) if engine == "postgresql" else 0.0
                    res = storage_cost(url, n, batch)
                    if engine == "postgresql":
                        res["server_cpu_s_per_trial"] = (_cluster_cpu(pg) - cpu0) / n
                    out["engines"][f"{engine}/{batch}"] = res
                    print(f"{engine:10s} batch {batch}: {res['s_per_trial'] * 1e3:7.2f} ms/trial", flush=True)
        finally:
            if pg is not None:
                pg.stop()
    return out


def table(res: dict) -> str:
    """The Markdown table of docs/scale.md: per-trial costs and the 2000-trial, 32-worker extrapolation."""
    sim = res["simulator_s_per_trial"]
    per_worker = STUDY_TRIALS / WORKERS
    m = res["machine"]
    lines = [f"Measured by `python -m bench.storage` ({res['n_trials']} trials per row, one worker, free objective, "
             f"random sampler; {m.get('cpu', '?')}, {m['cpus']} cores, load average {m['load_avg_at_start'][0]:.1f} "
             f"at start: the machine was shared, so every time here is inflated alike).  Simulator (drill `lab`, "
             f"one thread): **{sim * 1e3:.1f} ms per trial**.",
             "",
             "| storage, batch | worker ms / trial in the storage (first → last quarter) | one heartbeat [ms] | "
             "server CPU ms / trial | "
             f"{WORKERS} workers: share of time simulating | {STUDY_TRIALS} trials: each worker's wall [s] | "
             f"{STUDY_TRIALS} trials: server CPU [s] |",
             "|---|---|---|---|---|---|---|"]
    for key, r in res["engines"].items():
        db, srv, hb = r["s_per_trial"], r.get("server_cpu_s_per_trial"), r.get("heartbeat_s")
        q = r["quarters_s_per_trial"]
        lines.append(f"| {key.replace('/', ', batch ')} | {db * 1e3:.1f} ({q[0] * 1e3:.1f} → {q[-1] * 1e3:.1f}) | "
                     f"{'—' if hb is None or np.isnan(hb) else f'{hb * 1e3:.1f}'} | "
                     f"{'—' if srv is None else f'{srv * 1e3:.1f}'} | {sim / (sim + db):.0%} | "
                     f"{per_worker * (sim + db):.1f} | {'—' if srv is None else f'{STUDY_TRIALS * srv:.1f}'} |")
    if res.get("postgresql_skipped"):
        lines += ["", f"PostgreSQL not measured: {res['postgresql_skipped']}."]
    lines += ["", _verdict(res)]
    lines += ["", f"Extrapolated: each of {WORKERS} workers runs {per_worker:.1f} trials, each costing the simulator's "
              "time plus the storage's (a worker's round trips are sequential in its own loop): share simulating = "
              "sim / (sim + storage).  The server's CPU for the study is the trial count × its CPU per trial, spread "
              "over its cores; it is the one part the workers share."]
    return "\n".join(lines)


def _verdict(res: dict) -> str:
    """One paragraph: what bounds a 2000-trial, 32-worker study on each storage, from the measured numbers."""
    sim = res["simulator_s_per_trial"]
    best = {e: min((r for k, r in res["engines"].items() if k.startswith(e + "/")), key=lambda r: r["s_per_trial"])
            for e in ("sqlite", "journal", "postgresql") if any(k.startswith(e + "/") for k in res["engines"])}
    db = min(r["s_per_trial"] for r in best.values())
    text = (f"**Bottleneck.** With the drill's {sim * 1e3:.1f} ms per simulation, every storage costs a worker more "
            f"than the simulator does (at least {db / sim:.0f}× per trial, mostly the client's own SQLAlchemy / "
            f"journal work and round trips, which each worker pays for itself and which therefore scale with the "
            f"workers); the simulator is the bottleneck only for a model slower than about {db * 1e3:.0f} ms per "
            f"trial, where batch size and storage stop mattering.")
    pg = best.get("postgresql")
    if pg and pg.get("server_cpu_s_per_trial"):
        rate = WORKERS / (sim + pg["s_per_trial"])
        cores = rate * pg["server_cpu_s_per_trial"]
        text += (f"  The shared part is the PostgreSQL server: {WORKERS} workers ask about {rate:.0f} trials/s, "
                 f"which keeps about {cores:.1f} server cores busy ({pg['server_cpu_s_per_trial'] * 1e3:.1f} ms of "
                 f"server CPU per trial); a server with fewer cores sets the pace, and the {STUDY_TRIALS}-trial "
                 f"study then takes about {STUDY_TRIALS * pg['server_cpu_s_per_trial']:.0f} s of server CPU.  "
                 "Either way such a study is done in seconds to a minute: worth a server only for slower models "
                 "or many more trials.")
    return text


def main(quick: bool = False) -> dict:
    res = measure(quick)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"storage{'_quick' if quick else ''}.json").write_text(json.dumps(res, indent=1, default=float))
    if not quick:
        write_block(DOC, START, END, table(res))
    print(table(res))
    return res


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="100 trials per row, nothing written to docs/scale.md")
    a = ap.parse_args()
    os.environ.setdefault("VIBRO_NO_MLFLOW", "1")
    main(a.quick)
