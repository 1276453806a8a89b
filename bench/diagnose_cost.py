"""Where a diagnosis's time goes: the per-stage cost (report.json ``cost``) of ``vibro diagnose`` on a few logs of
the identification matrix (``bench/identification.py``): a drill control, a drill §6 effect, an indenter effect and
physics outside the library.

    python -m bench.diagnose_cost                         # the logs of LOGS, seed 0, rig noise
    python -m bench.diagnose_cost --logs drill:control@16 indenter-metal:guide_friction --fresh

A log is ``system:case`` (8 runs, as in the matrix) or ``system:case@N`` (the first N runs of the rig's grid; the
drill's whole grid is 16).  The logs are the matrix's own (written by the independent generator under
bench/results/identification/logs, or reused from there); every number of the table is the diagnosis's report.json
``cost``, with the machine's load average when each diagnosis ended.  A log already in
bench/results/diagnose_cost.json is not diagnosed again (``--fresh``: every one is); the table goes between the
diagnose-cost markers of docs/diagnose.md.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
from pathlib import Path

from bench.identification import ROOT, WORK, spec_of

OUT = Path(__file__).resolve().parent / "results" / "diagnose_cost.json"
DOC = ROOT / "docs" / "diagnose.md"
MARKERS = ("<!-- diagnose-cost:start -->", "<!-- diagnose-cost:end -->")
LOGS = ("drill:control", "drill:shaker_coil", "indenter-metal:guide_friction", "drill:outside:quadratic_damping",
        "drill:control@16", "drill:shaker_coil@16")
"""system:case[@runs] of the identification matrix (bench.identification.cases)."""
N_RUNS = 8
"""Runs of a log that names none (the matrix's logs)."""


def parse_log(item: str) -> tuple[str, str, int]:
    """(system, case, runs) of ``system:case[@runs]``."""
    head, _, runs = item.partition("@")
    system, case = head.split(":", 1)
    return system, case, int(runs) if runs else N_RUNS


def diagnose_log(system: str, case: str, noise: str, seed: int, n_runs: int | None, threads: int) -> dict:
    """Write (or reuse) the matrix's log of ``case`` and diagnose it with the default settings; its name, verdict,
    runs and report.json ``cost``."""
    from pipeline.datasets.measured import load_dataset
    from pipeline.diagnosis.outputs import diagnose_into
    from pipeline.diagnosis.run import DiagnoseConfig
    from tests.independent.generator import generate

    spec = spec_of(system, case, noise, seed, n_runs)
    data, truth = WORK / "logs" / spec.name, WORK / "logs" / f"{spec.name}.truth.json"
    if not truth.exists():
        shutil.rmtree(data, ignore_errors=True)
        generate(spec, data, truth, threads=threads)
    out = WORK / "cost" / spec.name
    shutil.rmtree(out, ignore_errors=True)
    rep = diagnose_into(load_dataset(data), out, DiagnoseConfig(n_threads=threads), log=lambda s: None).report
    r = rep.systems[0]
    return {"log": spec.name, "system": system, "case": case, "verdict": r.verdict,
            "selected": "+".join(r.selected) if r.selected else None, "n_runs": r.n_runs, "cost": rep.cost}


def _stage_table(rows: list[dict]) -> list[str]:
    """Stages as rows, logs as columns: simulations / CPU s / wall s (a stage's per-model parts indented)."""
    from pipeline.core.units import label

    order: list[tuple[str, str | None]] = []       # every stage in the order seen, its parts right under it
    for r in rows:
        for s in r["cost"]["stages"]:
            key = (s["stage"], s["part_of"])
            if key in order:
                continue
            at = len(order)
            if s["part_of"] is not None:
                at = max(i for i, (n, p) in enumerate(order) if n == s["part_of"] or p == s["part_of"]) + 1
            order.insert(at, key)
    cols = f"{label('simulations')} / {label('cpu_s')} / {label('wall_s')}"
    lines = [f"| stage ({cols}) | " + " | ".join(f"`{r['log']}`" for r in rows) + " |",
             "|---|" + "---|" * len(rows)]

    def cell(s: dict | None) -> str:
        return "—" if s is None else f"{s['simulations']} / {s['cpu_s']:.1f} / {s['wall_s']:.1f}"
    for name, part in order:
        stages = [next((s for s in r["cost"]["stages"] if (s["stage"], s["part_of"]) == (name, part)), None)
                  for r in rows]
        lines.append(f"| {name if part is None else '↳ ' + name} | " + " | ".join(cell(s) for s in stages) + " |")
    lines.append("| **total** | " + " | ".join(f"**{cell(r['cost']['total'])}**" for r in rows) + " |")
    return lines


def table(rows: list[dict], threads: int) -> str:
    """The per-stage table, the verdicts and the machine's load."""
    lines = _stage_table(rows)
    lines += ["", "| log | runs | verdict | simulations per run | CPU s per run | load average (1, 5, 15 min) |",
              "|---|---|---|---|---|---|"]
    for r in rows:
        t, n = r["cost"]["total"], r["n_runs"]
        lines.append(f"| `{r['log']}` | {n} | {r['verdict']}{' (' + r['selected'] + ')' if r['selected'] else ''} | "
                     f"{t['simulations'] / n:.0f} | {t['cpu_s'] / n:.1f} | "
                     f"{', '.join(f'{x:g}' for x in r['cost']['load_avg'])} |")
    lines += ["", f"Default settings, `--threads {threads}`, {platform.machine()} with "
                  f"{os.cpu_count()} cores; ↳ rows are the fit tasks of the stage above by model "
                  "(already in its numbers)."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--logs", nargs="+", default=list(LOGS), help="system:case of the identification matrix")
    p.add_argument("--noise", default="rig")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--fresh", action="store_true", help="diagnose every log again")
    p.add_argument("--no-doc", action="store_true", help="do not rewrite docs/diagnose.md")
    a = p.parse_args(argv)
    stored = {} if a.fresh or not OUT.exists() else {r["log"]: r for r in json.loads(OUT.read_text())["rows"]}
    rows = []
    for item in a.logs:
        system, case, n_runs = parse_log(item)
        name = spec_of(system, case, a.noise, a.seed, n_runs).name
        if name in stored:
            rows.append(stored[name])
            continue
        rows.append(diagnose_log(system, case, a.noise, a.seed, n_runs, a.threads))
        t = rows[-1]["cost"]["total"]
        print(f"{rows[-1]['log']}: {rows[-1]['verdict']}, {t['simulations']} simulations, {t['cpu_s']:.1f} s CPU, "
              f"{t['wall_s']:.1f} s wall", flush=True)
    from bench import publish

    publish({"threads": a.threads, "rows": rows}, OUT, table(rows, a.threads), None if a.no_doc else DOC, MARKERS)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
