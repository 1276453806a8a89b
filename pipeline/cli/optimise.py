"""``vibro optimise``: search frequency, amplitude and static force for maximum ROP, verified by the simulator."""
from __future__ import annotations

from pathlib import Path

from pipeline.cli import args as A

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
  shaker envelope: a rig file's 'exciter' (max_force_n against frequency_hz, max_stroke_m, max_velocity_m_s) is
  honoured like the power and deceleration limits; a recommendation on it says "ON THE SHAKER'S ENVELOPE".
  feedback: verified points are appended to feedback/optimise.parquet at the project root, beside optuna.db
  (or --feedback FILE; never inside the surrogate's dvc-managed folder), from whichever folder it runs; the
  infill rounds below retrain the surrogate on them (closing the loop).
  infill: a surrogate wrong at its recommended point, or at more than half of the verified points, is first
  corrected where it is used: up to --infill-rounds rounds simulate --infill-points points where the study looked
  (along the limits it ran into, around the best verified point and on the faces of the box it touches), append
  them to the feedback file, retrain the surrogate on its sweep (--train-data) plus the points of the feedback
  file this run wrote, search and verify again; report.json 'infill' (one record per round: points added,
  error at the verified points, wrong count, recommendation; the extra simulations) and report.md say how.
  how sure: with --rig (a corrected rig from vibro diagnose), the recommendation is re-simulated over 32 samples
  of the rig's fitted parameters; its ROP spread, with the rig's model_error added, goes to report.json 'spread',
  report.md and the last lines printed (as vibro compare states it).  A rig whose diagnosis left the data
  unexplained may carry an 'empirical_correction' of ROP ("physics unknown", docs/diagnose.md): --simulator
  studies apply it to every simulated ROP (the model's own in rop_model_m_s) and take its sd as the model error.
  fallback: a surrogate still wrong after the infill rounds never recommends: a study of --fallback-trials trials
  straight on the simulator (same model, rig, space and limits, started from the verified points) does, and
  report.json 'fallback' and report.md say so.

studies persist in optuna storage (default: sqlite file optuna.db at the project root); rerunning the same
command resumes the study and only runs the missing trials (--n-trials is the total).  Several workers on
one machine share the default SQLite file; on several machines give them the same --storage (a PostgreSQL
URL, or journal:///PATH on a shared file system) and --study-name: together they run exactly --n-trials
complete trials, and a killed worker's trials are re-run by the others (heartbeat, --heartbeat-s).
resume is exact only after an interruption between batches (every --batch-size trials): the rerun then holds
the trials of the uninterrupted study with the same seed.  An interruption inside a batch keeps that batch's
finished trials and proposes the rest afresh, so the study (and its recommendation) may differ from an
uninterrupted one; it still ends with exactly --n-trials trials.

examples:
  vibro optimise --surrogate models/surrogate --out results/optimise
  vibro optimise --surrogate models/surrogate --out results/optimise --max-peak-force-n 3000 --peak-force-static-ratio 2.5
  vibro optimise --surrogate models/surrogate --out results/optimise --max-power-w 18 --max-decel-g 4
  vibro optimise --surrogate models/surrogate --out results/optimise --max-power-w 18 --max-decel-g 4 --margin 0.05
  vibro optimise --simulator --max-power-w 18 --max-decel-g 4 --margin power_w=0.05 --margin peak_decel_g=0.1
  vibro optimise --simulator --max-power-w 18 --max-decel-g 4 --margin 0.05 --limit-map --out results/o  # + maps
  vibro optimise --surrogate models/surrogate --out results/pareto --objective pareto --n-verify 12
  vibro optimise --surrogate models/surrogate --out results/pareto --objective pareto --objectives rop_m_s,peak_decel_g
  vibro optimise --simulator --model drill --preset lab --n-trials 200 --out results/optimise-sim
  vibro optimise --simulator --preset lab --vary frequency_hz=150:350 --set static_force_n=1200 --out results/f-scan
  vibro optimise --simulator --rig my-rig.yaml --n-trials 200 --out results/my-rig      # your own rig
  vibro optimise --simulator --rig my-rig.yaml --sampler tpe --out results/my-rig-tpe   # optuna's TPE instead
  vibro optimise --params params.yaml --metrics metrics/optimise.json
  vibro optimise --surrogate models/surrogate --out results/optimise --fallback-trials 0   # report a failed surrogate, no fallback
  vibro optimise --surrogate models/surrogate-rig --train-data data/sweep-rig --infill-rounds 3 --infill-points 16 \
      --max-power-w 18 --max-decel-g 4 --out results/optimise-rig      # retrain where the surrogate was wrong
  vibro optimise --surrogate models/surrogate --infill-rounds 0 --out results/optimise     # no infill: fallback at once
  vibro optimise --simulator --storage postgresql://user@host/optuna --study-name rig-a --n-trials 400
  vibro optimise --simulator --storage journal:///shared/optuna/rig-a.log --study-name rig-a --n-trials 400 --heartbeat-s 30
"""


from pipeline.cli.args import (add_quiet, add_rig, add_set, add_workers, check_workers, load_rig,  # noqa: E402
                               parse_assignments, parse_ranges)
from pipeline.core.errors import UserError  # noqa: E402
from pipeline.core.rigfile import rig_name  # noqa: E402
from pipeline.core.units import spread_sentence  # noqa: E402


def _add_fallback(p) -> None:
    """What follows a surrogate that fails its verification: infill rounds, then a study on the simulator."""
    p.add_argument("--fallback-trials", type=A.count(0, 100_000),
                   help="when the surrogate fails its verification (its recommended point, or more than half of the "
                        "verified points, wrong) after --infill-rounds, run this many trials straight on the "
                        "simulator over the same space and recommend from those instead (default 200; 0: off)")
    p.add_argument("--infill-rounds", type=A.count(0, 100), metavar="N",
                   help="when the surrogate fails its verification, first up to N rounds of infill: simulate the "
                        "points where the study looked (around the best verified point, along the limits it ran "
                        "into, on the faces of the box it touches), retrain the surrogate on its sweep plus every "
                        "point simulated so far (the feedback file), search and verify again, until a round agrees and "
                        "its recommendation gains at most 1 %% of ROP over the round before; the --fallback-trials "
                        "study runs only if the last round still fails (default 3; 0: straight to the fallback)")
    p.add_argument("--infill-points", type=A.count(1, 10_000), metavar="N",
                   help="points simulated per infill round, besides the verified ones (default 16)")
    p.add_argument("--train-data", metavar="DATASET",
                   help="the sweep the surrogate was trained on, for infill (default: the dataset its report.json "
                        "names)")


def _add_limits(p) -> None:
    """The constraints (upper limits on the labels), the margin kept below them and the limit maps."""
    p.add_argument("--max-peak-force-n", type=A.positive, metavar="N", help="constraint: peak_force_n <= N newtons")
    p.add_argument("--peak-force-static-ratio", type=A.positive, metavar="K",
                   help="constraint: peak_force_n <= K × static_force_n (K = 1: impact below the static preload)")
    p.add_argument("--max-specific-energy-j-m", type=A.positive, metavar="E", help="constraint: specific_energy_j_m <= E J/m")
    p.add_argument("--max-power-w", type=A.positive, metavar="W",
                   help="constraint: the excitation's mean power power_w <= W watts (the exciter's power rating)")
    p.add_argument("--max-decel-g", type=A.positive, metavar="G",
                   help="constraint: the bit's peak deceleration peak_decel_g <= G (in g; tool life)")
    p.add_argument("--margin", action="append", metavar="FRACTION|LABEL=FRACTION",
                   help="keep the recommendation this fraction below every limit (0.05 = 5 %%), or below one limit "
                        "(power_w=0.05; repeatable); on the surrogate a point is judged by the upper end of its "
                        "predicted interval, so it stays feasible within that uncertainty")
    p.add_argument("--limit-map", action="store_true",
                   help="also simulate two maps of ROP around the recommendation over the search box (frequency x "
                        "static force at its amplitude, frequency x amplitude at its static force, 25 x 13 cells each) "
                        "with the limits' contours, the margin's and the exciter's envelope: limit_map_*.png/.parquet")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "optimise", help="optimise the operating point for ROP (optuna), verified by the simulator",
        description="Search the controls (frequency_hz, amplitude_n, static_force_n) for maximum rate of penetration "
                    "with optuna (a Sobol' pass then a local search by default), on a trained surrogate (then re-simulate the best distinct points) "
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
    add_rig(p, "with --simulator, optimise")
    A.add_chain(p, "the surrogate's chain (its report.json), corrected with --rig, else lab")
    p.add_argument("--vary", "--range", dest="ranges", action="append", metavar="NAME=LOW:HIGH",
                   help="search range (repeatable); default: the surrogate's training ranges, or the preset's published "
                        "space (drill lab: LAB_SPACE); alias --range")
    add_set(p, ("--fixed",), help="hold a parameter at a value (repeatable), e.g. --set static_force_n=1200; "
                                  "alias --fixed")
    p.add_argument("--objective", choices=["rop", "pareto"],
                   help="rop: maximise ROP (default); pareto: the front of --objectives (default ROP against power_w)")
    p.add_argument("--objectives", metavar="LABEL,LABEL[,...]",
                   help="Pareto objectives (default rop_m_s,power_w): any labels; rop_m_s is maximised, the others "
                        "minimised, or say max:LABEL / min:LABEL")
    p.add_argument("--sampler", choices=["tpe", "sobol-local", "gp", "nsga2", "random"],
                   help="optuna sampler (default: sobol-local for --objective rop, a Sobol' pass then a local search "
                        "that reaches the box's bounds and the limits exactly, the only one within 0.995 of a dense "
                        "scan on every case of bench/bench_search.py; tpe for pareto; gp needs PyTorch)")
    p.add_argument("--n-trials", type=A.n_trials, help="total complete trials of the study (default 600 on the surrogate, "
                                                 "200 on the simulator = simulator calls)")
    p.add_argument("--batch-size", type=A.count(1, 10_000), help="trials proposed and evaluated together (default 8)")
    p.add_argument("--seed", type=A.seed, help="sampler seed (default 0): same seed, same study")
    _add_limits(p)
    p.add_argument("--allow-not-settled", action="store_true",
                   help="accept not_settled (bounded but aperiodic) points; runaway and failed never are")
    p.add_argument("--n-verify", type=A.count(1, 10_000), help="distinct best points (or front points) re-simulated (default 10)")
    p.add_argument("--rel-tol", type=A.positive, help="ROP relative error above which the surrogate is wrong (default 0.1)")
    _add_fallback(p)
    p.add_argument("--storage", metavar="URL",
                   help="optuna storage URL (default sqlite:///<project root>/optuna.db: workers of one machine); "
                        "postgresql://USER@HOST/DB for workers on several machines (or any SQLAlchemy RDB URL); "
                        "journal:///PATH/study.log for a journal file on a file system every worker mounts, no "
                        "server (never a SQLite file on NFS); docs/scale.md says which to choose")
    p.add_argument("--heartbeat-s", type=A.count(1, 3600), metavar="S",
                   help="server and journal storages: a running trial records a heartbeat every S seconds; one "
                        "silent for 3*S (a killed or lost worker's) is marked failed and re-run, at most 3 times "
                        "(default 10)")
    p.add_argument("--study-name", help="study name (default derived from mode, objective, model, preset and settings)")
    p.add_argument("--feedback", metavar="FILE.parquet",
                   help=f"append verified points here (default <project root>/{DEFAULT_FEEDBACK}, beside optuna.db, "
                        "outside every dvc output; "
                        "never inside the surrogate's folder)")
    add_workers(p, dest="n_threads", help="simulator threads (default: all cores)")
    p.add_argument("--out", default="results/optimise", help="output directory (default results/optimise)")
    p.add_argument("--metrics", metavar="FILE.json", help="write the small metrics JSON here (for dvc)")
    p.add_argument("--no-mlflow", action="store_true", help="do not log to MLflow")
    add_quiet(p)
    A.add_overwrite(p, "optimisation result")
    p.set_defaults(func=run)


DEFAULT_FEEDBACK = "feedback/optimise.parquet"
"""Where verified points go without --feedback, relative to the project root (like the default optuna.db, so both
land in one place whatever the current folder): outside every dvc-managed output (dvc.yaml outs)."""


def _feedback_path(base: dict) -> None:
    """Default the feedback file outside the (dvc-managed) surrogate folder; refuse one inside it."""
    from pathlib import Path

    fb = base.get("feedback")
    sur = base.get("surrogate") or "models/surrogate" if base.get("mode", "surrogate") == "surrogate" else None
    if fb is None and sur is not None and Path(str(sur)).is_dir():
        from pipeline.tracking import project_root

        base["feedback"] = fb = str(project_root() / DEFAULT_FEEDBACK)
    if fb and sur and Path(str(sur)).is_dir() and Path(str(sur)).resolve() in Path(fb).resolve().parents:
        raise UserError(f"--feedback {fb} is inside the surrogate folder {sur} (a dvc-managed output that "
                        f"the next 'make run' replaces): write it elsewhere, e.g. {DEFAULT_FEEDBACK}")


def config_from_args(args):
    """OptimiseConfig from params.yaml's ``optimise`` section overridden by the flags."""
    return config_and_rig(args)[0]


def config_and_rig(args):
    """(OptimiseConfig, the ``sim.Rig`` of ``--rig`` or params.yaml's ``rig`` — None without one)."""
    from pipeline.optimise.config import OptimiseConfig, check_numbers

    from pipeline.core.params import read_section

    base: dict = read_section(args.params, "optimise")
    base = check_numbers(base, f"{args.params}: optimise" if args.params else "optimise")
    if args.simulator:
        base["mode"] = "simulator"
    elif args.surrogate:
        base["mode"], base["surrogate"] = "surrogate", args.surrogate
    rig_path = args.rig or base.pop("rig", None)
    base.pop("rig", None)
    rig = None
    if rig_path:
        if base.get("mode", "surrogate") != "simulator":
            raise UserError(f"--rig {rig_path} needs --simulator (a surrogate carries the rig it was trained on)")
        rig = load_rig(rig_path, args.model, args.preset)
        from pipeline.core.rigfile import read_exciter

        base["exciter"] = read_exciter(rig_path)
        if rig.empirical is not None:
            base["rop_correction"] = rig.empirical.to_mapping()
        base["model"], base["preset"] = rig.model, rig.preset
        base["fixed"] = {**rig.overrides(), **(base.get("fixed") or {})}
        args.model = args.preset = None
    if args.ranges:
        base["ranges"] = parse_ranges(args.ranges, "--vary")
    if args.sets:
        base["fixed"] = {**(base.get("fixed") or {}), **parse_assignments(args.sets, "--set")}
    if args.objectives:
        base["objectives"] = [s.strip() for s in args.objectives.split(",") if s.strip()]
    elif (args.objective or base.get("objective", "rop")) == "rop":
        base.pop("objectives", None)    # params.yaml's section serves both stages: its objectives are the Pareto study's
    for key in ("model", "preset", "objective", "sampler", "n_trials", "batch_size", "seed", "max_peak_force_n",
                "peak_force_static_ratio", "max_specific_energy_j_m", "max_power_w", "max_decel_g", "n_verify",
                "rel_tol", "fallback_trials", "storage", "heartbeat_s", "study_name", "feedback", "n_threads",
                "infill_rounds", "infill_points", "train_data"):
        v = getattr(args, key)
        if v is not None:
            base[key] = v
    if args.allow_not_settled:
        base["allow_not_settled"] = True
    if args.margin:
        base["margin"] = parse_margin(args.margin)
    if args.limit_map:
        base["limit_map"] = True
    if str(base.get("preset", "")).lower() == "none":
        base["preset"] = None
    check_workers(base.get("n_threads"))
    if base.get("mode") == "simulator" and base.get("ranges"):
        check_range_values(base["ranges"], base.get("model"))
    _feedback_path(base)
    base["storage"] = real_sqlite_url(base.get("storage"))
    return OptimiseConfig.from_mapping(base), rig


def parse_margin(items: list[str]) -> float | dict:
    """``["0.05"]`` -> 0.05 (every limit); ``["power_w=0.05", "peak_decel_g=0.1"]`` -> {label: fraction}."""
    if len(items) == 1 and "=" not in items[0]:
        return A.number(items[0], "--margin")
    out = {}
    for item in items:
        name, sep, val = item.partition("=")
        if not sep or not name.strip():
            raise UserError(f"--margin expects FRACTION or LABEL=FRACTION (repeatable), got '{item}'")
        out[name.strip()] = A.number(val, f"--margin {name.strip()}")
    return out


def check_range_values(ranges: dict, model: str | None) -> None:
    """UserError naming the range whose bound is no valid value of its parameter in ``model`` (e.g. frequency_hz
    = 0: the model's ``Param`` says > 0); the sampler may draw a bound itself.  Unknown names and malformed
    ranges are left to the search space's own check."""
    import sim
    from pipeline.core.numbers import PLAUSIBLE_FACTOR, plausible
    from pipeline.optimise.space import space_from_mapping
    from sim.registry import DEFAULT_MODEL

    if (model or DEFAULT_MODEL) not in sim.model_names():
        return                              # the run's own check names the unknown model
    spec = sim.get_model(model or DEFAULT_MODEL)
    by_name = {p.name: p for p in spec.params}
    for name, (lo, hi) in space_from_mapping(ranges).ranges.items():
        for end, v in (("low", lo), ("high", hi)):
            try:
                if name in by_name:
                    by_name[name].validate(v)
            except sim.ParameterError as e:
                raise UserError(f"range '{name}': its {end} bound {v:g} is outside the parameter's valid values "
                                f"({e})") from None
            if name in by_name and not plausible(v, by_name[name].default):
                raise UserError(f"range '{name}': its {end} bound {v:g} is not within a factor {PLAUSIBLE_FACTOR:g} "
                                f"of the parameter's default {by_name[name].default:g} {by_name[name].unit}; "
                                "not a physical range")


def real_sqlite_url(url: str | None) -> str | None:
    """A ``sqlite:///`` URL with its file's real path (symlinks resolved), so every worker reaching one database
    through another name shares its locks and its journal; other URLs unchanged."""
    from pipeline.optimise.coordination import sqlite_path

    db = sqlite_path(url)
    if db is None or "?" in str(db):
        return url
    return "sqlite:///" + str(db.resolve())


def run_tracked(cfg, out_dir, bundle=None, metrics_path: str | None = None, progress: bool = True,
                mlflow_enabled: bool = True, rig=None):
    """``optimise`` of ``cfg`` (on ``rig``, when given) into ``out_dir`` in an MLflow run that logs its parameters,
    metrics and files."""
    from pipeline import tracking
    from pipeline.optimise.outcome import optimise, plan_study
    from pipeline.optimise.outputs import run_params

    plan = plan_study(cfg, bundle)
    with tracking.run("optimise", run_params(plan), enabled=mlflow_enabled) as mlflow:
        outcome = optimise(cfg, out_dir, plan=plan, metrics_path=metrics_path, progress=progress,
                           notify=_say if progress else None, rig=rig)
        if mlflow is not None:
            _log_run(mlflow, outcome)
    return outcome


def _say(text: str) -> None:
    import sys

    print(f"vibro optimise: {text}", file=sys.stderr)


def _log_run(mlflow, outcome) -> None:
    """The finite metrics, the recommended controls as params, and the report, figures and verified.csv as artifacts."""
    import math

    rep = outcome.report
    files = [*outcome.figures, *map(str, outcome.reports),
             *(str(f) for f in outcome.tables if f.name == "verified.csv")]
    mlflow.log_metrics({k: float(v) for k, v in rep["metrics"].items()
                        if isinstance(v, (int, float)) and v is not None and math.isfinite(float(v))})
    if rep["recommendation"]:
        mlflow.log_params({f"best_{n}": v for n, v in rep["recommendation"]["params"].items()})
    for f in files:
        mlflow.log_artifact(f)


def run(args) -> int:
    from pipeline import tracking

    from pipeline.core.outdir import prepare_out

    from pipeline.core.outdir import check_out_file, record_out_file
    from pipeline.optimise.coordination import sqlite_path
    from pipeline.optimise.storages import check_storage_target, journal_path
    from pipeline.optimise.study import default_storage
    from pipeline.tracking.bundles import surrogate_chain, surrogate_rig

    cfg, rig_obj = config_and_rig(args)
    chain = A.chain_of(args, surrogate_chain(cfg.surrogate) if cfg.mode == "surrogate" else None)
    rig = rig_name(args.rig) or (surrogate_rig(cfg.surrogate) if cfg.mode == "surrogate" else None)
    url = cfg.storage or default_storage()
    check_storage_target(url)
    db = sqlite_path(url) or (journal_path(url) and Path(journal_path(url)))
    reads = [args.params, args.surrogate if args.surrogate and Path(args.surrogate).exists() else None,
             args.rig, db, db and f"{db}.lock", args.out]
    if args.metrics:
        check_out_file(args.metrics, flag="--metrics", kind="json", inputs=[*reads, cfg.feedback],
                       overwrite=args.overwrite)
    if cfg.feedback:
        check_out_file(cfg.feedback, flag="--feedback", kind="feedback", inputs=[*reads, args.metrics])
    inputs = [args.params, args.surrogate if args.surrogate and Path(args.surrogate).exists() else None,
              args.metrics, args.feedback, db]
    with tracking.variant(cfg.objective), tracking.chain(chain, rig), \
            prepare_out(args.out, inputs=inputs, overwrite=args.overwrite, marker="optimise") as tmp:
        rep = run_tracked(cfg, tmp, metrics_path=args.metrics, progress=not args.quiet,
                          mlflow_enabled=not args.no_mlflow, rig=rig_obj).report
    if args.metrics:
        record_out_file(args.metrics, command="optimise", kind="json")
    if rep["recommendation"] is None:        # the report is in place: the error names where it stays
        raise UserError(f"{rep['outcome']}; report: {Path(args.out) / 'report.md'}")
    print(rep["outcome"])
    if rep.get("pareto_verified") is not None:
        print(f"verified Pareto front ({' vs '.join(rep.get('objectives', []))}): {len(rep['pareto_verified'])} "
              f"distinct non-dominated points")
    if cfg.mode == "surrogate" and rep.get("surrogate_note"):
        print(rep["surrogate_note"])
    if rep.get("infill"):
        print("\n".join(rep["infill"]["lines"]))
        print(rep["infill"]["text"])
    if rep.get("fallback"):
        print(rep["fallback"]["text"])
    if rep.get("spread"):
        print(f"how sure: {spread_sentence(rep['spread'])}")
    print(f"report: {args.out}/report.md")
    return 0
