"""How well an undeclared chain's clock is told from its delays: the drill's control log written by the independent
generator through undeclared chains that differ in one part (a clock alone, a linear-phase FIR alone, the FIR with
the clock, the Butterworth with the clock), each diagnosed at the defaults.

    python -m bench.clock_split                 # 4 logs x seeds 0 and 1, about 7 minutes on 2 cores
    python -m bench.clock_split --seeds 0 --no-doc

A clock error ε turns harmonic k of a run by k Ω ε t̄ (t̄: time since the record's first sample), a delay τ by
−k Ω τ; across a log's runs and the halves of each record the two are told apart only by how t̄ differs.  The rows
say what a filter that the delays do not describe exactly does to the clock.  Rows: bench/results/clock_split.json.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import time
from pathlib import Path

import numpy as np
import pandas as pd

from bench import publish

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "identification.md"
OUT = ROOT / "bench" / "results" / "clock_split.json"
WORK = ROOT / "bench" / "results" / "identification" / "clock_split"
MARKERS = ("<!-- clock-split:start -->", "<!-- clock-split:end -->")
CASES = (("clock alone", None, 50.0), ("linear-phase FIR alone", "fir", 0.0), ("FIR and clock", "fir", 50.0),
         ("Butterworth and clock", "butter", 50.0))
"""(row, the generator's filter kind (order 8, 0.45 fs; None: none), clock error [ppm]); nothing declared."""


def _fs(log: Path, run_id: str) -> float:
    t = pd.read_csv(log / "series" / f"{run_id}.csv", usecols=["t_s"])["t_s"].to_numpy()
    return round(1.0 / float(np.median(np.diff(t))), 3)


def run_case(label: str, kind: str | None, clock_ppm: float, seed: int) -> dict:
    """Write the log, diagnose it at the defaults, compare the estimated chain with the generator's."""
    from pipeline.cli import main
    from tests.independent import daq as D
    from tests.independent.generator import LogSpec, generate

    chain = D.DaqChain(f"{kind or 'none'}-{clock_ppm:g}ppm", filter=kind, order=8, cutoff=0.45,
                       clock_ppm=clock_ppm, declared=False)
    spec = LogSpec("drill", noise="rig", seed=seed, n_runs=8, daq=chain)
    work = WORK / spec.name
    shutil.rmtree(work, ignore_errors=True)
    truth = generate(spec, work / "log", threads=2)
    t0, c0 = time.perf_counter(), time.process_time()
    assert main(["diagnose", str(work / "log"), "--out", str(work / "diag"), "--quiet", "--no-mlflow"]) == 0
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    rep = json.loads((work / "diag" / "report.json").read_text())["systems"]["drill"]
    est = rep["recording"]["estimated"]
    dc = {}
    for rid, r in truth["daq"]["runs"].items():
        dc[_fs(work / "log", rid)] = r.get("dc_delay_s", 0.0)
    delay_err = [1e6 * (d["value_s"] - dc[round(d["fs_hz"], 3)]) for d in est["delays"]]
    return {"case": label, "filter": kind, "clock_ppm": clock_ppm, "seed": seed, "verdict": rep["verdict"],
            "clock_est_ppm": est["clock_ppm"]["value"], "clock_sd_ppm": est["clock_ppm"]["sd"],
            "delay_error_us": delay_err, "delay_sd_us": [1e6 * d["sd_s"] for d in est["delays"]],
            "dc_delay_us": sorted({1e6 * v for v in dc.values()}), "wall_s": wall, "cpu_s": cpu,
            "load_1min": os.getloadavg()[0]}


def table(rows: list[dict]) -> str:
    lines = [f"Drill control, rig noise, 8 runs; load average (1 min) after each diagnosis "
             f"{min(r['load_1min'] for r in rows):.1f}-{max(r['load_1min'] for r in rows):.1f}.", "",
             "| undeclared chain | seed | verdict | clock: true → estimated ± sd [ppm] | error / sd | delays: DC delay [µs] | "
             "delay errors [µs] (sd) |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        err = r["clock_est_ppm"] - r["clock_ppm"]
        lines.append(f"| {r['case']} | {r['seed']} | {r['verdict']} | {r['clock_ppm']:g} → {r['clock_est_ppm']:.1f} ± "
                     f"{r['clock_sd_ppm']:.2f} | {err / r['clock_sd_ppm']:+.0f} | "
                     f"{', '.join(f'{x:.2f}' for x in r['dc_delay_us'])} | "
                     + ", ".join(f"{e:+.2f} ({s:.2f})" for e, s in zip(r["delay_error_us"], r["delay_sd_us"])) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.clock_split", description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="noise seeds of the generator (default 0 1)")
    p.add_argument("--no-doc", action="store_true", help="print the table, leave docs/identification.md alone")
    a = p.parse_args(argv)
    todo = [(case, seed) for case in CASES for seed in a.seeds]
    rows = []
    for i, ((label, kind, clock), seed) in enumerate(todo):
        print(f"[{i + 1}/{len(todo)}] {label}, seed {seed}", flush=True)
        rows.append(run_case(label, kind, clock, seed))
    publish({"rows": rows}, OUT, table(rows), None if a.no_doc else DOC, MARKERS)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
