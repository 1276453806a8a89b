"""``vibro synth``: write a measured-format dataset (MODELS.md §7) from the simulator."""
from __future__ import annotations

import argparse

from pipeline.cli import args as A
from pipeline.cli.args import add_quiet, add_workers, check_workers
from pipeline.core.errors import UserError

EPILOG = """\
effects (MODELS.md §6): shaker_coil (tau, beta), rate_stiffening (alpha), guide_friction (mu),
  tip_blunting (gamma; sandstone), suspension_hardening (kappa), sensor_lowpass (fc).
  --effect NAME uses the default strength (pipeline/synth.py EFFECT_DEFAULTS); --effect PARAM=VALUE sets one.
outside physics (for testing an 'unexplained' diagnosis):
  mount_resonance  accelerometer on a resonant mount (--outside-param fr_hz=450 --outside-param zeta=0.1)
  contact_hertz    metal only: elastic Hertzian contact kh (x1-G)^1.5 (--outside-param kh=3e8)
output: DIR/runs.csv, DIR/series/<run_id>.csv (t_s, accel_m_s2, force_n, disp_m[, progression_m]),
  DIR/truth.json (true parameters; the diagnosis does not read it), DIR/README.md.  Written atomically.
examples:
  vibro synth --out data/synth-metal-coil --system indenter-metal --effect shaker_coil
  vibro synth --out data/synth-sand-blunt --system indenter-sandstone --effect gamma=0.03 --signals accel_m_s2 force_n progression_m
  vibro synth --out data/synth-control --system indenter-metal --seed 3
  vibro synth --out data/synth-outside --system indenter-metal --outside mount_resonance
  vibro diagnose data/synth-metal-coil --out results/diag-coil"""


def add_parser(sub) -> None:
    p = sub.add_parser("synth", help="write a synthetic measured dataset (any §6 effect, perturbed parameters, noise)",
                       description="Generate a measured-format dataset (MODELS.md §7) from the indenter simulator: "
                                   "the calibratable parameters (MODELS.md §1) perturbed log-normally, optionally "
                                   "a §6 effect switched on or physics outside the library, and realistic sensor "
                                   "noise and offsets.  One run per frequency x pressure (Table 1 forcing).",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, metavar="DIR", help="dataset directory to write")
    p.add_argument("--system", default="indenter-metal", help="indenter-metal | indenter-sandstone [indenter-metal]")
    p.add_argument("--effect", action="append", metavar="NAME|PARAM=VALUE", help="switch on a §6 effect (repeatable)")
    p.add_argument("--outside", help="physics outside the library: mount_resonance | contact_hertz")
    p.add_argument("--outside-param", action="append", metavar="NAME=VALUE", help="parameter of --outside")
    p.add_argument("--frequencies", type=A.positive, nargs="+", metavar="HZ",
                   help="forcing frequencies [Table 1: 30 40 ... 100]; amplitude from Table 1 (interpolated)")
    p.add_argument("--pressures", type=A.positive, nargs="+", metavar="BAR", help="pneumatic pressures [1.0 1.5]")
    p.add_argument("--perturb", type=A.arg_type(lo=0.0, hi=5.0), default=0.3, help="log-normal sd of the calibratable parameters [0.3]")
    p.add_argument("--seed", type=A.seed, default=0, help="random seed (parameters, noise, offsets) [0]")
    p.add_argument("--cycles", type=A.count(4, 10_000), default=40, help="recorded forcing cycles per run [40]")
    p.add_argument("--fs", type=A.arg_type(lo=0.0, lo_open=True, hi=1e7), default=20000.0, help="approximate sample rate, Hz [20000]")
    p.add_argument("--signals", nargs="+", metavar="SIGNAL",
                   help="recorded signals [accel_m_s2 force_n disp_m]; progression_m also possible")
    p.add_argument("--noise-accel", type=A.arg_type(lo=0.0, hi=10.0), default=0.03, help="accel noise sd / signal sd [0.03]")
    p.add_argument("--noise-force", type=A.arg_type(lo=0.0, hi=10.0), default=0.02, help="force noise sd / signal sd [0.02]")
    add_workers(p, dest="threads", help="simulation threads (default: all cores)")
    add_quiet(p)
    A.add_overwrite(p, "synthetic dataset")
    p.set_defaults(func=run)


def run(args) -> int:
    from pipeline.cli.args import parse_assignments
    from pipeline.datasets.measured import write_dataset
    from pipeline.datasets.synth import SynthConfig, resolve_effects, synthesize

    effects: dict = {}
    for item in args.effect or []:
        if "=" in item:
            effects.update(parse_assignments([item], "--effect"))
        else:
            effects[item] = None
    if args.perturb < 0 or args.cycles < 4 or args.fs <= 0:
        raise UserError("--perturb must be >= 0, --cycles >= 4 and --fs > 0")
    cfg = SynthConfig(system=args.system, effects=resolve_effects(args.system, effects) if effects else {},
                      outside=args.outside, outside_params=parse_assignments(args.outside_param, "--outside-param"),
                      perturb=args.perturb, seed=args.seed, cycles=args.cycles, fs_hz=args.fs,
                      noise_accel=args.noise_accel, noise_force=args.noise_force, n_threads=check_workers(args.threads))
    if args.frequencies:
        cfg.frequencies_hz = tuple(args.frequencies)
    if args.pressures:
        cfg.pressures_bar = tuple(args.pressures)
    if args.signals:
        cfg.signals = tuple(args.signals)
    if any(f <= 0 for f in cfg.frequencies_hz) or any(p <= 0 for p in cfg.pressures_bar):
        raise UserError("--frequencies and --pressures must be > 0")
    from pipeline.core.outdir import check_out, prepare_out

    check_out(args.out, overwrite=args.overwrite, marker="synth")     # before the simulations, not after
    ds, info = synthesize(cfg, progress=not args.quiet)
    with prepare_out(args.out, overwrite=args.overwrite, marker="synth") as tmp:
        write_dataset(ds, tmp)
    print(f"wrote {len(ds.runs)} runs to {args.out} (truth: {info['truth']})")
    return 0
