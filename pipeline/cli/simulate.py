"""``vibro simulate``: one parameter point, labels as a table or JSON, optional plot."""
from __future__ import annotations

import argparse

from pipeline.cli.args import (add_rig, add_set, model_and_overrides, parse_assignments, parse_settings,
                               warn_out_of_range)
from vibrobase.jsonable import dump_json


def add_parser(sub) -> None:
    p = sub.add_parser(
        "simulate", help="simulate one parameter point and print its labels",
        description="Simulate one parameter point of MODEL to a labelled steady state (MODELS.md §5 labels: "
                    "rop_m_s, peak_force_n, mean_peak_force_n, impacts_per_cycle, period, peak_decel_g, "
                    "energy_per_cycle_j, specific_energy_j_m, status, reason).  Runs on the ahead-of-time "
                    "compiled kernel built by 'vibro compile' (run by 'make install'; about 0.2 s of CPU in all) "
                    "and, when that is missing or older than the sources, on numba's JIT kernel (about 1 s more "
                    "to load; 30-70 s to compile the first time); both give the same labels bit for bit.  "
                    "VIBRO_NO_AOT=1 forces the JIT kernel.\n\n"
                    "Exit status: 0 when the point was simulated, whatever its status (ok, no_contact, runaway, failed, "
                    "...: the status is a result, printed with its reason); 2 for a user error (a bad value, file or "
                    "flag, named in one line); 1 only for a bug in vibro.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  vibro simulate drill --preset lab --set frequency_hz=120 --set amplitude_n=800\n"
               "  vibro simulate indenter-metal --preset table1-60hz --json\n"
               "  vibro simulate drill --preset lab --setting method=dopri5 --setting rtol=1e-10   # the integrator\n"
               "  vibro simulate indenter-sandstone --set frequency_hz=80 --set amplitude_n=650 --plot out.png\n"
               "  vibro simulate --rig my-rig.yaml --set frequency_hz=250   # your own rig (docs/commands.md)\n"
               "  vibro models            # lists models, presets and every parameter with its default and unit")
    p.add_argument("model", nargs="?", help="drill | indenter-metal | indenter-sandstone | pendulum | rimd "
                                            "(optional with --rig)")
    p.add_argument("--preset", help="named parameter set of the model (see 'vibro models MODEL')")
    add_rig(p)
    add_set(p)
    p.add_argument("--setting", dest="settings", action="append", metavar="NAME=VALUE",
                   help="simulator setting (repeatable): rtol, min_transient, max_transient, window, period_tol, "
                        "settle_tol, max_steps_per_cycle, max_steps (work limit of one point, steps), event_tol, "
                        "max_step_frac, stat_tol, samples_per_cycle, and method = auto | exact "
                        "| dopri5 (auto: the exact propagator where it applies -- every phase of the drill, the RIMD's free "
                        "flight, every phase of the indenters while the seal friction is +/- pm -- else the DOPRI5 "
                        "integrator)")
    p.add_argument("--json", action="store_true", help="print one JSON object whose keys are the label names")
    p.add_argument("--plot", metavar="FILE.png",
                   help="save time histories of the impacting mass and contact force over the recorded cycles, "
                        "and the acceleration spectrum (0-1000 Hz for the indenter); .png added without a suffix")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing --plot file vibro did not write (only a figure)")
    p.set_defaults(func=run)


PLOT_SAMPLES = 2**20
"""Most history samples kept for ``--plot`` (about 110 bytes each in the simulator, a few times that while plotting:
a few hundred MB at most, whatever window x samples_per_cycle asks for)."""


def plot_settings(model: str, settings: dict | None) -> tuple[dict | None, str | None]:
    """``settings`` with ``samples_per_cycle`` lowered so the plotted history holds at most :data:`PLOT_SAMPLES`
    samples (the labels do not depend on it), and the line saying so, or None when nothing changed."""
    from sim import get_model
    from sim.api import make_settings

    st = make_settings(get_model(model), settings)
    if st.window * st.samples_per_cycle <= PLOT_SAMPLES:
        return settings, None
    spc = max(2, PLOT_SAMPLES // st.window)
    return ({**(settings or {}), "samples_per_cycle": spc},
            f"plot: {spc} samples per cycle instead of {st.samples_per_cycle} (at most {PLOT_SAMPLES} samples over "
            f"the {st.window}-cycle window)")


def run(args) -> int:
    from sim import get_model, simulate

    from pipeline.core.outdir import check_out_file, figure_path, record_out_file

    sets = parse_assignments(args.sets)
    model, preset, params = model_and_overrides(args.model, args.preset, args.rig, sets)
    settings = parse_settings(args.settings) or None
    get_model(model).resolve(preset, **params)      # a value that cannot be is an error before any warning
    warn_out_of_range(model, preset, sets)
    plot = None
    if args.plot is not None:
        plot = check_out_file(figure_path(args.plot), flag="--plot", kind="figure", inputs=[args.rig],
                              overwrite=args.overwrite)
    note = None
    if plot is not None:
        settings, note = plot_settings(model, settings)
    res = simulate(model, preset=preset, settings=settings, history=plot is not None, **params)
    if args.json:
        print(dump_json(res.labels))
    else:
        width = max(len(k) for k in res.labels)
        for k, v in res.labels.items():
            if isinstance(v, float):
                v = f"{v:.6g}"
            print(f"{k:<{width}}  {v}")
    if plot is not None:
        from pipeline.report.plots import plot_time_history

        if res.history is None:
            print(f"no plot: the run ended with status {res.status} ({res.labels['reason']})")
        else:
            if note:
                print(note)
            plot_time_history(res, plot)
            record_out_file(plot, command="simulate", kind="figure")
            print(f"plot saved to {plot}")
    return 0          # a status (even failed) is a result; exit 1 is reserved for bugs
