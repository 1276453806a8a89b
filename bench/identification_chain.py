"""The identification matrix with the data-acquisition chain: the same verdicts on logs recorded through a DAQ.

Each case of ``bench.identification`` (a control, §6 effects, pairs of effects, physics outside the library) is
written by the independent generator through a named chain of ``tests.independent.daq.DAQ_CHAINS`` and diagnosed:

    off             no chain (the lab-grade log)
    compensated     8th-order Butterworth at 0.45 fs, declared in runs.csv, delay removed by the DAQ  (butter8-comp)
    uncompensated   the same, declared, its delay left in the data                                    (butter8)
    undeclared      the same with a 50 ppm clock, nothing declared: the chain estimated as nuisance   (butter8-undeclared)
    saturated       the accelerometer clipped at 80 % of its record's peak                            (clip80)

    python -m bench.identification_chain                                   # the drill subset below, seed 0
    python -m bench.identification_chain --systems drill indenter-metal --seeds 0 1
    python -m bench.identification_chain --cases control shaker_coil --chains off undeclared

    python -m bench.identification_chain --systems rimd --chains saturated --fresh --block saturated

Rows are kept in bench/results/identification/rows_chain.json (an interrupted run resumes; ``--fresh`` diagnoses
the selected cases again) and each system's tables go to docs/identification.md between that system's chain-table
markers, with the machine's load; the other systems' tables stay as they were (``--block NAME``: all the selected
rows' tables between that block's markers instead).
"""
from __future__ import annotations

import argparse
import json
import os
import sys

from bench.identification import DOC, WORK, _fmt, log_name, pair_of, run_case, spec_of

CHAINS = {"off": None, "compensated": "butter8-comp", "uncompensated": "butter8", "undeclared": "butter8-undeclared",
          "saturated": "clip80"}
"""Column of the matrix -> the generator's named chain."""
_INDENTER = ["control", "shaker_coil", "guide_friction", "sensor_lowpass", "pair:shaker_coil+guide_friction",
             "outside:quadratic_damping"]
CASES = {"drill": ["control", "shaker_coil", "guide_friction", "rate_stiffening", "pair:shaker_coil+guide_friction",
                   "pair:rate_stiffening+suspension_hardening", "outside:quadratic_damping"],
         "indenter-metal": _INDENTER, "indenter-sandstone": _INDENTER,
         "pendulum": ["control", "rate_stiffening", "sensor_lowpass", "pair:rate_stiffening+sensor_lowpass",
                      "outside:quadratic_damping"],
         "rimd": ["control", "rate_stiffening", "suspension_hardening", "sensor_lowpass",
                  "pair:suspension_hardening+sensor_lowpass", "outside:quadratic_damping"]}
"""The default cases per system: the control, §6 effects, two pairs and an outside kind."""


def markers(system: str) -> tuple[str, str]:
    """docs/identification.md's markers around one system's tables."""
    return f"<!-- identification-chain:{system}:start -->", f"<!-- identification-chain:{system}:end -->"


def block_markers(name: str) -> tuple[str, str]:
    """docs/identification.md's markers around a named block of tables (``--block``)."""
    return f"<!-- identification-chain-{name}:start -->", f"<!-- identification-chain-{name}:end -->"


DELAY_TOL_US, CLOCK_TOL_PPM = 5.0, 5.0


def settings_of(column: str) -> dict:
    """Diagnose settings of a column: an undeclared chain is estimated (the default, said explicitly here)."""
    return {"estimate_chain": True} if column == "undeclared" else {}


def table(rows: list[dict]) -> str:
    """Per system and chain column: right / total, by kind of case, the chain estimate's errors; then every log."""
    lines = ["| system | chain | right | controls 'nothing missing' | effects selected | pairs: both named | "
             f"outside 'unexplained' | delay error ≤ {DELAY_TOL_US:g} µs | clock error ≤ {CLOCK_TOL_PPM:g} ppm |",
             "|---|---|---|---|---|---|---|---|---|"]
    for system, col in sorted({(r["system"], r["column"]) for r in rows}, key=lambda k: (k[0], list(CHAINS).index(k[1]))):
        rs = [r for r in rows if r["system"] == system and r["column"] == col]

        def frac(sel):
            xs = [r for r in rs if sel(r)]
            return f"{sum(r['correct'] for r in xs)}/{len(xs)}" if xs else "—"

        def within(key, tol):
            xs = [r[key] for r in rs if r.get(key) is not None]
            return f"{sum(x <= tol for x in xs)}/{len(xs)} (max {max(xs):.3g})" if xs else "—"
        lines.append(f"| {system} | {col} | {frac(lambda r: True)} | {frac(lambda r: r['expected'] == 'nothing missing')}"
                     f" | {frac(lambda r: r['expected'] == 'selected' and not pair_of(r['case']))}"
                     f" | {frac(lambda r: bool(pair_of(r['case'])))}"
                     f" | {frac(lambda r: r['expected'] == 'unexplained')}"
                     f" | {within('delay_error_us', DELAY_TOL_US)} | {within('clock_error_ppm', CLOCK_TOL_PPM)} |")
    right = sum(r["correct"] for r in rows)
    loads = [r["load_1min"] for r in rows if r.get("load_1min") is not None]
    if loads:
        lines.insert(0, f"Load average (1 min) after each diagnosis: {min(loads):.1f}-{max(loads):.1f}.\n")
    lines += [f"| **all** | | **{right}/{len(rows)}** | | | | | | |", "",
              "| log | chain | verdict | selected | nrms base → final | noise floor | diagnosis wall (CPU) |",
              "|---|---|---|---|---|---|---|"]
    for r in rows:
        sel = r["selected"] or (f"({r['leader']})" if r["leader"] else "—")
        lines.append(f"| {r['name']} | {r['column']} | {r['verdict']} {'✓' if r['correct'] else '✗'} | {sel} | "
                     f"{_fmt(r['base_nrms'])} → {_fmt(r['final_nrms'])} | {_fmt(r['noise_floor'])} | "
                     f"{r['wall_time_s']:.0f} s ({r['cpu_time_s']:.0f} s) |")
    return "\n".join(lines)


def _todo(a) -> list[tuple[str, str, str, int]]:
    """(system, case, column, seed), one case of each column in turn, so a partial run covers every column."""
    return [(s, c, col, seed) for seed in a.seeds for s in a.systems for c in (a.cases or CASES.get(s, ["control"]))
            for col in a.chains]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--systems", nargs="+", default=["drill"])
    p.add_argument("--cases", nargs="+", help="control, §6 effect names, pair:a+b, outside:<name>")
    p.add_argument("--chains", nargs="+", default=list(CHAINS), choices=list(CHAINS))
    p.add_argument("--noise", default="rig")
    p.add_argument("--seeds", nargs="+", type=int, default=[0])
    p.add_argument("--n-runs", type=int, default=8)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--fresh", action="store_true",
                   help="diagnose the selected cases again (the logs and the other cases' stored rows are kept)")
    p.add_argument("--block", metavar="NAME",
                   help="write all the selected rows' tables between docs/identification.md's "
                        "identification-chain-NAME markers instead of each system's (e.g. one column measured again)")
    p.add_argument("--no-doc", action="store_true", help="do not rewrite docs/identification.md")
    p.add_argument("--tables-only", action="store_true", help="write the tables from the stored rows, diagnose nothing")
    a = p.parse_args(argv)
    WORK.mkdir(parents=True, exist_ok=True)
    done_file = WORK / "rows_chain.json"
    done = {r["name"]: r for r in json.loads(done_file.read_text())} if done_file.exists() else {}
    todo = _todo(a)
    if a.fresh:
        for s, c, col, seed in todo:
            done.pop(log_name(spec_of(s, c, a.noise, seed, a.n_runs, CHAINS[col]), c), None)
    rows = []
    for k, (s, c, col, seed) in enumerate(todo, 1):
        name = log_name(spec_of(s, c, a.noise, seed, a.n_runs, CHAINS[col]), c)
        if name not in done and a.tables_only:
            continue
        if name not in done:
            r = run_case(s, c, a.noise, seed, a.threads, settings_of(col), a.n_runs, CHAINS[col])
            done[name] = {**r, "column": col, "load_1min": os.getloadavg()[0]}
            done_file.write_text(json.dumps(list(done.values()), indent=1, default=float))
            print(f"[{k}/{len(todo)}] {name}: {r['verdict']} {'✓' if r['correct'] else '✗'} (selected {r['selected']},"
                  f" nrms {_fmt(r['base_nrms'])} -> {_fmt(r['final_nrms'])}, {r['wall_time_s']:.0f} s)", flush=True)
        rows.append(done[name])
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    systems = dict.fromkeys(r["system"] for r in rows)
    groups = ({block_markers(a.block): rows} if a.block else
              {markers(system): [r for r in rows if r["system"] == system] for system in systems})
    for where, mine in groups.items():
        text = (table(mine) + f"\n\nLoad average when the tables were written (1, 5, 15 min): {load}; {len(mine)} "
                              f"logs, noise '{a.noise}'.")
        print(text)
        if not a.no_doc:
            from bench import write_block

            write_block(DOC, *where, text)
    kinds = sorted({r["expected"] for r in rows})
    print(json.dumps({"rows": len(rows), "right": sum(r["correct"] for r in rows),
                      "expected": {e: sum(r["expected"] == e for r in rows) for e in kinds}}), file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
