"""Discovery matrix of ``vibro diagnose`` on rig logs it did not make: proposals for physics outside the library,
and two §6 effects at once.

Every system × (each out-of-library physics of the independent rig, a pair of its §6 effects) × noise models: the log
is written by the independent generator in ``tests/independent`` (scipy reference with event location, signals
sampled at the DAQ's own instants, the noise a rig makes) and diagnosed at the defaults (``max_proposals`` 3), a pair
with ``max_effects: 2``.  Scored against the truth:

- out-of-library physics: the top proposal brings the held-out nrms within ``explained_nrms`` (2: twice the noise)
  **and** names the right kind of term (``tests.independent.rigs.OUTSIDE_KIND``: contact, velocity loss, or mode:
  the structured ``load_path_mode`` candidate; a sensor resonance has no term in the vocabulary);
- pairs of §6 effects: both selected;
- controls are not run here: discovery only runs on an "unexplained" verdict, and the identification matrix
  (``python -m bench.identification``) scores the controls' "nothing missing".

    python -m bench.discovery --n-runs 8                        # the matrix (hours on 2 cores; resumable)
    python -m bench.discovery --systems drill --cases outside:quadratic_damping --noise rig
    python -m bench.discovery --systems drill indenter-metal pendulum rimd --cases held-out --noise rig \
        --daq field --block held-out-field          # the held-out kinds recorded through a field DAQ chain

Logs and rows are kept under ``bench/results/discovery/`` (resumes; ``--fresh`` diagnoses again); the tables go to
docs/discovery.md between its generated-table markers and the summary to bench/results/discovery.json.
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).resolve().parent / "results"
WORK = RESULTS / "discovery"
DOC = ROOT / "docs" / "discovery.md"
START, END = "<!-- discovery:start -->", "<!-- discovery:end -->"
NOISE = ("rig", "white2")
PAIRS = {"drill": ("guide_friction", "tip_blunting"), "indenter-metal": ("guide_friction", "suspension_hardening"),
         "indenter-sandstone": ("tip_blunting", "guide_friction"), "pendulum": ("rate_stiffening", "sensor_lowpass"),
         "rimd": ("rate_stiffening", "suspension_hardening")}
"""The pair of §6 effects each rig gets at once (the independent rig's visible strengths)."""


def cases(system: str) -> list[str]:
    """Every out-of-library physics of the independent rig in the dynamics (not the sensor's, e.g. a mount
    resonance: the vocabulary is of the model's equations), then the pair."""
    from tests.independent.outside import OUTSIDE
    from tests.independent.rigs import RIGS

    return [*(f"outside:{o}" for o in RIGS[system].outside if not OUTSIDE[o].measurement),
            "pair:" + "+".join(PAIRS[system])]


def spec_of(system: str, case: str, noise: str, seed: int, n_runs: int | None, daq: str | None = None):
    """The generator's log of a case; ``daq``: a named chain of ``tests.independent.daq.DAQ_CHAINS`` (None: none)."""
    from tests.independent.daq import DAQ_CHAINS
    from tests.independent.generator import LogSpec
    from tests.independent.rigs import RIGS

    chain = None if daq is None else DAQ_CHAINS[daq]
    if case.startswith("outside:"):
        return LogSpec(system, outside=case.split(":", 1)[1], noise=noise, seed=seed, n_runs=n_runs, daq=chain)
    first, second = case.split(":", 1)[1].split("+")
    return LogSpec(system, effect=first, noise=noise, seed=seed, n_runs=n_runs,
                   overrides=dict(RIGS[system].effects[second]), daq=chain)


def row_name(system: str, case: str, noise: str, seed: int, n_runs: int | None, daq: str | None = None) -> str:
    what = case.replace(":", "-")
    return (f"{system}-{what}-{noise}" + ("" if daq is None else f"-{daq}") + f"-s{seed}"
            + ("" if n_runs is None else f"-n{n_runs}"))


def run_case(system: str, case: str, noise: str, seed: int, threads: int, n_runs: int | None,
             daq: str | None = None) -> dict:
    """Generate (or reuse) the log, diagnose it, and score the proposals / the pair against the truth."""
    from tests.independent.generator import generate
    from tests.independent.rigs import OUTSIDE_KIND

    name = row_name(system, case, noise, seed, n_runs, daq)
    data, truth_file = WORK / "logs" / name, WORK / "logs" / f"{name}.truth.json"
    if not truth_file.exists():
        shutil.rmtree(data, ignore_errors=True)
        generate(spec_of(system, case, noise, seed, n_runs, daq), data, truth_file, threads=threads)
    from pipeline.datasets.measured import load_dataset
    from pipeline.diagnosis.outputs import diagnose_into
    from pipeline.diagnosis.run import DiagnoseConfig

    out = WORK / "diagnoses" / name
    shutil.rmtree(out, ignore_errors=True)
    cfg = DiagnoseConfig(n_threads=threads, max_effects=2 if case.startswith("pair:") else 1)
    t0, c0 = time.time(), time.process_time()
    rep = diagnose_into(load_dataset(data), out, cfg, log=lambda s: None).report
    wall, cpu = time.time() - t0, time.process_time() - c0
    r = rep.system(system)
    disc, e = r.discrepancy, r.errors
    props = disc.proposals if disc else ()
    top = props[0] if props else None
    row = {"system": system, "case": case, "noise": noise if daq is None else f"{noise}, {daq}", "seed": seed,
           "name": name, "verdict": r.verdict,
           "selected": "+".join(r.selected) if r.selected else None, "selected_effects": list(r.selected or ()),
           "base_nrms": e.base.nrms, "final_nrms": e.final.nrms, "noise_floor": e.noise_floor,
           "base_error": e.base.error, "final_error": e.final.error, "accepted": disc.accepted if disc else None,
           "proposals": [{"terms": list(p.terms), "kinds": list(p.kinds), "coefficients": p.coefficients,
                          "coefficient_sd": p.coefficient_sd, "nrms": p.nrms, "error": p.error, "adequate": p.adequate,
                          "improves": p.improves} for p in props],
           "screening": [{"term": s.term, "entered": s.entered, "score": s.score, "in_support": s.in_support}
                         for s in (disc.screening if disc else ())],
           "empirical": None if r.empirical is None else r.empirical.to_json(),
           "n_simulations": r.n_simulations, "wall_time_s": round(wall, 1), "cpu_time_s": round(cpu, 1)}
    if case.startswith("outside:"):
        kind = OUTSIDE_KIND[case.split(":", 1)[1]]
        row["expected"] = f"proposal: {kind}"
        row["top_within_2x"] = bool(top is not None and top.nrms <= cfg.explained_nrms)
        row["right_kind"] = bool(top is not None and kind in top.kinds)
        row["correct"] = row["top_within_2x"] and row["right_kind"]
    else:
        pair = set(case.split(":", 1)[1].split("+"))
        row["expected"] = "both effects"
        row["correct"] = set(r.selected or ()) == pair
    return row


def _fmt(x, spec=".3g") -> str:
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def wrong_adoption(r: dict) -> bool:
    """An out-of-library row whose accepted proposal is of another kind than the truth's (the rig file would carry
    the wrong physics)."""
    from sim.models.discrepancy import CANDIDATES
    from tests.independent.rigs import OUTSIDE_KIND

    if not r["case"].startswith("outside:") or not r["accepted"]:
        return False
    return OUTSIDE_KIND[r["case"].split(":", 1)[1]] not in {CANDIDATES[t].kind for t in r["accepted"]}


def _kind_in_vocabulary(r: dict) -> bool:
    """Whether the vocabulary has a term of the kind of the row's out-of-library physics."""
    from sim.models.discrepancy import CANDIDATES
    from tests.independent.rigs import OUTSIDE_KIND

    return OUTSIDE_KIND[r["case"].split(":", 1)[1]] in {t.kind for t in CANDIDATES.values()}


def _empirical_cell(r: dict) -> str:
    """The empirical ROP correction's held-out ROP error before → after, and whether it was adopted."""
    if "empirical" not in r:
        return "not measured"
    e = r["empirical"]
    if e is None:
        return "—"
    if e["heldout_rop_error_before"] is None:
        return "not tried: " + e["text"].split("(", 1)[-1].rstrip(")")
    return (f"{100 * e['heldout_rop_error_before']:.3g} % → {100 * e['heldout_rop_error_after']:.3g} % "
            f"({'adopted' if e['adopted'] else 'not adopted'})")


def table(rows: list[dict]) -> str:
    """Summary per kind of case and noise model, then every log."""
    lines = ["| cases | noise | right | top proposal within 2× the noise | names the right kind | wrong proposal adopted |",
             "|---|---|---|---|---|---|"]
    kinds = sorted({r["case"] if r["case"].startswith("outside:") else "pair of §6 effects" for r in rows})
    for k in kinds:
        for noise in sorted({r["noise"] for r in rows}):
            rs = [r for r in rows if r["noise"] == noise and (r["case"] == k or (k.startswith("pair") and r["case"].startswith("pair:")))]
            if not rs:
                continue
            within = f"{sum(r.get('top_within_2x', False) for r in rs)}/{len(rs)}" if k.startswith("outside") else "—"
            kind = f"{sum(r.get('right_kind', False) for r in rs)}/{len(rs)}" if k.startswith("outside") else "—"
            wrong = f"{sum(wrong_adoption(r) for r in rs)}/{len(rs)}" if k.startswith("outside") else "—"
            lines.append(f"| {k} | {noise} | {sum(r['correct'] for r in rs)}/{len(rs)} | {within} | {kind} | {wrong} |")
    out = [r for r in rows if r["case"].startswith("outside:")]
    pairs = [r for r in rows if r["case"].startswith("pair:")]
    lines.append(f"| **out of library** | | **{sum(r['correct'] for r in out)}/{len(out)}** | "
                 f"{sum(r.get('top_within_2x', False) for r in out)}/{len(out)} | {sum(r.get('right_kind', False) for r in out)}/{len(out)} | "
                 f"{sum(wrong_adoption(r) for r in out)}/{len(out)} |")
    covered = [r for r in out if _kind_in_vocabulary(r)]
    lines.append(f"| **out of library, kinds the vocabulary has** | | **{sum(r['correct'] for r in covered)}/{len(covered)}** | "
                 f"{sum(r.get('top_within_2x', False) for r in covered)}/{len(covered)} | "
                 f"{sum(r.get('right_kind', False) for r in covered)}/{len(covered)} | "
                 f"{sum(wrong_adoption(r) for r in covered)}/{len(covered)} |")
    lines.append(f"| **pairs of §6 effects, both selected** | | **{sum(r['correct'] for r in pairs)}/{len(pairs)}** | | | |")
    tried = [r for r in rows if (r.get("empirical") or {}).get("heldout_rop_error_before") is not None]
    if tried:
        lines.append(f"| **empirical ROP correction** (logs left unexplained, held-out ROP measured) | | adopted "
                     f"{sum(r['empirical']['adopted'] for r in tried)}/{len(tried)}, halves the held-out ROP error "
                     f"{sum(r['empirical']['halved'] for r in tried)}/{len(tried)} | | | |")
    lines += ["", "| log | verdict | selected / accepted proposal | top proposal (kind): held-out nrms | nrms base → final | "
              "empirical ROP correction: held-out ROP error | noise floor | diagnosis wall (CPU) |",
              "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ok = "✓" if r["correct"] else "✗"
        top = r["proposals"][0] if r["proposals"] else None
        tp = (f"{' + '.join(top['terms'])} ({', '.join(top['kinds'])}): {_fmt(top['nrms'])}" if top else "—")
        sel = r["selected"] or ("proposal " + " + ".join(r["accepted"]) if r["accepted"] else "—")
        lines.append(f"| {r['name']} {ok} | {r['verdict']} | {sel} | {tp} | {_fmt(r['base_nrms'])} → "
                     f"{_fmt(r['final_nrms'])} | {_empirical_cell(r)} | {_fmt(r['noise_floor'])} | {r['wall_time_s']:.0f} s ({r['cpu_time_s']:.0f} s) |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from tests.independent.daq import DAQ_CHAINS
    from tests.independent.kinds import KINDS_SYSTEMS

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--systems", nargs="+", default=["drill", "indenter-metal", "indenter-sandstone", "pendulum", "rimd"])
    p.add_argument("--cases", nargs="+", help="subset: outside:<name>, pair, held-out (the held-out kinds of "
                                              "tests/independent/kinds.py)")
    p.add_argument("--noise", nargs="+", default=list(NOISE))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--n-runs", type=int, default=8, help="the first N runs spread over each rig's grid")
    p.add_argument("--daq", metavar="CHAIN", choices=sorted(DAQ_CHAINS),
                   help="record the logs through this named DAQ chain of the generator (e.g. field: an 8th-order "
                        "Butterworth at 0.45 fs, a 50 ppm clock, a clipped accelerometer and 50 Hz hum)")
    p.add_argument("--fresh", action="store_true",
                   help="diagnose the selected cases again (their logs and the other cases' stored rows are kept)")
    p.add_argument("--no-doc", action="store_true",
                   help="do not rewrite docs/discovery.md nor bench/results/discovery*.json (the rows are stored)")
    p.add_argument("--tables-only", action="store_true", help="write the tables from the stored rows, diagnose nothing")
    p.add_argument("--block", metavar="NAME",
                   help="write the tables between docs/discovery.md's discovery-NAME markers instead (a subset, e.g. "
                        "the held-out kinds), leaving the matrix's table and the README's summary as they are")
    a = p.parse_args(argv)
    WORK.mkdir(parents=True, exist_ok=True)
    done_file = WORK / "rows.json"
    done = {r["name"]: r for r in json.loads(done_file.read_text())} if done_file.exists() else {}
    per = {s: [c for c in cases(s) if a.cases is None or c in a.cases or (c.startswith("pair:") and "pair" in a.cases)
               or ("held-out" in a.cases and c.split(":", 1)[-1] in KINDS_SYSTEMS)] for s in a.systems}
    todo = [(s, per[s][k], n) for n in a.noise for k in range(max(map(len, per.values()), default=0))
            for s in a.systems if k < len(per[s])]
    if a.fresh:
        for s, c, n in todo:
            done.pop(row_name(s, c, n, a.seed, a.n_runs, a.daq), None)
    rows = []
    for k, (s, c, n) in enumerate(todo, 1):
        name = row_name(s, c, n, a.seed, a.n_runs, a.daq)
        if name not in done and a.tables_only:
            continue
        if name not in done:
            done[name] = run_case(s, c, n, a.seed, a.threads, a.n_runs, daq=a.daq)
            done_file.write_text(json.dumps(list(done.values()), indent=1, default=float))
            r = done[name]
            print(f"[{k}/{len(todo)}] {name}: {'✓' if r['correct'] else '✗'} {r['verdict']}, "
                  f"proposals {[p['terms'] for p in r['proposals']]}, nrms {_fmt(r['base_nrms'])} -> "
                  f"{_fmt(r['final_nrms'])} ({r['wall_time_s']:.0f} s)", flush=True)
        rows.append(done[name])
    if a.tables_only and not rows:     # no stored rows here: say so rather than overwrite the tables with empty ones
        print(f"bench.discovery --tables-only: no stored rows in {done_file} for this selection; nothing written",
              file=sys.stderr)
        return 2
    text = table(rows)
    print(text)
    summary = {"rows": len(rows), "right": sum(r["correct"] for r in rows)}
    if not a.no_doc:
        out = RESULTS / (f"discovery-{a.block}.json" if a.block else "discovery.json")
        out.write_text(json.dumps({"summary": summary, "rows": rows}, indent=1, default=float))
    if not a.no_doc and DOC.exists() and a.block:
        from bench import write_block

        write_block(DOC, f"<!-- discovery-{a.block}:start -->", f"<!-- discovery-{a.block}:end -->", text)
    elif not a.no_doc and DOC.exists():
        from bench import write_block

        write_block(DOC, START, END, text)
        from bench import write_between_markers

        write_between_markers(ROOT, ["README.md"], "<!-- discovery-summary:start -->", "<!-- discovery-summary:end -->",
                              text.split("\n\n")[0])
    print(json.dumps(summary), file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
