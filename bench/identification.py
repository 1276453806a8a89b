"""Identification matrix of ``vibro diagnose`` on rig logs it did not make.

Every system × (every §6 effect it supports, a control, physics outside the library) × noise models × seeds: the
log is written by the independent generator in ``tests/independent`` (scipy reference with event location, each
signal sampled at the DAQ's own instants, the noise a rig makes), diagnosed with the default settings, and the
verdict compared with the truth: a control must be "nothing missing", an effect must be selected with its
parameters, outside physics must be "unexplained".

    python -m bench.identification                      # the whole matrix (hours on 2 cores; resumable)
    python -m bench.identification --quick              # one seed, one noise model
    python -m bench.identification --systems drill --cases control shaker_coil --noise rig --seeds 0

Logs and per-case results are kept under ``bench/results/identification/`` (an interrupted run resumes where it
stopped; ``--fresh`` starts over); the summary goes to bench/results/identification.json and the tables to
docs/identification.md, between its generated-table markers.  Thresholds of the verdict can be replayed on the
stored statistics without diagnosing again (``--replay``): how docs/diagnose.md derives them.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from pipeline.diagnosis.report_types import Recording, SystemReport

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).resolve().parent / "results"
WORK = RESULTS / "identification"
DOC = ROOT / "docs" / "identification.md"
START, END = "<!-- identification:start -->", "<!-- identification:end -->"
RULE_DOC = ROOT / "docs" / "diagnose.md"
RULE_START, RULE_END = "<!-- verdict-stats:start -->", "<!-- verdict-stats:end -->"
NOISE = ("white2", "rig")
SEEDS = (0, 1)
PARAM_TOL = 0.05       # a selected effect's parameters within 5 % of the truth (where identifiable)


def cases(system: str) -> list[str]:
    """Every §6 effect of the independent rig, the control and every outside case."""
    from tests.independent.rigs import RIGS

    rig = RIGS[system]
    return ["control", *(f"outside:{o}" for o in rig.outside), *rig.effects]


def pair_of(case: str) -> tuple[str, str] | None:
    """``pair:a+b`` -> (a, b): two §6 effects at once, a as the log's effect and b's parameters on top."""
    return tuple(case.split(":", 1)[1].split("+", 1)) if case.startswith("pair:") else None


def spec_of(system: str, case: str, noise: str, seed: int, n_runs: int | None = None, chain: str | None = None):
    """The log of one case; ``n_runs``: the first n runs spread over the rig's grid (None: the whole grid);
    ``chain``: a named DAQ chain of the generator (``tests.independent.daq.DAQ_CHAINS``), None: none."""
    from tests.independent.daq import DAQ_CHAINS
    from tests.independent.generator import LogSpec
    from tests.independent.rigs import RIGS

    daq = None if chain is None else DAQ_CHAINS[chain]
    if case == "control":
        return LogSpec(system, noise=noise, seed=seed, n_runs=n_runs, daq=daq)
    if case.startswith("outside:"):
        return LogSpec(system, outside=case.split(":", 1)[1], noise=noise, seed=seed, n_runs=n_runs, daq=daq)
    pair = pair_of(case)
    if pair:
        return LogSpec(system, effect=pair[0], overrides=dict(RIGS[system].effects[pair[1]]), noise=noise, seed=seed,
                       n_runs=n_runs, daq=daq)
    return LogSpec(system, effect=case, noise=noise, seed=seed, n_runs=n_runs, daq=daq)


def log_name(spec, case: str) -> str:
    """The log's name: the spec's, with both effects of a pair (``drill-shaker_coil+guide_friction-rig-...``)."""
    pair = pair_of(case)
    return spec.name.replace(f"-{pair[0]}-", f"-{pair[0]}+{pair[1]}-", 1) if pair else spec.name


def expected(case: str) -> str:
    return "nothing missing" if case == "control" else ("unexplained" if case.startswith("outside:") else "selected")


def run_case(system: str, case: str, noise: str, seed: int, threads: int, settings: dict | None = None,
             n_runs: int | None = None, chain: str | None = None) -> dict:
    """Generate (or reuse) the log and diagnose it; the row of the matrix with every statistic of the verdict."""
    spec = spec_of(system, case, noise, seed, n_runs, chain)
    name = log_name(spec, case)
    data, info, gen_s = _log(spec, name, threads)
    from pipeline.datasets.measured import load_dataset
    from pipeline.diagnosis.outputs import diagnose_into
    from pipeline.diagnosis.run import DiagnoseConfig

    ds = load_dataset(data)
    out = WORK / "diagnoses" / name
    if out.exists():
        import shutil

        shutil.rmtree(out)
    t0, c0 = time.time(), time.process_time()
    rep = diagnose_into(ds, out, DiagnoseConfig(n_threads=threads, **(settings or {})), log=lambda s: None).report
    wall, cpu = time.time() - t0, time.process_time() - c0
    r = rep.system(system)
    truth = info["truth"]
    verdict = r.verdict
    fitted, right_effects = _selected_fit(r, case)
    errors = {k: fitted[k] / truth[k] - 1.0 for k in fitted if k in truth}
    base_err = {k: r.calibrated[k] / truth[k] - 1.0 for k in info["calibratable"] if k in truth}
    correct = (verdict == expected(case)) and right_effects
    e = r.errors
    return {"system": system, "case": case, "noise": noise, "seed": seed, "name": name, "chain": chain,
            "expected": expected(case), "verdict": verdict, "selected": _name(r.selected), "leader": _name(r.leader),
            "correct": bool(correct), "truth": {k: truth[k] for k in truth if k not in info["calibratable"]},
            "fitted": fitted, "param_errors": errors, "base_param_errors": base_err,
            "checks": r.call.to_json(), "candidates": [c.to_json() for c in r.candidates],
            "base_nrms": e.base.nrms, "final_nrms": e.final.nrms, "base_systematic": e.base.systematic,
            "final_systematic": e.final.systematic, "base_error": e.base.error, "final_error": e.final.error,
            "noise_floor": e.noise_floor, "n_simulations": r.n_simulations, "n_runs": r.n_runs,
            "heldout_n": e.n, **chain_errors(r.recording, info, data),
            "wall_time_s": round(wall, 1), "cpu_time_s": round(cpu, 1),
            "generate_s": None if gen_s is None else round(gen_s, 1)}


def _log(spec, name: str, threads: int) -> tuple[Path, dict, float | None]:
    """The log's folder, its truth and the seconds generating it took (None: generated before, reused)."""
    from tests.independent.generator import generate

    data = WORK / "logs" / name
    truth_file = WORK / "logs" / f"{name}.truth.json"
    gen_s = None
    if not truth_file.exists():
        if data.exists():
            import shutil

            shutil.rmtree(data)
        t0 = time.time()
        generate(spec, data, truth_file, threads=threads)
        gen_s = time.time() - t0
    return data, json.loads(truth_file.read_text()), gen_s


def _name(effects: tuple[str, ...] | None) -> str | None:
    """A model's effects as the rows name them (``a+b``)."""
    return None if effects is None else "+".join(effects)


def _selected_fit(r: SystemReport, case: str) -> tuple[dict, bool]:
    """(the fitted parameters of the case's true effect(s) when selected, whether the right effect(s) were)."""
    pair = pair_of(case)
    if pair:
        if sorted(r.selected or ()) != sorted(pair):
            return {}, False
        return dict(r.second_effect.candidates[0].params), True
    effect = case if expected(case) == "selected" else None
    if effect and r.selected == (effect,):
        return dict(next(c for c in r.candidates if c.effects == (effect,)).params), True
    return {}, effect is None


def chain_errors(recording: Recording, info: dict, data: Path) -> dict:
    """An estimated (undeclared) chain against the truth: the largest delay error [µs] over channels and rates (the
    truth: the filter's DC delay at that rate, 0 where compensated) and the clock's error [ppm]; {} when none."""
    est = recording.estimated
    runs = (info.get("daq") or {}).get("runs") or {}
    if not est or not runs:
        return {}
    true_delay: dict[float, float] = {}
    for run_id, d in runs.items():
        t = np.loadtxt(data / "series" / f"{run_id}.csv", delimiter=",", skiprows=1, usecols=0, max_rows=2)
        fs = round(1.0 / float(t[1] - t[0]), 3)
        true_delay[fs] = 0.0 if d.get("compensated") else float(d.get("dc_delay_s", 0.0))
    errs = [abs(x.value_s - true_delay[round(float(x.fs_hz), 3)]) * 1e6 for x in est.delays
            if round(float(x.fs_hz), 3) in true_delay]
    clock = next(iter(runs.values())).get("clock_ppm", 0.0)
    return {"delay_error_us": max(errs) if errs else None,
            "clock_error_ppm": abs(float(est.clock_ppm.value) - float(clock))}


def replay(rows: list[dict], rule) -> list[dict]:
    """The verdicts of ``rows`` under another VerdictRule, from their stored statistics (no diagnosis)."""
    from pipeline.diagnosis.verdict import ModelStats, decide

    out = []
    for r in rows:
        n = r["heldout_n"]
        chi2_base = r["base_nrms"] ** 2 * n
        base = ModelStats("base", 0.0, chi2_base, n, r["base_systematic"])
        cands = [ModelStats(c["effect"], c["delta_score"], chi2_base - c["delta_chi2_heldout"], n, c["systematic"])
                 for c in r["candidates"]]
        v = decide(base, cands, rule)
        effect = r["case"] if r["expected"] == "selected" else None
        ok = v.kind == r["expected"] and (effect is None or v.selected == effect)
        out.append({**r, "verdict": v.kind, "selected": v.selected, "leader": v.leader, "correct": ok})
    return out


def _fmt(x, spec=".3g") -> str:
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def table(rows: list[dict]) -> str:
    """The matrix as markdown: a summary per system and noise model, then every case."""
    lines = ["| system | noise | right | controls 'nothing missing' | effects selected | outside 'unexplained' |"
             " parameters within 5 % |", "|---|---|---|---|---|---|---|"]
    keys = sorted({(r["system"], r["noise"]) for r in rows})
    for system, noise in keys:
        rs = [r for r in rows if r["system"] == system and r["noise"] == noise]

        def frac(sel):
            xs = [r for r in rs if sel(r)]
            return f"{sum(r['correct'] for r in xs)}/{len(xs)}" if xs else "—"
        par = [r for r in rs if r["param_errors"]]
        lines.append(f"| {system} | {noise} | {frac(lambda r: True)} | {frac(lambda r: r['expected'] == 'nothing missing')} | "
                     f"{frac(lambda r: r['expected'] == 'selected')} | {frac(lambda r: r['expected'] == 'unexplained')} | "
                     f"{sum(all(abs(e) <= PARAM_TOL for e in r['param_errors'].values()) for r in par)}/{len(par)} |")
    tot = len(rows)
    right = sum(r["correct"] for r in rows)
    lines.append(f"| **all** | | **{right}/{tot} ({100 * right / max(tot, 1):.0f} %)** | | | | |")
    lines += ["", "| log | verdict | selected (leader) | effect parameters: fitted / truth − 1 | nrms base → final | "
              "systematic base → final | noise floor | diagnosis wall (CPU) |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ok = "✓" if r["correct"] else "✗"
        pe = ", ".join(f"{k} {v:+.1%}" for k, v in r["param_errors"].items()) or "—"
        lead = r["selected"] or (f"({r['leader']})" if r["leader"] else "—")
        lines.append(f"| {r['name']} | {r['verdict']} {ok} | {lead} | {pe} | {_fmt(r['base_nrms'])} → "
                     f"{_fmt(r['final_nrms'])} | {_fmt(r['base_systematic'])} → {_fmt(r['final_systematic'])} | "
                     f"{_fmt(r['noise_floor'])} | {r['wall_time_s']:.0f} s ({r['cpu_time_s']:.0f} s) |")
    return "\n".join(lines)


def _spread(xs: list) -> str:
    xs = sorted(x for x in xs if x is not None and math.isfinite(x))
    if not xs:
        return "—"
    return f"{xs[0]:.3g} / {xs[len(xs) // 2]:.3g} / {xs[-1]:.3g}"


def rule_table(rows: list[dict]) -> str:
    """What each threshold of the verdict saw over the matrix (min / median / max): the statistics the rule's
    thresholds are set against (docs/diagnose.md)."""
    def lead(r):
        name = r["leader"] or (r["candidates"][0]["effect"] if r["candidates"] else None)
        return next((c for c in r["candidates"] if c["effect"] == name), None)

    def true_c(r):
        return next((c for c in r["candidates"] if c["effect"] == r["case"]), None)

    ctl = [r for r in rows if r["expected"] == "nothing missing"]
    eff = [r for r in rows if r["expected"] == "selected"]
    out = [r for r in rows if r["expected"] == "unexplained"]
    lines = ["| statistic (held-out) | controls: calibrated base | effects: the true effect's fit | "
             "outside physics: best candidate |", "|---|---|---|---|",
             f"| nrms (adequate ≤ explained_nrms) | {_spread([r['base_nrms'] for r in ctl])} | "
             f"{_spread([true_c(r)['nrms'] for r in eff if true_c(r)])} | "
             f"{_spread([lead(r)['nrms'] for r in out if lead(r)])} |",
             f"| systematic error (adequate ≤ systematic_tol) | {_spread([r['base_systematic'] for r in ctl])} | "
             f"{_spread([true_c(r)['systematic'] for r in eff if true_c(r)])} | "
             f"{_spread([lead(r)['systematic'] for r in out if lead(r)])} |",
             f"| best candidate's ΔBIC (improves ≥ bic_margin) | "
             f"{_spread([-lead(r)['delta_score'] for r in ctl if lead(r)])} | "
             f"{_spread([-true_c(r)['delta_score'] for r in eff if true_c(r)])} | "
             f"{_spread([-lead(r)['delta_score'] for r in out if lead(r)])} |",
             f"| best candidate's held-out Δχ² (improves ≥ test_margin) | "
             f"{_spread([lead(r)['delta_chi2_heldout'] for r in ctl if lead(r)])} | "
             f"{_spread([true_c(r)['delta_chi2_heldout'] for r in eff if true_c(r)])} | "
             f"{_spread([lead(r)['delta_chi2_heldout'] for r in out if lead(r)])} |",
             f"| best candidate's held-out nrms ÷ the base's (material ≤ nrms_ratio) | "
             f"{_spread([lead(r)['nrms'] / r['base_nrms'] for r in ctl if lead(r)])} | "
             f"{_spread([true_c(r)['nrms'] / r['base_nrms'] for r in eff if true_c(r)])} | "
             f"{_spread([lead(r)['nrms'] / r['base_nrms'] for r in out if lead(r)])} |",
             f"| base systematic error | {_spread([r['base_systematic'] for r in ctl])} | "
             f"{_spread([r['base_systematic'] for r in eff])} | {_spread([r['base_systematic'] for r in out])} |",
             "", f"Logs: {len(ctl)} controls, {len(eff)} effects, {len(out)} outside; min / median / max."]
    return "\n".join(lines)


def _interleaved(systems: list[str], only: list[str] | None) -> list[tuple[str, str]]:
    """(case, system) pairs taking one case of each system in turn, so a partial run covers every system."""
    per = {s: [c for c in cases(s) if only is None or c in only] for s in systems}
    out = []
    for k in range(max((len(v) for v in per.values()), default=0)):
        out += [(per[s][k], s) for s in systems if k < len(per[s])]
    return out


BEFORE_CHAIN_DEFAULT = {"estimate_chain": False}
"""The settings of a stored case that names none: it ran before the undeclared chain was estimated by default."""


def _settings(items: list[str]) -> dict:
    """``["estimate_chain=false", "max_nfev=10"]`` -> diagnose settings of their types, as ``vibro diagnose
    --setting`` reads them."""
    from pipeline.cli.args import parse_assignments
    from pipeline.cli.diagnose import TEXT_DIAGNOSE_SETTINGS, typed_settings

    return typed_settings(parse_assignments(items, "--setting", words=TEXT_DIAGNOSE_SETTINGS))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--systems", nargs="+", default=["drill", "indenter-metal", "indenter-sandstone", "pendulum", "rimd"])
    p.add_argument("--cases", nargs="+", help="subset: effect names, control, outside:<name>")
    p.add_argument("--noise", nargs="+", default=list(NOISE))
    p.add_argument("--seeds", nargs="+", type=int, default=list(SEEDS))
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--n-runs", type=int, default=None,
                   help="shorter logs: the first N runs spread over each rig's grid (default: the whole grid)")
    p.add_argument("--quick", action="store_true", help="seed 0 and the first noise model only")
    p.add_argument("--fresh", action="store_true", help="diagnose every case again (the logs are kept)")
    p.add_argument("--replay", action="store_true", help="recompute verdicts from stored statistics only")
    p.add_argument("--no-doc", action="store_true",
                   help="do not rewrite docs/identification.md nor bench/results/identification.json (a subset's "
                        "rows are kept in bench/results/identification/rows.json)")
    p.add_argument("--setting", action="append", default=[], metavar="KEY=VALUE",
                   help="a diagnose setting for every case (repeatable), e.g. estimate_chain=false; a stored case is "
                        "reused only when it ran with the same settings")
    a = p.parse_args(argv)
    from pipeline.core.errors import UserError

    try:
        settings = _settings(a.setting)
    except UserError as e:
        p.error(str(e))
    if a.quick:
        a.seeds, a.noise = a.seeds[:1], a.noise[:1]
    WORK.mkdir(parents=True, exist_ok=True)
    done_file = WORK / "rows.json"
    stored = json.loads(done_file.read_text()) if done_file.exists() else []
    other = [r for r in stored if r.get("settings", BEFORE_CHAIN_DEFAULT) != settings]     # kept, not reused
    done = {r["name"]: r for r in stored if r not in other} if not a.fresh else {}
    todo = [(s, c, n, seed) for seed in a.seeds for c, s in _interleaved(a.systems, a.cases) for n in a.noise]
    rows = []
    for k, (s, c, n, seed) in enumerate(todo, 1):
        name = log_name(spec_of(s, c, n, seed, a.n_runs), c)
        if name in done and not a.replay:
            rows.append(done[name])
            continue
        if a.replay:
            if name in done:
                rows.append(done[name])
            continue
        r = {**run_case(s, c, n, seed, a.threads, settings, n_runs=a.n_runs), "settings": settings}
        done[name] = r
        rows.append(r)
        done_file.write_text(json.dumps([*other, *done.values()], indent=1, default=float))
        print(f"[{k}/{len(todo)}] {name}: {r['verdict']} {'✓' if r['correct'] else '✗'} "
              f"(selected {r['selected']}, nrms {_fmt(r['base_nrms'])} -> {_fmt(r['final_nrms'])}, "
              f"systematic {_fmt(r['base_systematic'])} -> {_fmt(r['final_systematic'])}, {r['wall_time_s']:.0f} s)",
              flush=True)
    if a.replay and not rows:      # no stored rows here: say so rather than overwrite the tables with empty ones
        print(f"bench.identification --replay: no stored rows in {done_file} for this selection; nothing written",
              file=sys.stderr)
        return 2
    if a.replay:
        from pipeline.diagnosis.run import DiagnoseConfig
        c = DiagnoseConfig()
        rows = replay(rows, c.rule())
    text = table(rows)
    print(text)
    summary = {"rows": len(rows), "right": sum(r["correct"] for r in rows),
               "by_expected": {e: [sum(r["correct"] for r in rows if r["expected"] == e),
                                   sum(1 for r in rows if r["expected"] == e)]
                               for e in ("nothing missing", "selected", "unexplained")}}
    if a.no_doc:        # the committed summary stays the whole matrix's; this selection's rows are in rows.json
        print(json.dumps(summary), file=sys.stderr)
        return 0
    (RESULTS / "identification.json").write_text(json.dumps({"summary": summary, "rows": rows}, indent=1, default=float))
    if DOC.exists():
        from bench import write_block

        write_block(DOC, START, END, text)
        if RULE_DOC.exists():
            write_block(RULE_DOC, RULE_START, RULE_END, rule_table(rows))
        from bench import write_between_markers

        summary_rows = text.split("\n\n")[0]
        write_between_markers(ROOT, ["README.md"], "<!-- identification-summary:start -->",
                              "<!-- identification-summary:end -->", summary_rows)
    print(json.dumps(summary), file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
