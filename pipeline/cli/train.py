"""``vibro train``: learn the surrogate (regime classifier + regressors with 90 % intervals) from a sweep."""
from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.cli import args as A
from pipeline.cli.args import add_quiet, add_rig, add_workers, load_rig
from pipeline.core.errors import UserError
from pipeline.core.rigfile import rig_name

EPILOG = """what it writes (in --out):
  bundle.skops, bundle.json    the chosen models, input schema (names, trained ranges), model/preset and the
                               dataset fingerprint; load with surrogate.load_bundle(DIR or MLFLOW_RUN_ID)
  report.json                  CV scores of every candidate, held-out R2 / MAE / RMSE / interval coverage per
                               target, accuracy + confusion matrix, learning curve, simulations needed per goal
  parity.png, confusion.png, learning_curve.png  (adaptive.png, adaptive_design.parquet with --adaptive)

examples:
  vibro train data/sweep --out models/surrogate --params params.yaml --metrics metrics/train.json
  vibro train data/sweep --regressors gbt,mlp --no-mlflow          # quick: no Gaussian process
  vibro train data/sweep --workers 1                                # one process (same result, slower)
  vibro train data/sweep --adaptive --budget 768 --batch 64         # + adaptive sampling vs space-filling
  vibro train data/my-rig --adaptive --rig my-rig.yaml               # adaptive sampling simulates your rig
  vibro train points.parquet --model drill --inputs frequency_hz,amplitude_n

rows checked before training (one bad row refuses the dataset, exit 2 naming the column and the row; no row
  is dropped, so the trained ranges come only from rows that passed):
  inputs are parameters or controls, never a MODELS.md section-5 label; input values finite, valid for their
  parameter (e.g. frequency_hz > 0) and inside the sweep's declared range (metadata 'vary'); labels never
  negative or infinite (specific_energy_j_m is +inf where rop_m_s is 0, as the simulator writes it)

params.yaml section 'train' (all optional; flags override): test_fraction 0.2, cv_folds 5, seed 0,
  targets [rop_m_s, peak_force_n, impacts_per_cycle, specific_energy_j_m], regressors [gp, gbt, mlp] (also krr),
  classifiers [gbt, mlp, trees], transforms {target: auto|log|identity}, domains {target: progressing|settled|all},
  max_gp_points 600, workers null (all cores), threads 1 (BLAS per process), interval 0.9, learning_curve [0.1, 0.2, 0.35, 0.5, 1.0],
  goals {rop_m_s_r2 0.95, peak_force_n_r2 0.97, accuracy 0.97, coverage_low 0.85, coverage_high 0.95},
  adaptive {enabled false, initial 128, batch 64, budget 768, pool 4096, boundary_weight 0.5, ensemble 5}"""


def add_parser(sub) -> None:
    p = sub.add_parser(
        "train", help="learn a surrogate of the response surface from a sweep dataset",
        description="Learn the simulator's response from a sweep dataset (directory of part-*.parquet + "
                    "metadata.json, or one .parquet file): a regime classifier (progressing, no_progress, "
                    "runaway, not_settled, failed) and, per target, a regressor inside its regime with a "
                    "split-conformal 90 % prediction interval.  Candidates (Gaussian process, gradient-boosted "
                    "trees, neural network, kernel ridge) are selected by K-fold cross-validation on the training "
                    "split; a held-out split (never trained on) gives the report.  Logged to MLflow (params, "
                    "metrics, figures, the model with its signature).",
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG)
    p.add_argument("dataset", help="sweep dataset directory or .parquet file")
    p.add_argument("--out", default="models/surrogate", help="output directory (default: models/surrogate)")
    p.add_argument("--params", metavar="FILE", help="YAML file whose 'train' section sets the options below")
    p.add_argument("--metrics", metavar="FILE.json", help="also write the headline held-out metrics here")
    p.add_argument("--model", help="model name, when the dataset has no metadata.json (e.g. drill)")
    p.add_argument("--inputs", help="comma-separated input columns (default: metadata 'vary', else varying controls)")
    p.add_argument("--regressors", help="comma-separated regressor candidates: gp, gbt, mlp, krr")
    p.add_argument("--classifiers", help="comma-separated classifier candidates: gbt, mlp, trees")
    p.add_argument("--test-fraction", type=A.arg_type(lo=0.0, hi=0.9, lo_open=True), help="held-out fraction (default 0.2)")
    p.add_argument("--cv-folds", type=A.count(2, 100), help="cross-validation folds for model selection (default 5)")
    p.add_argument("--seed", type=A.seed, help="seed of the split, the models and the adaptive design (default 0)")
    p.add_argument("--max-gp-points", type=A.count(1, 100_000), help="Gaussian-process training subsample (default 600)")
    add_workers(p, help="processes fitting the cross-validation folds and learning-curve sizes at once "
                        "(default: all cores; the result does not depend on it)")
    p.add_argument("--adaptive", action="store_true",
                   help="also run adaptive sampling (calls the simulator) and compare it with the space-filling "
                        "design at equal numbers of simulations")
    p.add_argument("--initial", type=A.count(2, A.MAX_POINTS), help="adaptive: initial space-filling points (default 128)")
    p.add_argument("--batch", type=A.count(1, A.MAX_POINTS), help="adaptive: points added per round (default 64)")
    p.add_argument("--budget", type=A.count(1, A.MAX_POINTS), help="adaptive: total simulations (default 768)")
    add_rig(p, "name the surrogate for the rig the sweep ran on (checked against the dataset) and, with --adaptive, "
               "simulate")
    A.add_chain(p)
    p.add_argument("--no-mlflow", action="store_true", help="do not log to MLflow")
    add_quiet(p)
    A.add_overwrite(p, "surrogate bundle")
    p.set_defaults(func=run)


def _config(args):
    from surrogate.config import TrainConfig

    from pipeline.core.params import read_section

    d = read_section(args.params, "train")
    for key in ("test_fraction", "cv_folds", "seed", "max_gp_points", "workers"):
        if getattr(args, key) is not None:
            d[key] = getattr(args, key)
    for key in ("regressors", "classifiers"):
        if getattr(args, key):
            d[key] = [s.strip() for s in getattr(args, key).split(",") if s.strip()]
    ad = dict(d.get("adaptive") or {})
    if args.adaptive:
        ad["enabled"] = True
    for key in ("initial", "batch", "budget"):
        if getattr(args, key) is not None:
            ad[key] = getattr(args, key)
    d["adaptive"] = ad
    return TrainConfig.from_dict(d)


def run(args) -> int:
    import json

    from pipeline import tracking
    from vibrobase.files import atomic_write_text
    from vibrobase.jsonable import dump_json
    from pipeline.core.outdir import check_out, check_out_file, prepare_out, record_out_file
    from pipeline.training.workflow import load_training_data, run_training
    from surrogate import mlflow_model

    cfg = _config(args)
    check_adaptive(cfg.adaptive)
    inputs_arg = [s.strip() for s in args.inputs.split(",")] if args.inputs else None
    data = load_training_data(args.dataset, args.model, inputs_arg)
    rig = load_rig(args.rig, data.model)
    if rig is not None:
        check_rig_matches(rig, data.meta, args.rig, args.dataset)
    out = Path(args.out)
    check_out(out, inputs=[args.dataset, args.params, args.metrics], overwrite=args.overwrite, marker="train")
    if args.metrics:
        check_out_file(args.metrics, flag="--metrics", kind="json", inputs=[args.dataset, args.params, args.rig, out],
                       overwrite=args.overwrite)
    check_some_rows_usable(data.df, args.dataset)
    chain = A.chain_of(args)
    provenance = {"chain": chain, "rig": str(args.rig) if args.rig else None, "rig_name": rig_name(args.rig),
                  "dataset": str(args.dataset)}      # what `vibro optimise` infill retrains on
    params = {"dataset": str(args.dataset), "model": data.model, "preset": data.preset, "fingerprint": data.fingerprint,
              "inputs": ",".join(data.inputs), "n_points": len(data.df), "rig": args.rig or "",
              **{f"train.{k}": v for k, v in cfg.to_dict().items()}}
    tags = {"vibro.rig_file": str(args.rig)} if args.rig else None
    with prepare_out(out, inputs=[args.dataset, args.params, args.metrics], overwrite=args.overwrite,
                     marker="train") as tmp, tracking.chain(chain, rig_name(args.rig)), \
            tracking.run("train", params, tags=tags, enabled=not args.no_mlflow) as mlflow:
        res = run_training(data, cfg, tmp, rig=rig, progress=not args.quiet, provenance=provenance)
        bundle = res.bundle
        if args.metrics:
            atomic_write_text(args.metrics, dump_json(res.headline) + "\n")
            record_out_file(args.metrics, command="train", kind="json")
        if mlflow is not None:
            mlflow.log_metrics(res.flat_metrics)
            for path in res.figures.values():
                mlflow.log_artifact(path, artifact_path="figures")
            mlflow.log_text(json.dumps(json.loads(dump_json(bundle.report)), indent=2), "report.json")
            mlflow_model.log(mlflow, bundle, tmp, data.df, name=model_name(data.model, chain))
            run_id = mlflow.active_run().info.run_id
    _print_summary(bundle, out, res.adaptive)
    if mlflow is not None:
        print(f"MLflow run {run_id}  (pipeline.tracking.load_bundle('{run_id}'))")
    return 0


def check_rig_matches(rig, meta: dict, path: str, dataset: str) -> None:
    """UserError when rig file ``path`` is not the rig sweep ``dataset`` was simulated on (its preset, or a
    parameter the rig sets that the sweep held at another value): the surrogate would be named for the wrong rig."""
    import math

    fixed = meta.get("fixed") or {}
    if "preset" in meta and meta.get("preset") != rig.preset:
        raise UserError(f"--rig {path}: preset {rig.preset!r}, but dataset '{dataset}' was simulated with preset "
                        f"{meta.get('preset')!r}")
    for name, value in rig.overrides().items():
        got = fixed.get(name)
        if got is None or not math.isclose(float(got), float(value), rel_tol=1e-9, abs_tol=0.0):
            raise UserError(f"--rig {path}: {name} = {value:g}, but dataset '{dataset}' was simulated with "
                            f"{name} = {'its preset value' if got is None else format(float(got), 'g')}; "
                            f"give the rig file the sweep used")


def check_adaptive(ad) -> None:
    """UserError when the adaptive design cannot fit its budget (initial points and one batch)."""
    if ad.enabled and ad.initial + ad.batch > ad.budget:
        raise UserError(f"--adaptive: --initial {ad.initial} + --batch {ad.batch} exceeds --budget {ad.budget} "
                        f"simulations; raise --budget or lower --initial / --batch")


def check_some_rows_usable(df, dataset: str) -> None:
    """UserError when every row of the training set failed (nothing to learn from)."""
    if "status" in df and len(df) and (df["status"].astype(str) == "failed").all():
        raise UserError(f"{dataset}: every one of its {len(df)} rows has status 'failed'; nothing to train on")


def model_name(model: str, chain: str) -> str:
    """The logged MLflow model's name: ``drill-surrogate-lab``, ``drill-surrogate-corrected``."""
    return f"{model}-surrogate-{chain}"


def describe(report: dict) -> str:
    """What the surrogate stands for: ``rig 'my-rig' (model 'drill', preset 'lab', my-rig.yaml)`` on a rig file,
    else ``'drill' (preset 'lab')``."""
    if report.get("rig"):
        name = report.get("rig_name") or rig_name(report["rig"])
        return f"rig '{name}' (model '{report['model']}', preset {report['preset']!r}, {report['rig']})"
    return f"'{report['model']}' (preset {report['preset']!r})"


def _print_summary(bundle, out: Path, ad: dict | None) -> None:
    r = bundle.report
    c = r["held_out"]["classification"]
    print(f"surrogate of {describe(r)} trained on {r['n_train']} simulations, held out {r['n_test']}; "
          f"written to {out}")
    print(f"  regime classifier {bundle.classifier_name}: held-out accuracy {c['accuracy']:.4f}")
    constant = r.get("constant_targets") or {}
    for t, m in r["held_out"]["targets"].items():
        tm = bundle.regressors[t]
        if t in constant:
            print(f"  {t:<20} constant in the data: {constant[t]:.6g} at every point (nothing to learn; predicted exactly)")
            continue
        r2 = "n/a" if m.get("r2") is None else f"{m['r2']:.4f}"
        print(f"  {t:<20} {tm.name:<4} ({tm.transform.kind}, {tm.domain}, n={m['n']}): R2 {r2}, "
              f"RMSE {m.get('rmse', float('nan')):.4g}, 90% interval coverage {m.get('coverage', float('nan')):.3f}")
    need = r.get("simulations_needed") or {}
    if need:
        print("  training simulations needed: " + ", ".join(f"{k} {v if v is not None else 'not reached'}"
                                                          for k, v in need.items()))
    notes = r.get("goals_notes") or {}
    print("  goals met: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in r["goals_met"].items() if v is not None))
    for k, note in notes.items():
        print(f"  {k}: not applicable, {note}")
    if ad:
        for k, s in ad["savings"].items():
            print(f"  adaptive ({k}): {s['adaptive_sims']} simulations reach {s['level']:.4g}; space-filling needs "
                  f"{s['space_filling_sims'] if s['space_filling_sims'] is not None else 'more than it has'}")
