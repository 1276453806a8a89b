"""Does a training design with points on the box's boundary buy accuracy where the optimiser looks?

For each model (the drill ``lab`` preset; the corrected rig of ``--rig``, a ``vibro diagnose`` rig.yaml) and each
design size, the surrogate is trained on a ``sobol`` and on a ``sobol-boundary`` sweep of the lab search space
(``pipeline.datasets.spec``: the sweep's own design code) and scored on the SAME hidden points, simulated once per
model and never trained on: ``--test-interior`` scrambled Sobol' points (another seed) and ``--test-boundary`` points
on the box's corners, edges and faces (``designs.boundary_points``, another seed), scored apart.  Every training
point is trained on (``surrogate.train.fit``: CV model selection and conformal 90 % intervals on the design, no
split held out of it), so both designs see the same number of simulations.
Scores: ROP R² on progressing points, regime accuracy, 90 % interval coverage (ROP, power, deceleration), R² of
power_w and peak_decel_g -- the labels the pipeline's limits constrain.
Writes bench/results/design.json and the table between the design markers of docs/train.md.

Run: ``python -m bench.bench_design [--sizes 256 512] [--rig results/diagnose/drill-rig/rig.yaml]
[--regressors gp gbt mlp] [--fractions 0.25]``.
"""
from __future__ import annotations

import argparse
import itertools
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
DOC = ROOT / "docs" / "train.md"
DEFAULT_RIG = ROOT / "results" / "diagnose" / "drill-rig" / "rig.yaml"
MARKERS = ("<!-- design:start -->", "<!-- design:end -->")
TARGETS = ("rop_m_s", "power_w", "peak_decel_g")
GOALS = {"rop_r2": 0.99, "accuracy": 0.98, "coverage": (0.88, 0.92), "power_r2": 0.99, "decel_r2": 0.99}
TEST_SEED = 7919          # the hidden points' seed: no training design uses it


def lab_sweep() -> dict:
    """params.yaml's sweep section (the ``make run`` sweep): model, preset, lab ranges."""
    from pipeline.core.params import read_section

    return dict(read_section(str(ROOT / "params.yaml"), "sweep", section_required=True))


def simulator(sweep: dict, rig):
    """table of varied parameters -> labelled frame on the lab preset, or on ``rig`` (its preset, parameters and
    effects) when given: ``pipeline.training.workflow.simulator``, the adaptive study's."""
    from pipeline.training.workflow import simulator as make

    return make(sweep["model"], sweep.get("preset"), {"fixed": sweep.get("fixed") or {}}, rig)


def design_frame(sweep: dict, design: str, n: int, seed: int, fraction: float | None) -> pd.DataFrame:
    """The varied parameters of a ``design`` sweep of ``n`` points (physical units)."""
    from pipeline.datasets.spec import design_points, make_spec

    raw = {k: v for k, v in sweep.items() if k not in ("scheduler", "workers", "boundary_fraction", "design")}
    spec = make_spec({**raw, "design": design, "n_points": n, "seed": seed,
                      **({"boundary_fraction": fraction} if design == "sobol-boundary" else {})})
    return design_points(spec).drop(columns="point_id")


def hidden_points(sweep: dict, n_interior: int, n_boundary: int) -> dict[str, pd.DataFrame]:
    """The hidden test inputs: interior Sobol' and boundary points, both seeded by ``TEST_SEED``."""
    from pipeline.datasets import designs
    from pipeline.datasets.spec import make_spec

    raw = {k: v for k, v in sweep.items() if k not in ("scheduler", "workers", "boundary_fraction", "design")}
    spec = make_spec({**raw, "design": "sobol", "n_points": 1, "seed": 0})
    d = len(spec.vary)
    units = {"interior": designs.sobol(d, n_interior, TEST_SEED),
             "boundary": designs.boundary_points(d, n_boundary, TEST_SEED)}
    return {k: pd.DataFrame({name: np.clip(r.to_physical(u[:, j]), r.low, r.high)
                             for j, (name, r) in enumerate(spec.vary.items())}) for k, u in units.items()}


def train(df: pd.DataFrame, sweep: dict, cfg):
    """A bundle fitted on every row of ``df`` (CV selection, conformal intervals), no split held out."""
    from threadpoolctl import threadpool_limits

    from surrogate.train import fit, with_power

    names = list(sweep["vary"])
    ranges = {n: (float(sweep["vary"][n]["low"]), float(sweep["vary"][n]["high"])) for n in names}
    with threadpool_limits(cfg.threads):
        bundle, info = fit(with_power(df.reset_index(drop=True)), names, ranges, {n: "linear" for n in names},
                           sweep["model"], sweep.get("preset"), cfg, fingerprint="bench-design")
    return bundle, info


def score(bundle, test: pd.DataFrame) -> dict:
    """The issue's held-out numbers of ``bundle`` on ``test`` (``surrogate.train.evaluate``)."""
    from surrogate.train import evaluate

    ev = evaluate(bundle, test)
    t = ev["targets"]
    cov = {k: t.get(k, {}).get("coverage") for k in TARGETS}
    return {"n": int(len(test)), "accuracy": ev["classification"]["accuracy"],
            "rop_r2": t.get("rop_m_s", {}).get("r2"), "power_r2": t.get("power_w", {}).get("r2"),
            "decel_r2": t.get("peak_decel_g", {}).get("r2"), "coverage": cov,
            "n_progressing": t.get("rop_m_s", {}).get("n")}


def met(s: dict) -> dict:
    """Which of the issue's targets a score meets (every coverage inside 0.88-0.92)."""
    lo, hi = GOALS["coverage"]
    covs = [c for c in s["coverage"].values() if c is not None]
    return {"rop_r2": (s["rop_r2"] or -1) >= GOALS["rop_r2"], "accuracy": (s["accuracy"] or 0) >= GOALS["accuracy"],
            "coverage": bool(covs) and all(lo <= c <= hi for c in covs),
            "power_r2": (s["power_r2"] or -1) >= GOALS["power_r2"], "decel_r2": (s["decel_r2"] or -1) >= GOALS["decel_r2"]}


def _f(x, fmt: str = ".4f") -> str:
    return "—" if x is None else format(x, fmt)


def mean_scores(rows: list[dict]) -> list[dict]:
    """Rows of the same model, design and size averaged over their seeds (each score, each hidden set)."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["model"], r["design"], r["n"]), []).append(r)
    out = []
    for (model, design, n), rs in groups.items():
        def avg(get):
            v = [get(r) for r in rs if get(r) is not None]
            return float(np.mean(v)) if v else None
        scores = {w: {"accuracy": avg(lambda r: r["scores"][w]["accuracy"]),
                      **{k: avg(lambda r, k=k: r["scores"][w][k]) for k in ("rop_r2", "power_r2", "decel_r2")},
                      "coverage": {t: avg(lambda r, t=t: r["scores"][w]["coverage"][t]) for t in TARGETS}}
                  for w in rs[0]["scores"]}
        out.append({"model": model, "design": design, "n": n, "seeds": sorted(r["seed"] for r in rs),
                    "train_s": avg(lambda r: r["train_s"]), "scores": scores})
    return out


def table(res: dict) -> str:
    """The markdown table of docs/train.md: one row per model, design, size and hidden set (means over seeds)."""
    load = res["machine"]["load_avg_at_start"]
    lines = [f"Hidden points per model: {res['test']['interior']} interior (Sobol', seed {TEST_SEED}) and "
             f"{res['test']['boundary']} on the boundary (corners, edges, faces); regressors {', '.join(res['regressors'])}, "
             f"classifiers {', '.join(res['classifiers'])}, {res['cv_folds']}-fold CV, every design point trained on; "
             f"scores are means over the design seeds listed.  Load average {load[0]:.1f} at the start, "
             f"{res['machine']['load_avg_at_end'][0]:.1f} at the end ({res['machine']['cpus']} cores, shared); "
             f"{res['seconds']:.0f} s in all.",
             "",
             "| model | design | n | seeds | hidden set | ROP R² (progressing) | regime accuracy "
             "| coverage ROP / power / decel | power R² | decel R² | targets met | train s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in mean_scores(res["rows"]):
        for where in ("interior", "boundary"):
            s = r["scores"][where]
            cov = " / ".join(_f(s["coverage"][k], ".3f") for k in TARGETS)
            ok = met(s)
            lines.append(f"| {r['model']} | {r['design']} | {r['n']} | {','.join(map(str, r['seeds']))} | {where} "
                         f"| {_f(s['rop_r2'])} | {_f(s['accuracy'])} | {cov} | {_f(s['power_r2'])} | {_f(s['decel_r2'])} "
                         f"| {sum(ok.values())}/5 | {r['train_s']:.0f} |")
    lines.append("")
    lines.append("Targets: ROP R² ≥ 0.99, accuracy ≥ 0.98, every 90 % coverage in 0.88–0.92, power and deceleration "
                 "R² ≥ 0.99. Models chosen per row and per seed: `bench/results/design.json`.")
    return "\n".join(lines)


def _models(rig_path: str | None) -> dict:
    """"lab" -> None and, with a rig file, "corrected rig" -> its ``sim.Rig``.  ``rig_path`` None: the pipeline's
    corrected rig when ``make run`` has written it (else the lab model only, said on stderr)."""
    import sys

    from pipeline.core.rigfile import read_rig

    out = {"lab": None}
    if rig_path is None:
        if not DEFAULT_RIG.exists():
            print(f"bench_design: no {DEFAULT_RIG.relative_to(ROOT)} (make run, or `vibro diagnose measured/drill-rig "
                  f"--out results/diagnose/drill-rig`): the lab model only", file=sys.stderr)
            return out
        rig_path = str(DEFAULT_RIG)
    if rig_path:
        out["corrected rig"] = read_rig(rig_path)      # UserError naming a missing or bad file
    return out


def _args(argv):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512], help="design sizes (default 256 512)")
    ap.add_argument("--models", nargs="+", default=["lab", "rig"], choices=["lab", "rig"],
                    help="lab: the drill lab preset; rig: the corrected rig (default both)")
    ap.add_argument("--designs", nargs="+", default=["sobol", "sobol-boundary"], choices=["sobol", "sobol-boundary"],
                    help="designs to train on (default both)")
    ap.add_argument("--fractions", type=float, nargs="+", default=[0.25],
                    help="boundary fractions of sobol-boundary to measure (default 0.25)")
    ap.add_argument("--rig", default=None, help="corrected rig file (default: results/diagnose/drill-rig/rig.yaml "
                                                "where it exists; '' for the lab model only)")
    ap.add_argument("--regressors", nargs="+", default=None, help="default: params.yaml's train.regressors")
    ap.add_argument("--classifiers", nargs="+", default=None, help="default: params.yaml's train.classifiers")
    ap.add_argument("--test-interior", type=int, default=1024, help="hidden interior points per model")
    ap.add_argument("--test-boundary", type=int, default=512, help="hidden boundary points per model")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0], help="seeds of the training designs (default 0)")
    ap.add_argument("--out", default=str(RESULTS / "design.json"))
    ap.add_argument("--no-doc", action="store_true", help="do not write the table into docs/train.md")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> dict:
    a = _args(argv)
    from bench import publish
    from pipeline.core.params import read_section
    from surrogate.config import TrainConfig

    t0, load0 = time.time(), os.getloadavg()
    sweep = lab_sweep()
    tr = dict(read_section(str(ROOT / "params.yaml"), "train", section_required=True))
    tr.update({k: v for k, v in (("regressors", a.regressors), ("classifiers", a.classifiers)) if v})
    tr.update(targets=list(TARGETS), learning_curve=[])
    cfg = TrainConfig.from_dict(tr)
    rows = []
    chosen = {"lab": "lab", "rig": "corrected rig"}
    for model, rig in _models(a.rig if "rig" in a.models else "").items():
        if model not in {chosen[m] for m in a.models}:
            continue
        run = simulator(sweep, rig)
        hidden = {k: run(v) for k, v in hidden_points(sweep, a.test_interior, a.test_boundary).items()}
        plans = ([("sobol", None)] if "sobol" in a.designs else []) + \
            ([("sobol-boundary", f) for f in a.fractions] if "sobol-boundary" in a.designs else [])
        for n, seed, (design, frac) in itertools.product(a.sizes, a.seeds, plans):
            df = run(design_frame(sweep, design, n, seed, frac))
            t1 = time.time()
            bundle, info = train(df, sweep, cfg)
            row = {"model": model, "design": design if frac is None else f"{design} {frac:g}", "n": n, "seed": seed,
                   "train_s": time.time() - t1, "scores": {k: score(bundle, v) for k, v in hidden.items()},
                   "chosen": {"classifier": info["classifier"]["model"],
                              **{t: i.get("model") for t, i in info["targets"].items()}}}
            rows.append(row)
            print(f"{model} {row['design']} n={n} seed {seed}: " + "; ".join(
                f"{w} ROP R² {_f(s['rop_r2'])} acc {_f(s['accuracy'])} power R² {_f(s['power_r2'])} "
                f"decel R² {_f(s['decel_r2'])}" for w, s in row["scores"].items())
                + f" ({row['train_s']:.0f} s)", flush=True)
    res = {"rows": rows, "sizes": a.sizes, "fractions": a.fractions, "rig": a.rig,
           "test": {"interior": a.test_interior, "boundary": a.test_boundary, "seed": TEST_SEED},
           "regressors": cfg.regressors, "classifiers": cfg.classifiers, "cv_folds": cfg.cv_folds,
           "goals": GOALS, "seconds": time.time() - t0,
           "machine": {"cpus": os.cpu_count(), "load_avg_at_start": list(load0), "load_avg_at_end": list(os.getloadavg())}}
    publish(res, Path(a.out), table(res), None if a.no_doc else DOC, MARKERS)
    return res


if __name__ == "__main__":
    main()
