"""``vibro train``: learn the surrogate (regime classifier + regressors with 90 % intervals) from a sweep."""
from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.cli.args import add_quiet, add_rig, add_workers, load_rig
from pipeline.core.errors import UserError

EPILOG = """what it writes (in --out):
  bundle.joblib, bundle.json   the chosen models, input schema (names, trained ranges), model/preset and the
                               dataset fingerprint; load with surrogate.load_bundle(DIR or MLFLOW_RUN_ID)
  report.json                  CV scores of every candidate, held-out R2 / MAE / RMSE / interval coverage per
                               target, accuracy + confusion matrix, learning curve, simulations needed per goal
  parity.png, confusion.png, learning_curve.png  (adaptive.png, adaptive_design.parquet with --adaptive)

examples:
  vibro train data/sweep --out models/surrogate --params params.yaml --metrics metrics/train.json
  vibro train data/sweep --regressors gbt,mlp --no-mlflow          # quick: no Gaussian process
  vibro train data/sweep --adaptive --budget 768 --batch 64         # + adaptive sampling vs space-filling
  vibro train data/my-rig --adaptive --rig my-rig.yaml               # adaptive sampling simulates your rig
  vibro train points.parquet --model drill --inputs frequency_hz,amplitude_n

params.yaml section 'train' (all optional; flags override): test_fraction 0.2, cv_folds 5, seed 0,
  targets [rop_m_s, peak_force_n, impacts_per_cycle, specific_energy_j_m], regressors [gp, gbt, mlp] (also krr),
  classifiers [gbt, mlp, trees], transforms {target: auto|log|identity}, domains {target: progressing|settled|all},
  max_gp_points 600, threads 1, interval 0.9, learning_curve [0.1, 0.2, 0.35, 0.5, 0.75, 1.0],
  goals {rop_m_s_r2 0.95, peak_force_n_r2 0.97, accuracy 0.97, coverage_low 0.85, coverage_high 0.95},
  adaptive {enabled false, initial 128, batch 64, budget 768, pool 4096, boundary_weight 0.5, ensemble 5}"""


def add_parser(sub) -> None:
    p = sub.add_parser(
        "train", help="learn a surrogate of the response surface from a sweep dataset",
        description="Learn the simulator's response from a sweep dataset (directory of part-*.parquet + "
                    "metadata.json, or one .parquet file): a regime classifier (progressing, no_progress, "
                    "runaway, not_settled, failed) and, per target, a regressor inside its regime with a "
                    "split-conformal 90 %% prediction interval.  Candidates (Gaussian process, gradient-boosted "
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
    p.add_argument("--test-fraction", type=float, help="held-out fraction (default 0.2)")
    p.add_argument("--cv-folds", type=int, help="cross-validation folds for model selection (default 5)")
    p.add_argument("--seed", type=int, help="seed of the split, the models and the adaptive design (default 0)")
    p.add_argument("--max-gp-points", type=int, help="Gaussian-process training subsample (default 600)")
    add_workers(p, dest="threads", help="BLAS/OpenMP threads while fitting (default 1)")
    p.add_argument("--adaptive", action="store_true",
                   help="also run adaptive sampling (calls the simulator) and compare it with the space-filling "
                        "design at equal numbers of simulations")
    p.add_argument("--initial", type=int, help="adaptive: initial space-filling points (default 128)")
    p.add_argument("--batch", type=int, help="adaptive: points added per round (default 64)")
    p.add_argument("--budget", type=int, help="adaptive: total simulations (default 768)")
    add_rig(p, "with --adaptive, simulate")
    p.add_argument("--no-mlflow", action="store_true", help="do not log to MLflow")
    add_quiet(p)
    p.set_defaults(func=run)


def _config(args):
    from surrogate.config import TrainConfig

    from pipeline.core.params import read_section

    d = read_section(args.params, "train")
    for key in ("test_fraction", "cv_folds", "seed", "max_gp_points", "threads"):
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


def _simulator(model: str, preset, meta: dict, rig=None):
    """table of inputs -> labelled frame, with the sweep's fixed parameters and settings (with ``rig``: the
    rig's preset, parameters and effects instead of the sweep's preset and fixed parameters)."""
    import sim

    fixed = meta.get("fixed") or {}
    settings = meta.get("settings") or None
    if rig is not None:
        preset, fixed = rig.preset, rig.overrides()

    def run(table):
        for k, v in fixed.items():
            if k not in table.columns:
                table[k] = v
        return sim.simulate_batch(model, table, preset=preset, settings=settings)

    return run


def run(args) -> int:
    import json

    from pipeline import tracking
    from pipeline.core.files import atomic_write_parquet, atomic_write_text
    from pipeline.core.jsonable import dump_json
    from pipeline.datasets.store import load_with_metadata
    from surrogate import adaptive as adaptive_mod
    from surrogate import data, mlflow_model, report
    from surrogate.train import split_frame, train_bundle

    cfg = _config(args)
    df, meta = load_with_metadata(args.dataset)
    df = data.check_frame(df, f"dataset '{args.dataset}'")
    model = meta.get("model") or args.model
    if not model:
        raise UserError(f"dataset '{args.dataset}' has no metadata.json naming its model: pass --model")
    if args.model and meta.get("model") and args.model != meta["model"]:
        raise UserError(f"--model {args.model} but dataset '{args.dataset}' was simulated with model '{meta['model']}'")
    preset = meta.get("preset")
    if args.rig and not cfg.adaptive.enabled:
        raise UserError(f"--rig {args.rig} is used by --adaptive (the only part of training that simulates)")
    rig = load_rig(args.rig, model)
    inputs_arg = [s.strip() for s in args.inputs.split(",")] if args.inputs else None
    inputs, ranges = data.infer_inputs(df, meta, inputs_arg)
    fp = meta.get("fingerprint") or data.fingerprint_frame(df)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    params = {"dataset": str(args.dataset), "model": model, "preset": preset, "fingerprint": fp,
              "inputs": ",".join(inputs), "n_points": len(df),
              **{f"train.{k}": v for k, v in cfg.to_dict().items()}}
    with tracking.run("train", params, enabled=not args.no_mlflow) as mlflow:
        bundle = train_bundle(df, inputs, ranges, model, preset, cfg, scale=data.scales(meta, inputs),
                              fingerprint=fp, progress=not args.quiet, fixed=meta.get("fixed"),
                              settings=meta.get("settings"))
        train, test = split_frame(df, cfg)
        ad = None
        if cfg.adaptive.enabled:
            from threadpoolctl import threadpool_limits

            with threadpool_limits(cfg.threads):
                ad = adaptive_mod.run(bundle, train, test, cfg, _simulator(model, preset, meta, rig), progress=not args.quiet)
            design = ad.pop("design")
            atomic_write_parquet(out / "adaptive_design.parquet", design)
            bundle.report["adaptive"] = ad
        bundle.save(out)
        figs = report.figures(bundle, test, out, ad)
        flat = report.flat_metrics(bundle.report)
        if args.metrics:
            m = Path(args.metrics)
            m.parent.mkdir(parents=True, exist_ok=True)
            headline = {"held_out": bundle.report["held_out"], "goals_met": bundle.report["goals_met"],
                        "simulations_needed": bundle.report["simulations_needed"], "n_train": bundle.report["n_train"],
                        "n_test": bundle.report["n_test"], "adaptive_savings": (ad or {}).get("savings")}
            atomic_write_text(m, dump_json(headline) + "\n")
        if mlflow is not None:
            mlflow.log_metrics(flat)
            for path in figs.values():
                mlflow.log_artifact(path, artifact_path="figures")
            mlflow.log_text(json.dumps(json.loads(dump_json(bundle.report)), indent=2), "report.json")
            mlflow_model.log(mlflow, bundle, out, df)
            run_id = mlflow.active_run().info.run_id
    _print_summary(bundle, out, ad)
    if mlflow is not None:
        print(f"MLflow run {run_id}  (pipeline.tracking.load_bundle('{run_id}'))")
    return 0


def _print_summary(bundle, out: Path, ad: dict | None) -> None:
    r = bundle.report
    c = r["held_out"]["classification"]
    print(f"surrogate of '{r['model']}' (preset {r['preset']!r}) trained on {r['n_train']} simulations, "
          f"held out {r['n_test']}; written to {out}")
    print(f"  regime classifier {bundle.classifier_name}: held-out accuracy {c['accuracy']:.4f}")
    for t, m in r["held_out"]["targets"].items():
        tm = bundle.regressors[t]
        r2 = "n/a" if m.get("r2") is None else f"{m['r2']:.4f}"
        print(f"  {t:<20} {tm.name:<4} ({tm.transform.kind}, {tm.domain}, n={m['n']}): R2 {r2}, "
              f"RMSE {m.get('rmse', float('nan')):.4g}, 90% interval coverage {m.get('coverage', float('nan')):.3f}")
    need = r.get("simulations_needed") or {}
    if need:
        print("  training simulations needed: " + ", ".join(f"{k} {v if v is not None else 'not reached'}"
                                                          for k, v in need.items()))
    print("  goals met: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in r["goals_met"].items()))
    if ad:
        for k, s in ad["savings"].items():
            print(f"  adaptive ({k}): {s['adaptive_sims']} simulations reach {s['level']:.4g}; space-filling needs "
                  f"{s['space_filling_sims'] if s['space_filling_sims'] is not None else 'more than it has'}")
