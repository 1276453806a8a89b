"""``vibro verify``: re-simulate a list of points and compare with their predictions."""
from __future__ import annotations

import argparse

from pipeline.cli import args as A
from pipeline.cli.args import add_quiet, add_rig, add_set, add_workers, check_workers, load_rig
from pipeline.core.errors import UserError
from pipeline.core.rigfile import rig_name

EPILOG = """\
input: a CSV or Parquet file with one row per point and the input columns (frequency_hz, amplitude_n,
static_force_n, ...).  Predictions come from --surrogate, or else from the file's own columns rop_m_s,
peak_force_n, impacts_per_cycle, specific_energy_j_m (or *_pred), with optional *_lo/*_hi intervals and status.

output under --out: verified.csv (inputs, T_pred, T_lo, T_hi, T_sim, status_pred, status_sim, feasible_pred,
feasible_sim, rop_rel_error, in_interval, surrogate_wrong, why), verification.png, summary.json.

examples:
  vibro verify results/optimise/verified.csv --surrogate models/surrogate --out results/verify
  vibro verify candidates.parquet --model drill --preset lab --out results/verify --metrics metrics/verify.json
  vibro verify points.csv --surrogate models/surrogate --feedback feedback/verify.parquet
  vibro verify candidates.csv --rig my-rig.yaml --out results/verify-my-rig       # your own rig
"""


def add_parser(sub) -> None:
    p = sub.add_parser(
        "verify", help="re-simulate points (CSV/Parquet) and compare with predictions",
        description="Re-simulate every point of a CSV/Parquet file with the simulator and put the prediction (from a "
                    "surrogate bundle or the file's own columns) next to the simulated labels; a point is marked "
                    "surrogate_wrong when its feasibility differs or its ROP is off by more than --rel-tol.",
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG)
    p.add_argument("points", help="CSV or Parquet file of points")
    p.add_argument("--surrogate", metavar="DIR|RUN_ID", help="predict with this surrogate bundle (model, preset and "
                                                              "inputs come from it)")
    p.add_argument("--model", help="model to simulate without --surrogate (default drill)")
    p.add_argument("--preset", help="preset without --surrogate (default lab; 'none' for the defaults)")
    p.add_argument("--inputs", nargs="+", metavar="NAME",
                   help="input columns (default: the surrogate's inputs, else every model parameter in the file)")
    add_rig(p, "without --surrogate, re-simulate on")
    add_set(p, ("--fixed",), help="hold a parameter at a value (repeatable; over the rig or the surrogate's "
                                  "sweep conditions); alias --fixed")
    p.add_argument("--max-peak-force-n", type=A.positive, metavar="N", help="feasibility: peak_force_n <= N")
    p.add_argument("--peak-force-static-ratio", type=A.positive, metavar="K", help="feasibility: peak_force_n <= K × static_force_n")
    p.add_argument("--max-specific-energy-j-m", type=A.positive, metavar="E", help="feasibility: specific_energy_j_m <= E")
    p.add_argument("--allow-not-settled", action="store_true", help="count not_settled points as feasible")
    p.add_argument("--rel-tol", type=A.positive, default=0.1, help="ROP relative error marking a wrong prediction (default 0.1)")
    p.add_argument("--feedback", metavar="FILE.parquet", help="append the simulated points to this feedback file")
    add_workers(p, dest="n_threads", help="simulator threads (default: all cores)")
    add_quiet(p)
    p.add_argument("--out", default="results/verify", help="output directory (default results/verify)")
    p.add_argument("--metrics", metavar="FILE.json", help="write the summary metrics JSON here too")
    p.add_argument("--no-mlflow", action="store_true", help="do not log to MLflow")
    A.add_overwrite(p, "verification")
    p.set_defaults(func=run)


def _what_to_simulate(args, points, fixed: dict, bundle) -> tuple:
    """Model, preset, fixed parameters, simulator settings and input columns: the surrogate bundle's (its sweep
    conditions under --set), or the rig's / --model and --preset with the file's columns of that model (columns of
    another model refused)."""
    import sim

    if bundle is not None:
        model, preset = bundle.model, bundle.preset
        fixed = {**bundle.fixed, **fixed}     # the sweep's conditions, overridden by --set
        settings = bundle.settings or None
        inputs = args.inputs or list(bundle.inputs)
    else:
        rig = load_rig(args.rig, args.model, args.preset)
        if rig is not None:
            model, preset = rig.model, rig.preset
            fixed = {**rig.overrides(), **fixed}
        else:
            model = args.model or sim.registry.DEFAULT_MODEL
            preset = "lab" if args.preset is None else (None if str(args.preset).lower() == "none" else args.preset)
        settings = None
        names = sim.get_model(model).param_names
        others = {p for m in sim.model_names() if m != model for p in sim.get_model(m).param_names} - set(names)
        foreign = [c for c in points.columns if c in others]
        if foreign:
            where = f"rig file {args.rig} describes" if rig is not None else "this run simulates"
            raise UserError(f"{args.points}: column(s) {', '.join(foreign[:4])} are parameters of another model, "
                            f"but {where} model '{model}': the points were made for another model")
        inputs = args.inputs or [c for c in points.columns if c in names]
        if not inputs:
            raise UserError(f"{args.points}: no column is a parameter of model '{model}' "
                            f"({', '.join(names)}); give --inputs")
    return model, preset, fixed, settings, inputs


def run(args) -> int:
    from pathlib import Path

    from pipeline import tracking
    from pipeline.cli.args import parse_assignments
    from vibrobase.jsonable import dump_json
    from vibrobase.files import atomic_write_text
    from pipeline.optimise.constraints import Constraints
    from pipeline.optimise.verify import VerifyConfig, read_points, run_verify
    from pipeline.core.outdir import check_out, check_out_file, prepare_out, record_out_file
    from pipeline.tracking import load_bundle

    if args.rel_tol <= 0:
        raise UserError(f"--rel-tol must be > 0, got {args.rel_tol}")
    check_workers(args.n_threads)
    if args.rig and args.surrogate:
        raise UserError(f"--rig {args.rig} and --surrogate: the surrogate carries the rig it was trained on; "
                        "give one of them")
    points = read_points(args.points)
    fixed = parse_assignments(args.sets, "--set")
    bundle = load_bundle(args.surrogate) if args.surrogate else None
    model, preset, fixed, settings, inputs = _what_to_simulate(args, points, fixed, bundle)
    cons = Constraints(max_peak_force_n=args.max_peak_force_n, peak_force_static_ratio=args.peak_force_static_ratio,
                       max_specific_energy_j_m=args.max_specific_energy_j_m, require_settled=not args.allow_not_settled)
    cons.check(None, None)
    out = Path(args.out)
    sources = [args.points, args.surrogate if args.surrogate and Path(args.surrogate).exists() else None,
               args.feedback, args.metrics]
    check_out(out, inputs=sources, overwrite=args.overwrite, marker="verify")
    reads = [args.points, args.surrogate if args.surrogate and Path(args.surrogate).exists() else None, args.rig, out]
    if args.metrics:
        check_out_file(args.metrics, flag="--metrics", kind="json", inputs=[*reads, args.feedback],
                       overwrite=args.overwrite)
    if args.feedback:
        check_out_file(args.feedback, flag="--feedback", kind="feedback", inputs=[*reads, args.metrics])
    params = {"points": args.points, "surrogate": args.surrogate, "model": model, "preset": preset,
              "inputs": ",".join(inputs), "rel_tol": args.rel_tol, **cons.to_dict()}
    cfg = VerifyConfig(points=points, source=args.points, model=model, preset=preset, inputs=inputs,
                       constraints=cons, rel_tol=args.rel_tol, bundle=bundle, fixed=fixed, settings=settings,
                       n_threads=args.n_threads, feedback=args.feedback)
    with prepare_out(out, inputs=sources, overwrite=args.overwrite, marker="verify") as tmp, \
            tracking.chain("corrected" if args.rig else "lab", rig_name(args.rig)), \
            tracking.run("verify", params, enabled=not args.no_mlflow) as mlflow:
        res = run_verify(cfg, tmp, progress=not args.quiet)
        summary = res.summary
        if args.metrics:
            atomic_write_text(Path(args.metrics), dump_json(summary))
            record_out_file(args.metrics, command="verify", kind="json")
        if mlflow is not None:
            mlflow.log_metrics({k: float(v) for k, v in summary.items() if isinstance(v, (int, float))})
            for f in (res.figure, str(res.table_path), str(res.summary_path)):
                mlflow.log_artifact(f)
    med = summary["rop_rel_error_median"]
    med = "n/a" if med is None else f"{100 * med:.2g} %"
    counts = ", ".join(f"{k} {v}" for k, v in summary["status_sim_counts"].items())
    print(f"verified {summary['n_points']} point(s): surrogate wrong at {summary['n_surrogate_wrong']}, "
          f"median relative ROP error {med}, simulator statuses: {counts}")
    print(f"table: {out / 'verified.csv'}")
    return 0

