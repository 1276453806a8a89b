"""``vibro synth``: write a measured-format dataset (MODELS.md §7) from the simulator."""
from __future__ import annotations

import argparse

from pipeline.cli import args as A
from pipeline.cli.args import add_quiet, add_workers, check_workers
from pipeline.core.errors import UserError

EPILOG = """\
systems: indenter-metal, indenter-sandstone, drill, pendulum, rimd.  Each has rig defaults (the ModelSpec.synth field in sim/models/):
  drill: preset lab, 8 frequencies 150-430 Hz x static force 900 / 1500 N, 25.6 kHz DAQ, 28.3-cycle records logged
  0.15-0.6 s after the start from rest (record_start_s), two summary-only runs, every 5th run without force_n.
effects (MODELS.md §6): shaker_coil (tau, beta), rate_stiffening (alpha), guide_friction (mu), tip_blunting (gamma),
  suspension_hardening (kappa), sensor_lowpass (fc) -- those of the system.  --effect NAME uses the default
  strength (pipeline/synthesis/workflow.py effect_defaults); --effect PARAM=VALUE sets one.
outside physics (for testing an 'unexplained' diagnosis):
  mount_resonance  accelerometer on a resonant mount (--outside-param fr_hz=... --outside-param zeta=0.1)
  contact_hertz    metal only: elastic Hertzian contact kh (x1-G)^1.5 (--outside-param kh=3e8)
output: DIR/runs.csv, DIR/series/<run_id>.csv, DIR/summary.csv (summary-only runs), DIR/README.md, written
  atomically; the truth goes to --truth FILE (default DIR.truth.json next to DIR; the diagnosis never reads it).
examples:
  vibro synth --out data/synth-metal-coil --system indenter-metal --effect shaker_coil
  vibro synth --out data/drill-blunt --system drill --effect tip_blunting
  vibro synth --out measured/drill-rig-synth --system drill --truth measured/truth/drill-rig-synth.json
  vibro synth --out data/pend-control --system pendulum --seed 3
  vibro synth --out data/synth-outside --system indenter-metal --outside mount_resonance
  vibro diagnose data/drill-blunt --out results/diag-drill-blunt"""


def add_parser(sub) -> None:
    p = sub.add_parser("synth", help="write a synthetic measured dataset (any system, §6 effect, noise, DAQ sampling)",
                       description="Generate a measured-format dataset (MODELS.md §7) from the simulator, recorded "
                                   "as a rig records it (DAQ rate, partial cycles, offsets, optional records from "
                                   "rest, summary-only runs): the calibratable parameters (MODELS.md §6) perturbed "
                                   "log-normally, optionally a §6 effect switched on or physics outside the library.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, metavar="DIR", help="dataset directory to write")
    p.add_argument("--truth", metavar="FILE.json", help="where to write the truth [DIR.truth.json]")
    p.add_argument("--system", default="indenter-metal", help="indenter-metal | indenter-sandstone | drill | "
                                                              "pendulum | rimd [indenter-metal]")
    p.add_argument("--effect", action="append", metavar="NAME|PARAM=VALUE", help="switch on a §6 effect (repeatable)")
    p.add_argument("--outside", help="physics outside the library: mount_resonance | contact_hertz")
    p.add_argument("--outside-param", action="append", metavar="NAME=VALUE", help="parameter of --outside")
    p.add_argument("--frequencies", type=A.positive, nargs="+", metavar="HZ", help="forcing frequencies [rig default]")
    p.add_argument("--levels", "--pressures", dest="levels", type=A.nonnegative, nargs="+", metavar="X",
                   help="second control: indenter pressure [bar], drill static force [N], pendulum gap [m], "
                        "rimd amplitude [N] [rig default]")
    p.add_argument("--perturb", type=A.arg_type(lo=0.0, hi=5.0), default=0.3, help="log-normal sd of the calibratable parameters [0.3]")
    p.add_argument("--seed", type=A.seed, default=0, help="random seed (parameters, noise, offsets) [0]")
    p.add_argument("--cycles", type=A.arg_type(lo=2.0, hi=10_000.0), help="recorded forcing cycles per run, need not be whole [rig default]")
    p.add_argument("--fs", type=A.arg_type(lo=0.0, lo_open=True, hi=1e7), help="DAQ sample rate, Hz [rig default: 20000 indenter, 25600 drill, 10000]")
    p.add_argument("--record-start", type=A.nonnegative, nargs="*", metavar="S",
                   help="record_start_s values cycled over the runs (records from rest); none given = steady state "
                        "[rig default]")
    p.add_argument("--summary-runs", type=A.count(0, 10_000), help="runs logged as summary.csv rows only [rig default]")
    p.add_argument("--signals", nargs="+", metavar="SIGNAL",
                   help="recorded signals (accel_m_s2 force_n disp_m progression_m) [rig default]")
    p.add_argument("--noise-accel", type=A.arg_type(lo=0.0, hi=10.0), default=0.03, help="accel noise sd / signal sd [0.03]")
    p.add_argument("--noise-force", type=A.arg_type(lo=0.0, hi=10.0), default=0.02, help="force noise sd / signal sd [0.02]")
    add_workers(p, dest="threads", help="simulation threads (default: all cores)")
    add_quiet(p)
    A.add_overwrite(p, "synthetic dataset")
    p.set_defaults(func=run)


MAX_RECORD_SAMPLES = 10_000_000
"""Samples in one run's record (cycles / f x DAQ rate): a bound on the memory asked for (80 MB per signal)."""


def check_record_size(cfg) -> None:
    """UserError when the lowest frequency's record would hold more than MAX_RECORD_SAMPLES samples."""
    r = cfg.resolved()
    f = min(r.frequencies_hz)
    n = r.cycles / f * r.fs_hz
    if n > MAX_RECORD_SAMPLES:
        raise UserError(f"--frequencies {f:g}: a record of {r.cycles:g} cycles at {r.fs_hz:g} Hz holds {n:.3g} samples, "
                        f"more than the bound {MAX_RECORD_SAMPLES:.0e}; raise the frequency or lower --cycles / --fs")


def run(args) -> int:
    from pipeline.cli.args import parse_assignments
    from pipeline.datasets.measured import write_dataset
    from pipeline.synthesis.workflow import SynthConfig, resolve_effects, synthesize
    from pathlib import Path

    from vibrobase.files import atomic_write_json

    effects: dict = {}
    for item in args.effect or []:
        if "=" in item:
            effects.update(parse_assignments([item], "--effect"))
        else:
            effects[item] = None
    if args.perturb < 0 or (args.cycles is not None and args.cycles < 2.5) or (args.fs is not None and args.fs <= 0):
        raise UserError("--perturb must be >= 0, --cycles >= 2.5 and --fs > 0")
    if args.summary_runs is not None and args.summary_runs < 0:
        raise UserError("--summary-runs must be >= 0")
    cfg = SynthConfig(system=args.system, effects=resolve_effects(args.system, effects) if effects else {},
                      outside=args.outside, outside_params=parse_assignments(args.outside_param, "--outside-param"),
                      perturb=args.perturb, seed=args.seed, cycles=args.cycles, fs_hz=args.fs,
                      frequencies_hz=tuple(args.frequencies) if args.frequencies else None,
                      levels=tuple(args.levels) if args.levels else None,
                      record_start_s=None if args.record_start is None else tuple(args.record_start),
                      summary_runs=args.summary_runs, signals=tuple(args.signals) if args.signals else None,
                      noise_accel=args.noise_accel, noise_force=args.noise_force, n_threads=check_workers(args.threads))
    if any(f <= 0 for f in cfg.frequencies_hz or ()) or any(x < 0 for x in cfg.record_start_s or ()):
        raise UserError("--frequencies must be > 0 and --record-start >= 0")
    check_record_size(cfg)
    from pipeline.core.outdir import check_out, check_out_file, prepare_out, record_out_file

    truth = Path(args.truth) if args.truth else Path(str(Path(args.out)).rstrip("/") + ".truth.json")
    check_out(args.out, inputs=[truth], overwrite=args.overwrite, marker="synth")   # before the simulations, not after
    check_out_file(truth, flag="--truth", kind="json", inputs=[args.out], overwrite=args.overwrite)
    ds, info = synthesize(cfg, progress=not args.quiet)
    with prepare_out(args.out, inputs=[truth], overwrite=args.overwrite, marker="synth") as tmp:
        write_dataset(ds, tmp)
    atomic_write_json(truth, info)
    record_out_file(truth, command="synth", kind="json")
    print(f"wrote {len(ds.runs)} runs to {args.out} (truth: {truth})")
    return 0
