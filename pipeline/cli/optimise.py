"""``vibro optimise``: search frequency, amplitude and static force for maximum ROP, verified by the simulator."""
from __future__ import annotations

import argparse


EPILOG = """\
what it writes under --out:
  report.md / report.json   recommendation (the best point verified by the simulator), what was tried,
                            prediction next to simulation for every verified point
  verified.csv              verified points: inputs, T_pred [T_lo, T_hi], T_sim, statuses, surrogate_wrong, why
  trials.csv                every complete trial of the study (inputs, value(s), labels, feasibility)
  history.png, importances.png, verification.png, pareto.png (with --objective pareto)
  the outcome line says which limits the recommendation sits at and whether it lies on a bound of the search
  space (which control, lower or upper): there the optimum may lie beyond the box.
  feedback: verified points are appended to <surrogate dir>/feedback.parquet (or --feedback FILE) so that
  training can include them (closing the loop).

studies persist in optuna storage (default: sqlite file optuna.db at the project root); rerunning the same
command resumes the study and only runs the missing trials (--n-trials is the total).  Several workers on
several machines: give them the same --storage RDB URL and --study-name.

examples:
  vibro optimise --surrogate models/surrogate --out results/optimise
  vibro optimise --surrogate models/surrogate --out results/optimise --max-peak-force-n 3000 --peak-force-static-ratio 2.5
  vibro optimise --surrogate models/surrogate --out results/optimise --max-power-w 18 --max-decel-g 4
  vibro optimise --surrogate models/surrogate --out results/pareto --objective pareto --n-verify 12
  vibro optimise --surrogate models/surrogate --out results/pareto --objective pareto --objectives rop_m_s,peak_decel_g
  vibro optimise --simulator --model drill --preset lab --n-trials 200 --out results/optimise-sim
  vibro optimise --simulator --preset lab --range frequency_hz=150:350 --fixed static_force_n=1200 --out results/f-scan
  vibro optimise --params params.yaml --metrics metrics/optimise.json
  vibro optimise --simulator --storage postgresql://user@host/optuna --study-name rig-a --n-trials 400
"""


def add_parser(sub) -> None:
    p = sub.add_parser(
        "optimise", help="optimise the operating point for ROP (optuna), verified by the simulator",
        description="Search the controls (frequency_hz, amplitude_n, static_force_n) for maximum rate of penetration "
                    "with optuna (TPE by default), on a trained surrogate (then re-simulate the best distinct points) "
                    "or directly on the simulator, under constraints: a bounded settled steady state (never "
                    "runaway), optional upper limits on peak impact force (absolute, or k × static force: seed 002's "
                    "bit-bounce rule), on specific energy, on the exciter's mean power and on the bit's peak "
                    "deceleration.  --objective pareto gives the front of ROP against the mean power (or the labels "
                    "--objectives names).  The recommendation is the best *verified* point; where the surrogate was "
                    "wrong the report says so and the point is added to the feedback file for retraining.",
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG)
    p.add_argument("--params", metavar="FILE", help="params.yaml: its 'optimise' section gives defaults; flags override")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--surrogate", metavar="DIR|RUN_ID",
                     help="surrogate bundle directory or MLflow run id (mode 'surrogate'; default models/surrogate)")
    src.add_argument("--simulator", action="store_true", help="optimise directly on the simulator (mode 'simulator')")
    p.add_argument("--model", help="model for --simulator (default drill; the surrogate knows its own)")
    p.add_argument("--preset", help="preset for --simulator (default lab)")
    p.add_argument("--range", dest="ranges", action="append", metavar="NAME=LOW:HIGH",
                   help="search range (repeatable); default: the surrogate's training ranges, or the preset's published "
                        "space (drill lab: LAB_SPACE)")
    p.add_argument("--fixed", action="append", metavar="NAME=VALUE",
                   help="hold a parameter at a value (repeatable), e.g. --fixed static_force_n=1200")
    p.add_argument("--objective", choices=["rop", "pareto"],
                   help="rop: maximise ROP (default); pareto: the front of --objectives (default ROP against power_w)")
    p.add_argument("--objectives", metavar="LABEL,LABEL[,...]",
                   help="Pareto objectives (default rop_m_s,power_w): any labels; rop_m_s is maximised, the others "
                        "minimised, or say max:LABEL / min:LABEL")
    p.add_argument("--sampler", choices=["tpe", "gp", "nsga2", "random"],
                   help="optuna sampler (default tpe: constraints, batches, no extra package; gp needs PyTorch)")
    p.add_argument("--n-trials", type=int, help="total complete trials of the study (default 600 on the surrogate, "
                                                 "200 on the simulator = simulator calls)")
    p.add_argument("--batch-size", type=int, help="trials proposed and evaluated together (default 8)")
    p.add_argument("--seed", type=int, help="sampler seed (default 0): same seed, same study")
    p.add_argument("--max-peak-force-n", type=float, metavar="N", help="constraint: peak_force_n <= N newtons")
    p.add_argument("--peak-force-static-ratio", type=float, metavar="K",
                   help="constraint: peak_force_n <= K × static_force_n (K = 1: impact below the static preload)")
    p.add_argument("--max-specific-energy-j-m", type=float, metavar="E", help="constraint: specific_energy_j_m <= E J/m")
    p.add_argument("--max-power-w", type=float, metavar="W",
                   help="constraint: the excitation's mean power power_w <= W watts (the exciter's power rating)")
    p.add_argument("--max-decel-g", type=float, metavar="G",
                   help="constraint: the bit's peak deceleration peak_decel_g <= G (in g; tool life)")
    p.add_argument("--allow-not-settled", action="store_true",
                   help="accept not_settled (bounded but aperiodic) points; runaway and failed never are")
    p.add_argument("--n-verify", type=int, help="distinct best points (or front points) re-simulated (default 10)")
    p.add_argument("--rel-tol", type=float, help="ROP relative error above which the surrogate is wrong (default 0.1)")
    p.add_argument("--storage", metavar="URL", help="optuna storage URL (default sqlite:///<project root>/optuna.db)")
    p.add_argument("--study-name", help="study name (default derived from mode, objective, model, preset and settings)")
    p.add_argument("--feedback", metavar="FILE.parquet",
                   help="append verified points here (default <surrogate dir>/feedback.parquet; simulator mode: none)")
    p.add_argument("--threads", type=int, dest="n_threads", help="simulator threads (default: all cores)")
    p.add_argument("--out", default="results/optimise", help="output directory (default results/optimise)")
    p.add_argument("--metrics", metavar="FILE.json", help="write the small metrics JSON here (for dvc)")
    p.add_argument("--no-mlflow", action="store_true", help="do not log to MLflow")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def config_from_args(args):
    """OptimiseConfig from params.yaml's ``optimise`` section overridden by the flags."""
    from pipeline.cli.args import parse_assignments
    from pipeline.optimise.space import parse_range
    from pipeline.optimise.workflow import OptimiseConfig

    from pipeline.core.params import read_section

    base: dict = read_section(args.params, "optimise")
    if args.simulator:
        base["mode"] = "simulator"
    elif args.surrogate:
        base["mode"], base["surrogate"] = "surrogate", args.surrogate
    if args.ranges:
        base["ranges"] = dict(parse_range(r) for r in args.ranges)
    if args.fixed:
        base["fixed"] = {**(base.get("fixed") or {}), **parse_assignments(args.fixed, "--fixed")}
    if args.objectives:
        base["objectives"] = [s.strip() for s in args.objectives.split(",") if s.strip()]
    for key in ("model", "preset", "objective", "sampler", "n_trials", "batch_size", "seed", "max_peak_force_n",
                "peak_force_static_ratio", "max_specific_energy_j_m", "max_power_w", "max_decel_g", "n_verify", "rel_tol", "storage", "study_name",
                "feedback", "n_threads"):
        v = getattr(args, key)
        if v is not None:
            base[key] = v
    if args.allow_not_settled:
        base["allow_not_settled"] = True
    if str(base.get("preset", "")).lower() == "none":
        base["preset"] = None
    return OptimiseConfig.from_mapping(base)


def run(args) -> int:
    from pipeline.optimise.workflow import run_optimise

    cfg = config_from_args(args)
    rep = run_optimise(cfg, args.out, metrics_path=args.metrics, progress=not args.quiet,
                       mlflow_enabled=not args.no_mlflow)
    print(rep["outcome"])
    if rep.get("pareto_verified") is not None:
        print(f"verified Pareto front ({' vs '.join(rep.get('objectives', []))}): {len(rep['pareto_verified'])} "
              f"distinct non-dominated points")
    if cfg.mode == "surrogate" and rep.get("surrogate_note"):
        print(rep["surrogate_note"])
    print(f"report: {args.out}/report.md")
    return 0
