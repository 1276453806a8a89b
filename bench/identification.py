"""Identification matrix of ``vibro diagnose`` on ``vibro synth`` data: for a system, one dataset per §6 effect,
a control (no effect) and one case of physics outside the library; each is diagnosed at the default settings.

``python -m bench.identification --system drill [--threads 2] [--cases tip_blunting control]``
writes bench/results/identification_<system>.json (or --out) and prints the markdown table of README.md
(effect -> identified, fitted value vs truth, held-out error before/after, noise floor, wall time).
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
SEEDS = {"control": 2, "outside": 3}       # effect datasets use seed 1 (as the indenter's slow tests)


def cases(system: str) -> list[str]:
    """Every §6 effect of the system's model, then 'control' and 'outside'."""
    import sim

    return [*sim.get_model(system).effects, "control", "outside"]


def run_case(system: str, case: str, threads: int | None, settings: dict | None = None) -> dict:
    """Synthesize (rig defaults) and diagnose one case; returns the row of the table."""
    from pipeline.diagnosis.driver import diagnose
    from pipeline.diagnosis.run import DiagnoseConfig
    from pipeline.datasets.measured import load_dataset, write_dataset
    from pipeline.datasets.synth import SynthConfig, resolve_effects, synthesize

    effects = resolve_effects(system, {case: None}) if case not in ("control", "outside") else {}
    cfg = SynthConfig(system=system, effects=effects, outside="mount_resonance" if case == "outside" else None,
                      seed=SEEDS.get(case, 1), n_threads=threads)
    ds, info = synthesize(cfg)
    with tempfile.TemporaryDirectory() as tmp:
        write_dataset(ds, Path(tmp) / "data")
        data = load_dataset(Path(tmp) / "data")
        t0, c0 = time.time(), time.process_time()
        rep = diagnose(data, Path(tmp) / "diag", DiagnoseConfig(n_threads=threads, **(settings or {})),
                       log=lambda s: None)
        wall, cpu = time.time() - t0, time.process_time() - c0
    r = rep["systems"][system]
    sel = r["selected"]
    fitted = {}
    if sel:
        fitted = next(c for c in r["candidates"] if c["effect"] == sel)["params"]
    expected = case if case not in ("control", "outside") else None
    return {"case": case, "expected": expected, "selected": sel, "explained": r["explained"],
            "correct": sel == expected and (r["explained"] if case != "outside" else not r["explained"]),
            "truth": {k: info["truth"][k] for k in effects}, "fitted": fitted,
            "calibrated": r["calibrated"], "truth_base": {k: v for k, v in info["truth"].items() if k not in effects},
            "base_error": r["base_error"], "final_error": r["final_error"], "noise_floor": r["noise_floor"],
            "base_nrms": r["base_nrms"], "final_nrms": r["final_nrms"], "n_simulations": r["n_simulations"],
            "wall_time_s": round(wall, 1), "cpu_time_s": round(cpu, 1)}


def table(rows: list[dict]) -> str:
    """Markdown table of the rows."""
    out = ["| data made with | identified | fitted (truth) | held-out error before → after (noise floor) | "
           "nrms before → after | time (CPU) |", "|---|---|---|---|---|---|"]
    for r in rows:
        made = {"control": "control (no effect)", "outside": "outside: mount resonance"}.get(r["case"], r["case"])
        ident = r["selected"] or ("nothing — explained" if r["explained"] else "nothing — **unexplained**")
        ok = "✓" if r["correct"] else "✗"
        fit = ", ".join(f"{k} = {r['fitted'].get(k, float('nan')):.3g} ({v:.3g})" for k, v in r["truth"].items()) or "—"
        out.append(f"| {made} | {ident} {ok} | {fit} | {r['base_error']:.3g} → {r['final_error']:.3g} "
                   f"({r['noise_floor']:.3g}) | {r['base_nrms']:.3g} → {r['final_nrms']:.3g} | {r['wall_time_s']:.0f} s "
                   f"({r.get('cpu_time_s', float('nan')):.0f} s) |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--system", default="drill")
    p.add_argument("--cases", nargs="+", help="subset of the cases (effects, control, outside)")
    p.add_argument("--threads", type=int)
    p.add_argument("--out", help="results JSON (default bench/results/identification_<system>.json); rows of other "
                                 "cases already there are kept")
    a = p.parse_args(argv)
    out = Path(a.out) if a.out else RESULTS / f"identification_{a.system}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    old = json.loads(out.read_text()) if out.exists() else []
    rows: list[dict] = []
    for case in a.cases or cases(a.system):
        rows.append(run_case(a.system, case, a.threads))
        print(table(rows[-1:]).splitlines()[-1], flush=True)
        keep = [r for r in old if r["case"] not in {x["case"] for x in rows}]
        out.write_text(json.dumps(keep + rows, indent=2, default=float))     # after every case (long runs)
    print(table(keep + rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
