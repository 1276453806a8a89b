"""``vibro sweep``: build (or resume) a labelled Parquet dataset over a design of parameter points."""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from pipeline.cli import args as A
from pipeline.cli.args import (add_quiet, add_rig, add_set, add_workers, check_settings, load_rig, number, parse_assignments,
                               parse_settings)
from pipeline.core.errors import UserError
from pipeline.core.rigfile import rig_name
from pipeline.core.design_names import BOUNDARY_FRACTION, DESIGN_MEANINGS

DESIGNS = tuple(DESIGN_MEANINGS)

EPILOG = """\
spec (params.yaml section 'sweep'; command-line options override it):
  model: drill                 preset: lab (null = model defaults)
  rig: my-rig.yaml             optional rig file: model, preset, parameters, effects (docs/commands.md "Rig files")
  fixed: {gap_m: 0.0}          parameters held constant (on top of the rig)
  vary:                        varied parameters; scale linear|log; levels = grid points (grid only)
    frequency_hz: {low: 10.0, high: 400.0, scale: linear}
  design: sobol|sobol-boundary|lhs|grid   n_points: 1024      seed: 0
  boundary_fraction: 0.25      sobol-boundary only: share of the points on the box's corners, edges, faces
  settings: {window: 32}       sim.Settings fields (part of the spec)
  chunk_size: 64               points per chunk file (execution detail)
  scheduler: null              Dask scheduler address, or local:N
  workers: null                local threads (default: all cores)

designs (--design, sweep.design):
{designs}

output: OUT/part-XXXXX.parquet (one row per point: point_id, every resolved parameter, every
MODELS.md section-5 label, status, reason, transient_cycles, n_steps, n_events) and
OUT/metadata.json (spec, fingerprint, git commit, package versions, seed, wall time, status counts).
Rerunning the same command after an interruption resumes; a different spec into the same OUT is refused.

examples:
  vibro sweep --params params.yaml --out data/sweep --metrics metrics/sweep.json
  vibro sweep --preset none --vary frequency_hz=10:400 --vary amplitude_n=100:3000:log \\
              --design lhs --n-points 200 --seed 1 --out data/lhs200
  vibro sweep --design grid --vary frequency_hz=50:350 --vary static_force_n=100:1400 --n-points 400 --out data/grid
  vibro sweep --params params.yaml --out data/sweep --scheduler tcp://10.0.0.5:8786
  vibro sweep --params params.yaml --out data/sweep --scheduler local:2     # throw-away 2-worker LocalCluster
  vibro sweep --params params.yaml --out /tmp/x --dry-run                   # validate and print the plan
  vibro sweep --rig my-rig.yaml --vary frequency_hz=100:450 --vary static_force_n=600:1800 --out data/my-rig
"""


def add_parser(sub) -> None:
    p = sub.add_parser(
        "sweep", help="simulate a design of parameter points into a labelled, resumable Parquet dataset",
        description="Simulate every point of a sweep (Sobol', Latin hypercube or full grid over the varied "
                    "parameters of a model) and write a labelled Parquet dataset in atomically written chunks. "
                    "Failed and non-steady runs stay in the dataset with their status and reason. An interrupted "
                    "sweep resumes where it stopped and ends with exactly the rows of an uninterrupted run. "
                    "Chunks run on local cores (threads) or on a Dask distributed cluster (--scheduler).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=EPILOG.replace("{designs}", "\n".join(f"  {k:<15} {v}" for k, v in DESIGN_MEANINGS.items())))
    p.add_argument("--params", metavar="FILE.yaml", help="read the 'sweep' section of this params file "
                   "(default: the built-in default sweep: drill, preset lab, MODELS.md section-2 ranges, sobol-boundary, "
                   "1024 points)")
    p.add_argument("--out", default="data/sweep", metavar="DIR", help="dataset directory (default: data/sweep)")
    p.add_argument("--model", help="model name (drill, indenter-metal, indenter-sandstone, ...)")
    p.add_argument("--preset", help="named parameter set of the model; 'none' for the model defaults")
    add_rig(p, "sweep")
    A.add_chain(p)
    add_set(p, ("--fix",), help="hold a parameter at a value (repeatable; added to the spec's 'fixed', over the "
                                "rig); alias --fix")
    p.add_argument("--vary", action="append", metavar="NAME=LOW:HIGH[:SCALE[:LEVELS]]",
                   help="vary a parameter (repeatable); SCALE linear (default) or log; LEVELS = grid points on "
                        "this axis. Given on the command line, --vary replaces the spec's whole 'vary' section")
    p.add_argument("--design", choices=DESIGNS, help="where the points go (see 'designs' below; default sobol-boundary)")
    p.add_argument("--boundary-fraction", type=A.finite, metavar="F",
                   help=f"sobol-boundary: share of n_points on the boundary, in [0, 1] (default {BOUNDARY_FRACTION})")
    p.add_argument("--n-points", type=A.n_points, help="number of points (> 0)")
    p.add_argument("--seed", type=A.seed, help="seed of the design (same seed -> same dataset)")
    p.add_argument("--setting", dest="settings", action="append", metavar="NAME=VALUE",
                   help="simulation setting (repeatable), e.g. --setting window=16 or --setting method=dopri5; "
                        "part of the spec")
    p.add_argument("--chunk-size", type=A.n_points, help="points per chunk file (default 64); keep it when resuming")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the chunks on an existing Dask distributed cluster (tcp://host:port), or on a "
                        "throw-away LocalCluster with local:N (N single-threaded worker processes)")
    add_workers(p, help="local threads (default: all cores)")
    p.add_argument("--metrics", metavar="FILE.json",
                   help="write counts per status, n_points, wall time and sims/s to this JSON file")
    p.add_argument("--plot", metavar="FILE.png",
                   help="overview figure (ROP over the first two varied parameters, statuses marked); "
                        "by default written to a temporary file and only logged to MLflow")
    p.add_argument("--overwrite", action="store_true",
                   help="discard an existing dataset in --out and start afresh (never files a sweep did not "
                        "write); also replace --metrics / --plot files vibro did not write")
    p.add_argument("--dry-run", action="store_true", help="validate the spec and print the plan; write nothing")
    add_quiet(p)
    p.add_argument("--no-mlflow", action="store_true", help="do not log the run to MLflow")
    p.set_defaults(func=run)


def _parse_vary(items: list[str]) -> dict[str, dict]:
    out: dict[str, dict] = {}
    for item in items:
        name, eq, rest = item.partition("=")
        parts = rest.split(":")
        if not eq or not name.strip() or len(parts) < 2 or len(parts) > 4:
            raise UserError(f"--vary expects NAME=LOW:HIGH[:SCALE[:LEVELS]], got '{item}'")
        entry: dict = {}
        for key, raw in zip(("low", "high"), parts[:2]):
            entry[key] = number(raw, f"--vary {name}: {key}")
        if len(parts) >= 3 and parts[2]:
            entry["scale"] = parts[2]
        if len(parts) == 4:
            entry["levels"] = number(parts[3], f"--vary {name}: levels", integer=True, lo=1, hi=A.MAX_POINTS)
        out[name.strip()] = entry
    return out


def spec_from_args(args):
    """The validated SweepSpec and execution options (scheduler, workers) from params file + flags."""
    from pipeline.core.params import read_section
    from pipeline.datasets.spec import default_spec_dict, make_spec

    raw = read_section(args.params, "sweep", section_required=True) if args.params else default_spec_dict()
    raw = dict(raw)
    scheduler = args.scheduler or raw.pop("scheduler", None)
    raw.pop("scheduler", None)
    if scheduler is not None:
        from pipeline.core.dask_client import check_address

        scheduler = check_address(scheduler, "--scheduler" if args.scheduler else f"{args.params}: sweep.scheduler")
    workers = args.workers if args.workers is not None else raw.pop("workers", None)
    raw.pop("workers", None)
    if workers is not None:
        workers = number(workers, "--workers" if args.workers is not None else "sweep.workers", integer=True, lo=1,
                         hi=A.MAX_THREADS)
    where = f"{args.params}: sweep" if args.params else "sweep"
    for key, hi in (("n_points", A.MAX_POINTS), ("chunk_size", A.MAX_POINTS), ("seed", 2**32 - 1)):
        if raw.get(key) is not None:
            raw[key] = number(raw[key], f"{where}.{key}", integer=True, lo=0 if key == "seed" else 1, hi=hi)
    if raw.get("settings") is not None:
        raw["settings"] = check_settings(raw["settings"], f"{where}.settings")
    rig_path = args.rig or raw.pop("rig", None)
    raw.pop("rig", None)
    rig = load_rig(rig_path, args.model, args.preset)
    args.rig = rig_path
    own = dict(raw.get("fixed") or {}) if isinstance(raw.get("fixed"), dict) else {}   # the user's, not the rig's
    if rig is not None:            # the rig's model, preset, parameters and effects; 'fixed' and --set on top
        raw["model"], raw["preset"] = rig.model, rig.preset
        raw["fixed"] = {**rig.overrides(), **(raw.get("fixed") or {})}
    if args.sets:
        sets = parse_assignments(args.sets, "--set")
        own.update(sets)
        raw["fixed"] = {**(raw.get("fixed") or {}), **sets}
    if args.vary:
        raw["vary"] = _parse_vary(args.vary)
    if args.settings:
        raw["settings"] = {**(raw.get("settings") or {}), **parse_settings(args.settings)}
    if args.boundary_fraction is not None and not 0.0 <= args.boundary_fraction <= 1.0:
        raise UserError(f"--boundary-fraction must be in [0, 1] (a share of n_points), got {args.boundary_fraction:g}")
    spec = make_spec(raw, model=None if rig else args.model, preset=None if rig else args.preset, design=args.design,
                     boundary_fraction=args.boundary_fraction, n_points=args.n_points,
                     seed=args.seed, chunk_size=args.chunk_size)
    # before any work (--dry-run too): the user's values and ranges outside what the model was validated on
    A.warn_out_of_range(spec.model, spec.preset, {**{k: spec.fixed[k] for k in own if k in spec.fixed},
                                                  **{k: (r.low, r.high) for k, r in spec.vary.items()}})
    return spec, scheduler, workers


def run(args) -> int:
    from pipeline import tracking
    from vibrobase.files import atomic_write_json
    from pipeline.datasets.workflow import SweepJob, plan_lines, run_sweep_job

    from pipeline.core.outdir import check_out_file, figure_path, record_out_file

    if not str(args.out).strip():
        raise UserError("--out is empty; give the dataset folder")
    spec, scheduler, workers = spec_from_args(args)
    if args.plot is not None:
        args.plot = str(check_out_file(figure_path(args.plot), flag="--plot", kind="figure",
                                       inputs=[args.params, args.rig, args.out, args.metrics],
                                       overwrite=args.overwrite))
    if args.metrics is not None:
        check_out_file(args.metrics, flag="--metrics", kind="json",
                       inputs=[args.params, args.rig, args.out, args.plot], overwrite=args.overwrite)
    if args.dry_run:
        print("\n".join(plan_lines(spec, args.out)))
        return 0
    if scheduler is not None and not scheduler.startswith("local:"):
        from pipeline.core.dask_client import probe

        probe(scheduler)            # an unreachable scheduler is refused before --out is created
    params = {"model": spec.model, "preset": spec.preset, "rig": args.rig or "", "design": spec.design, "n_points": spec.n_points,
              "seed": spec.seed, "chunk_size": spec.chunk_size, "fingerprint": spec.fingerprint,
              **({"boundary_fraction": spec.boundary_fraction} if spec.boundary_fraction is not None else {}),
              "scheduler": scheduler or "local", "out": args.out,
              **{f"vary.{k}": f"{r.low:g}:{r.high:g}:{r.scale}" for k, r in spec.vary.items()},
              **{f"fixed.{k}": v for k, v in spec.fixed.items()},
              **{f"settings.{k}": v for k, v in spec.settings.items()}}
    with tracking.chain(A.chain_of(args), rig_name(args.rig)), tracking.run("sweep", params, enabled=not args.no_mlflow) as mlflow, \
            tempfile.TemporaryDirectory(prefix="vibro-sweep-") as tmpdir:
        plot = Path(args.plot) if args.plot else (Path(tmpdir) / "sweep_overview.png" if mlflow is not None else None)
        job = SweepJob(spec=spec, out=Path(args.out), scheduler=scheduler, workers=workers,
                       overwrite=args.overwrite, plot=plot)
        res = run_sweep_job(job, progress=not args.quiet)
        summary = res.summary
        if args.plot and res.plot is not None:
            record_out_file(res.plot, command="sweep", kind="figure")
        print("\n".join(summary.lines()))
        if args.plot and res.plot is None:      # the figure is ROP over two varied parameters
            print(f"no overview figure written to {args.plot}: it needs two varied parameters, this sweep varies "
                  f"only {', '.join(spec.vary)}")
        if args.metrics:
            atomic_write_json(Path(args.metrics), summary.metrics())
            record_out_file(args.metrics, command="sweep", kind="json")
        if mlflow is not None:
            if res.plot is not None:
                mlflow.log_artifact(str(res.plot))
            m = summary.metrics()
            mlflow.log_metrics({"n_points": m["n_points"], "computed": m["computed"], "reused": m["reused"],
                                "wall_time_s": m["wall_time_s"], "sims_per_s": m["sims_per_s"] or 0.0,
                                **{f"count_{k}": v for k, v in m["status_counts"].items()}})
            mlflow.log_artifact(str(Path(args.out) / "metadata.json"))
    return 0
