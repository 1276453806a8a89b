"""``vibro map``: Peterka maps, ROP maps and bifurcation diagrams (PNG + Parquet of the labels)."""
from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.cli.args import (add_quiet, add_rig, add_set, add_workers, check_workers, count, finite,
                               model_and_overrides, parse_assignments, parse_settings)
from pipeline.core.errors import UserError
from pipeline.core.rigfile import rig_name

KINDS = ("auto", "peterka", "rop", "label", "bifurcation")

EPILOG = """\
kinds (--kind auto picks: no --y -> bifurcation; pendulum/rimd -> peterka; drill/indenter-* -> rop):
  peterka      each cell classified: no impact, z=1/1, z=1/2, other periodic (k/n: k impacts per n
               cycles), non-periodic; second panel coloured by --color (default peak_force_n)
  rop          --color (default rop_m_s) over progressing cells; non-progressing, runaway, not-settled
               and failed regions drawn as flat colours
  label        like rop but colours any label over every cell that has a value
  bifurcation  continuation sweep of --x (each point starts from the previous final state), --direction
               up, down or both; stroboscopic samples of the impacting mass and peak force per point

outputs: OUT.png and OUT.parquet (one row per cell, or per sweep point; bifurcation also writes
OUT.strobe.parquet with one row per recorded cycle).  Default OUT: maps/<model>_<kind>_<x>[_<y>].

examples:
  vibro map pendulum --x frequency_hz --y gap_m                         # Peterka map, 40 x 40, 1-10 Hz x 0-3 mm
  vibro map pendulum --x frequency_hz --nx 100 --y gap_m --ny 100 --out maps/pendulum_peterka_100
  vibro map rimd --x frequency_hz=3:12 --y gap_m=0:0.003                # axis ranges as NAME=LO:HI
  vibro map --rig my-rig.yaml --x frequency_hz --y static_force_n --set amplitude_n=2250   # your own rig
  vibro map rimd --x frequency_hz --x-range 4 10 --nx 49 --set gap_m=0.001 --direction both   # bifurcation
  vibro map drill --preset lab --x frequency_hz --y amplitude_n --set static_force_n=1200
  vibro map drill --preset lab --x frequency_hz --y static_force_n --set amplitude_n=2250
  vibro map indenter-sandstone --x frequency_hz --y amplitude_n --set static_force_n=199
"""


def add_parser(sub) -> None:
    p = sub.add_parser(
        "map", help="response maps: Peterka map, ROP map, bifurcation diagram (PNG + Parquet)",
        description="Map the response of MODEL over one or two parameters with sim.simulate_batch (threads) "
                    "and save a PNG figure plus a Parquet table of every cell's labels (MODELS.md §5) and its "
                    "impact-pattern class.  With --y: a 2-D grid of cells, each simulated from rest.  Without "
                    "--y: a bifurcation diagram along --x, each point continued from the previous point's "
                    "final state, swept up and/or down to show coexisting attractors and jumps.",
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG)
    p.add_argument("model", nargs="?", help="drill | indenter-metal | indenter-sandstone | pendulum | rimd "
                                            "(optional with --rig)")
    p.add_argument("--x", required=True, metavar="PARAM[=LO:HI]",
                   help="parameter on the horizontal axis, optionally with its range in SI units (e.g. "
                        "frequency_hz=3:12; default range per model, ModelSpec.map_ranges; drill forces are "
                        "multiples of Pr)")
    p.add_argument("--x-range", nargs=2, type=finite, metavar=("LO", "HI"), help="range of --x (older spelling of "
                                                                                  "--x PARAM=LO:HI)")
    p.add_argument("--nx", type=count(1, 10_000), default=40, help="number of --x values (default 40)")
    p.add_argument("--y", metavar="PARAM[=LO:HI]",
                   help="parameter on the vertical axis, optionally with its range (omit for a bifurcation diagram)")
    p.add_argument("--y-range", nargs=2, type=finite, metavar=("LO", "HI"), help="range of --y (older spelling of "
                                                                                  "--y PARAM=LO:HI)")
    p.add_argument("--ny", type=count(1, 10_000), default=40, help="number of --y values (default 40)")
    p.add_argument("--log-x", action="store_true", help="geometric spacing of --x values")
    p.add_argument("--log-y", action="store_true", help="geometric spacing of --y values")
    p.add_argument("--color", metavar="LABEL",
                   help="label that colours the map: peak_force_n (Peterka default), rop_m_s (ROP default), "
                        "mean_peak_force_n, impacts_per_cycle, period, peak_decel_g, energy_per_cycle_j, "
                        "specific_energy_j_m")
    p.add_argument("--kind", choices=KINDS, default="auto", help="kind of map (default auto, see below)")
    p.add_argument("--direction", choices=("up", "down", "both"), default="both",
                   help="bifurcation sweep direction (default both)")
    p.add_argument("--preset", help="named parameter set of the model (see 'vibro models MODEL')")
    add_rig(p, "map")
    add_set(p, help="fix another parameter (repeatable; over the rig), e.g. --set static_force_n=700")
    p.add_argument("--setting", dest="settings", action="append", metavar="NAME=VALUE",
                   help="simulator setting (repeatable): rtol, min_transient, max_transient, window, period_tol, "
                        "settle_tol, max_steps_per_cycle, max_steps, event_tol, max_step_frac, stat_tol, "
                        "method = auto | exact | dopri5")
    add_workers(p, dest="threads", help="worker threads (default: all cores)")
    p.add_argument("--out", metavar="PREFIX", help="output prefix: writes PREFIX.png and PREFIX.parquet")
    p.add_argument("--overwrite", action="store_true",
                   help="replace existing PREFIX.png / PREFIX.parquet files vibro did not write (only a figure / "
                        "a Parquet file)")
    p.add_argument("--no-mlflow", action="store_true", help="do not log the run to MLflow")
    add_quiet(p)
    p.set_defaults(func=run)


def _settings(items):
    s = parse_settings(items) or None
    return s


def _axis(value: str | None, legacy, flag: str) -> tuple[str | None, tuple]:
    """``NAME`` or ``NAME=LO:HI`` of --x/--y -> (name, (lo, hi) or (None, None)); --x-range/--y-range as fallback."""
    if value is None:
        return None, (None, None)
    name, eq, rest = value.partition("=")
    if not eq:
        return value, tuple(legacy) if legacy else (None, None)
    lo_s, colon, hi_s = rest.partition(":")
    try:
        if not colon:
            raise ValueError
        return name.strip(), (float(lo_s), float(hi_s))
    except ValueError:
        raise UserError(f"{flag} expects PARAM or PARAM=LO:HI, got '{value}'") from None


def resolve_kind(model: str, kind: str, has_y: bool) -> str:
    from pipeline.maps import compute as M

    if kind == "auto":
        if not has_y:
            return "bifurcation"
        return M.default_kind(model)
    if kind == "bifurcation" and has_y:
        raise UserError("--kind bifurcation sweeps one parameter: drop --y")
    if kind != "bifurcation" and not has_y:
        raise UserError(f"--kind {kind} needs --y PARAM (a 2-D grid)")
    return kind


def run(args) -> int:
    import sim

    from pipeline.cli.args import MAX_POINTS

    if args.y and args.nx * args.ny > MAX_POINTS:
        raise UserError(f"--nx x --ny = {args.nx * args.ny} points, more than the bound {MAX_POINTS}")

    from pipeline.maps import compute as M
    from pipeline.maps.workflow import MapConfig, run_map
    from pipeline import tracking
    from pipeline.core.outdir import check_out_file, check_out_prefix, record_out_file

    args.x, xr = _axis(args.x, args.x_range, "--x")
    args.y, yr = _axis(args.y, args.y_range, "--y")
    args.model, args.preset, fixed = model_and_overrides(args.model, args.preset, args.rig,
                                                         parse_assignments(args.sets))
    spec = sim.get_model(args.model)
    kind = resolve_kind(args.model, args.kind, bool(args.y))
    if args.y and args.x == args.y:
        raise UserError(f"--x and --y must be different parameters (both are '{args.x}')")
    settings = _settings(args.settings)
    check_workers(args.threads)
    color = args.color or ("rop_m_s" if kind in ("rop", "label") else "peak_force_n")
    if color not in sim.LABELS:
        raise UserError(f"--color '{color}' is not a label; known: {', '.join(sim.LABELS)}")
    base = spec.resolve(args.preset, **{k: v for k, v in fixed.items() if k not in (args.x, args.y)})
    xs = M.axis_values(args.model, args.x, xr[0], xr[1], args.nx, args.log_x, base)
    ys = None
    if args.y:
        ys = M.axis_values(args.model, args.y, yr[0], yr[1], args.ny, args.log_y, base)
    out = Path(args.out or f"maps/{args.model}_{kind}_{args.x}" + (f"_{args.y}" if args.y else ""))
    if args.out is not None:
        out = check_out_prefix(args.out)
    # validate the fixed parameters and settings before anything runs
    spec.resolve(args.preset, **{**fixed, args.x: float(xs[0]), **({args.y: float(ys[0])} if args.y else {})})
    sim.api.make_settings(spec, settings)
    params = {"model": args.model, "kind": kind, "x": args.x, "x_lo": xs[0], "x_hi": xs[-1], "nx": xs.size,
              "y": args.y or "", "ny": 0 if ys is None else ys.size, "color": color, "preset": args.preset or "", "rig": args.rig or "",
              **{f"set.{k}": v for k, v in fixed.items()}, **{f"setting.{k}": v for k, v in (settings or {}).items()}}
    cfg = MapConfig(model=args.model, kind=kind, x=args.x, xs=xs, out=out, y=args.y, ys=ys, color=color,
                    direction=args.direction, preset=args.preset, fixed=fixed, settings=settings,
                    threads=args.threads)
    written = [(cfg.png, "figure"), (cfg.parquet, "parquet")]
    if kind == "bifurcation":
        written.append((out.with_name(out.name + ".strobe.parquet"), "parquet"))
    for path, file_kind in written:
        check_out_file(path, flag="--out", kind=file_kind, inputs=[args.rig], overwrite=args.overwrite)
    with tracking.chain("corrected" if args.rig else "lab", rig_name(args.rig)), \
            tracking.run("map", params, enabled=not args.no_mlflow) as mlflow:
        res = run_map(cfg, progress=not args.quiet)
        for path, file_kind in written:
            if Path(path) in map(Path, res.files):
                record_out_file(path, command="map", kind=file_kind)
        if mlflow is not None:
            mlflow.log_metric("wall_s", res.wall_s)
            mlflow.log_metric("n_points", len(res.table))
            for name, c in res.counts.items():
                mlflow.log_metric(f"n_{name.replace(' ', '_').replace('=', '').replace('/', '_')}", c)
            for f in res.files:
                mlflow.log_artifact(str(f))
    print(f"{len(res.table)} points in {res.wall_s:.1f} s; impact patterns: "
          + ", ".join(f"{k} {v}" for k, v in sorted(res.counts.items())))
    for f in res.files:
        print(f"wrote {f}")
    return 0
