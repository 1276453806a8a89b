"""Closing the loop on physics the library does not have: what each model's recommendation is worth on the true rig.

For a log of the independent generator with out-of-library physics (``bench.discovery`` writes and diagnoses it), the
operating point that maximises ROP over the log's own box (the controls its runs vary, between their extremes; the
others at the log's values) is recommended by ``vibro optimise --simulator`` (its defaults) on three models:

- ``lab``: the model the lab started from (the rig's preset, nothing fitted);
- ``calibrated``: the diagnosis's corrected rig without its correction (the calibrated parameters, no adopted
  discrepancy term, no empirical correction);
- ``corrected``: the corrected rig as written, with the correction the diagnosis adopted: a structured discrepancy
  term (``sim.models.discrepancy``) or an empirical ROP correction ("empirical correction, physics unknown":
  ``pipeline.diagnosis.empirical``).

Each recommendation is then run on the *true* rig (``tests.independent``: the scipy reference with the outside
physics, from rest, ROP over ``--window`` cycles after ``--settle-s``), and compared with the true rig's best point
on a tensor grid of the box (``--grid`` frequencies x 3 levels of each other varied control).  Writes
bench/results/close_loop_outside.json and the table between docs/discovery.md's ``close-loop-outside`` markers.

    python -m bench.close_loop_outside --logs drill-outside-rate_strength-rig-s0-n8 drill-outside-drive_mode-rig-s0-n8

Rows are kept in the results file and reused (``--fresh`` runs them again).
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
WORK = ROOT / "bench" / "results" / "discovery"
OUT = ROOT / "bench" / "results" / "close_loop_outside.json"
DOC = ROOT / "docs" / "discovery.md"
MODELS = ("lab", "calibrated", "corrected")


def true_rop(args) -> float:
    """ROP [m/s] of one operating point on the true rig (the independent reference), 0 when it does not progress."""
    system, outside, truth, point, settle_s, window = args
    from tests.independent.outside import model_for
    from tests.independent.rigs import RIGS
    from tests.reference_solutions import reference_run

    rig = RIGS[system]
    params = {**rig.known, **point, **truth}
    params.update(rig.derived(params))
    f = float(point["frequency_hz"])
    out = reference_run(model_for(system, outside), params, int(round(settle_s * f)), window, rtol=1e-9)
    return max(float(out.get("rop_m_s") or 0.0), 0.0)


def box(runs: pd.DataFrame) -> tuple[dict, dict]:
    """(varied control -> (low, high), fixed control -> value) of a log's runs."""
    from sim.controls import CONTROLS

    ctl = [c for c in CONTROLS if c in runs.columns and runs[c].notna().all()]
    varied = {c: (float(runs[c].min()), float(runs[c].max())) for c in ctl if runs[c].nunique() > 1}
    fixed = {c: float(runs[c].iloc[0]) for c in ctl if c not in varied}
    return varied, fixed


def recommend(rig_mapping: dict, varied: dict, fixed: dict, work: Path, trials: int) -> dict:
    """The point ``vibro optimise --simulator`` recommends on a rig mapping (its defaults, ``trials`` trials)."""
    import yaml

    from pipeline.cli import main as cli

    work.mkdir(parents=True, exist_ok=True)
    rig_file = work / "rig.yaml"
    rig_file.write_text(yaml.safe_dump(rig_mapping, sort_keys=False))
    out = work / "optimise"
    args = ["optimise", "--simulator", "--rig", str(rig_file), "--n-trials", str(trials), "--out", str(out),
            "--storage", f"sqlite:///{work / 'optuna.db'}", "--no-mlflow", "--quiet"]
    for n, (lo, hi) in varied.items():
        args += ["--vary", f"{n}={lo:g}:{hi:g}"]
    for n, v in fixed.items():
        args += ["--set", f"{n}={v:g}"]
    if cli(args) != 0:
        raise RuntimeError(f"optimise failed in {work}")
    rec = json.loads((out / "report.json").read_text())["recommendation"]
    return {"point": {**fixed, **rec["params"]}, "model_rop_m_s": rec["rop_m_s_sim"]}


def correction_of(rig: dict) -> str:
    """What a corrected rig mapping corrects with: its discrepancy terms, "empirical", or "none"."""
    if rig.get("discrepancy"):
        return "discrepancy: " + ", ".join(rig["discrepancy"])
    return "empirical" if "empirical_correction" in rig else "none"


def run_case(name: str, grid: int, trials: int, settle_s: float, window: int, workers: int) -> dict:
    import yaml

    truth = json.loads((WORK / "logs" / f"{name}.truth.json").read_text())
    system, outside = truth["system"], truth["outside"]
    runs = pd.read_csv(WORK / "logs" / name / "runs.csv")
    varied, fixed = box(runs)
    corrected = yaml.safe_load((WORK / "diagnoses" / name / "rig.yaml").read_text())
    calibrated = {k: v for k, v in corrected.items() if k not in ("empirical_correction", "discrepancy")}
    lab = {"model": corrected["model"], **({"preset": corrected["preset"]} if corrected.get("preset") else {})}
    work = ROOT / "bench" / "results" / "close_loop_outside" / name
    shutil.rmtree(work, ignore_errors=True)       # a study from an earlier run would be resumed, not redone
    recs = {m: recommend(r, varied, fixed, work / m, trials) for m, r in zip(MODELS, (lab, calibrated, corrected))}
    axes = [np.linspace(lo, hi, grid if n == "frequency_hz" else 3) for n, (lo, hi) in varied.items()]
    points = [{**fixed, **dict(zip(varied, v))} for v in np.array(np.meshgrid(*axes, indexing="ij")).reshape(
        len(axes), -1).T]
    jobs = [(system, outside, truth["truth"], p, settle_s, window) for p in points + [recs[m]["point"] for m in MODELS]]
    t0 = time.time()
    with ProcessPoolExecutor(workers) as pool:
        rops = list(pool.map(true_rop, jobs))
    scan = rops[:len(points)]
    best = int(np.argmax(scan))
    row = {"name": name, "system": system, "outside": outside, "box": varied, "fixed": fixed,
           "empirical_adopted": "empirical_correction" in corrected, "correction": correction_of(corrected),
           "grid": grid, "settle_s": settle_s,
           "window_cycles": window, "true_best_rop_m_s": scan[best], "true_best_point": points[best],
           "reference_s": round(time.time() - t0, 1)}
    for m, r in zip(MODELS, rops[len(points):]):
        row[m] = {**recs[m], "true_rop_m_s": r, "ratio": r / scan[best] if scan[best] > 0 else None}
    return row


def table(rows: list[dict]) -> str:
    head = ("| log | correction adopted | true rig's best on the grid [mm/s] | lab model's point | "
            "calibrated model's point | corrected model's point |")
    lines = [head, "|---|---|---|---|---|---|"]
    for r in rows:
        cells = []
        for m in MODELS:
            x = r[m]
            p = ", ".join(f"{k} {v:.4g}" for k, v in x["point"].items() if k in r["box"])
            cells.append(f"{1e3 * x['true_rop_m_s']:.3g} mm/s ({100 * x['ratio']:.1f} %) at {p}")
        word = r.get("correction") or ("empirical" if r["empirical_adopted"] else "none")
        lines.append(f"| {r['name']} | {word} | "
                     f"{1e3 * r['true_best_rop_m_s']:.3g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--logs", nargs="+", required=True, help="log names under bench/results/discovery/logs")
    p.add_argument("--grid", type=int, default=15, help="frequencies of the true rig's scan")
    p.add_argument("--trials", type=int, default=200)
    p.add_argument("--settle-s", type=float, default=0.5)
    p.add_argument("--window", type=int, default=30)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--fresh", action="store_true", help="run the logs already in the results again")
    p.add_argument("--no-doc", action="store_true")
    a = p.parse_args(argv)
    done = {r["name"]: r for r in json.loads(OUT.read_text())["rows"]} if OUT.exists() else {}
    for name in a.logs:
        if name in done and not a.fresh:
            continue
        done[name] = run_case(name, a.grid, a.trials, a.settle_s, a.window, a.workers)
        r = done[name]
        print(f"{name}: " + ", ".join(f"{m} {100 * r[m]['ratio']:.1f} %" for m in MODELS), flush=True)
        OUT.write_text(json.dumps({"rows": list(done.values())}, indent=1, default=float))
    rows = [done[n] for n in a.logs]
    text = table(rows)
    print(text)
    if not a.no_doc:
        from bench import write_between_markers

        write_between_markers(ROOT, ["docs/discovery.md"], "<!-- close-loop-outside:start -->",
                              "<!-- close-loop-outside:end -->", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
