"""``vibro diagnose``: calibrate the model against a measured dataset, find the missing effect."""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import fields
from pathlib import Path
from typing import TYPE_CHECKING

from pipeline.cli.args import add_quiet, add_workers, check_workers
from pipeline.cli import args as A
from pipeline.core.errors import UserError

if TYPE_CHECKING:
    from pipeline.diagnosis.report_types import DiagnoseReport

DESCRIPTION = """\
Diagnose a model against a measured dataset (MODELS.md §7: runs.csv, series/<run_id>.csv, summary.csv).
1. validate the dataset strictly (errors name file, line and column; nothing is written on error);
2. split the runs deterministically into calibration and held-out runs (>= min_runs_holdout runs per system:
   every holdout_every-th run held out, never two at one forcing frequency where another run can be; fewer:
   leave-one-run-out cross-validation);
3. calibrate the base model's uncertain parameters (MODELS.md §6: metal k1, c1, pm; sandstone kl, ku, pm;
   drill K1, C1, Pr; pendulum ki, ci, zeta; rimd ki, lambda_i, c1), the rig's known parameters coming from the
   runs' preset / parameter columns
   by multi-start least squares on noise-normalised features: amplitude and phase of every harmonic of the
   forcing frequency up to max_harmonic_hz of acceleration, force and displacement, the progression rate, or
   the summary features (peak_decel_g, impacts_per_cycle, rop_m_s, peak_force_n, spectral_ratio);
4. fit every §6 effect that applies to the system (shaker_coil, rate_stiffening, guide_friction, tip_blunting,
   suspension_hardening, sensor_lowpass) on top of the calibrated base model and rank them by BIC; the verdict
   (docs/diagnose.md) is "nothing missing", an effect "selected" or "unexplained", decided on held-out runs:
   a model is adequate when its held-out nrms (residual / noise estimated per signal, record and harmonic,
   with a model floor) is <= explained_nrms or its systematic error (from the two halves of every record,
   free of any noise estimate) is <= systematic_tol; a candidate is selected when it beats the base on BIC
   (bic_margin), on held-out chi2 (test_margin) and materially (half of systematic_tol of systematic error, or
   the held-out nrms cut to nrms_ratio of the base's or to the noise level), and is adequate;
5. write DIR/report.json, DIR/report.md and PNG figures (residual structure before/after, measured vs
   simulated cycle histories and spectra), and log the run to MLflow;
6. write the corrected rig DIR/rig.yaml (DIR/rig-<system>.yaml per system of a several-system dataset):
   preset, known and calibrated parameters, the selected effect with its fitted parameters and their sd
   (docs/closed-loop.md); use it with --rig in every simulating command.  An unexplained residual
   still writes the calibrated base rig, marked UNEXPLAINED in its 'source' (report.json 'rig');
7. when the residual is unexplained, propose the missing term (docs/diagnose.md "Proposing the missing
   term"): the model's discrepancy terms (contact_quadratic, contact_cubic, contact_rate_product: δ₊², δ₊³,
   δ₊ δ̇ in the contact force; tool_viscous, tool_quadratic_drag: −c v, −c v|v| on the impacting mass) are
   screened by a non-negative sparse regression of the calibrated base's residual on their sensitivities
   (scikit-learn lars_path, BIC), then up to max_proposals sets (every single term when the screening selects
   none) and the structured candidates, each fitted from a grid of its parameters: the hidden load-path mode
   (load_path_mode_ratio, _hz, _zeta: a hidden mass on a spring and damper at the impacting mass), the contact
   exponent (pendulum, metal indenter; contact_exponent_shift s: k δ → k δ_r (δ₊/δ_r)^(1+s)), the rock's rate
   strength (drill; rock_rate_strength η: Pr → Pr (1 + η ẋb)) and a loss in the impacting mass's suspension
   (drill, indenters, RIMD; link_power_loss_n c, _exponent p: c (|v|/v_r)^p sgn v), a contact that drifts
   through a run (pendulum, metal indenter; contact_drift_m_s a: x_c = G + a t) and dry friction at a support
   (pendulum pivot, RIMD clamp, indenter carriages; support_friction_n μ: μ tanh(v/v_ε)), the stop on a
   compliant mount (RIMD, metal indenter; stop_mode_ratio, _hz, _zeta), a mode in the drive (RIMD beam,
   drill exciter; drive_mode_ratio, _hz, _zeta), a face that wears with the work pressed into it (pendulum,
   metal indenter; contact_wear_m_j k_w: ṡ = k_w F_c max(v, 0), and on steady-state records
   contact_wear_before_m_j = k_w N, N the cycles run before the record) and a contact that unloads below its
   loading law (pendulum, metal indenter; contact_unloading_shift s_u: (δ/δ_m)^(1+s_u) below the peak δ_m) are
   re-fitted and judged
   on the held-out runs by the rule of step 4; a proposal is fitted only where every fold's calibration runs hold
   at least 2 measured numbers per free parameter (a summary log of a few runs fits none, and says so).
   report.json 'discrepancy' ranks them (terms in words and symbols, coefficients with sd, held-out error against
   the floor); an accepted proposal goes into the rig file as a 'discrepancy:' entry (term names and
   coefficients, never code) that every --rig command simulates in the kernel;
8. when nothing (no effect, no proposal) explains the residual, the last resort: a Gaussian process of the
   relative ROP discrepancy over the controls the runs vary, fitted on the calibration runs and scored on the
   held-out ones (report.json 'empirical'); when it cuts the held-out ROP error by empirical_gain it is refitted
   on all runs and written to the rig file as 'empirical_correction' ("empirical correction, physics unknown"),
   which optimise --simulator --rig and compare apply to the simulated ROP, its sd in the spread.
The recording is a model of its own (docs/diagnose.md "The recording chain"): optional runs.csv columns declare a
run's DAQ chain, and the model's signals pass through it before they are compared:
  daq_filter     anti-alias filter: butter:order:cutoff_hz, ellip:order:cutoff_hz[:ripple_db:stop_db] (analog
                 prototypes; ellip default 0.1 dB, 60 dB, cut-off = pass-band edge), fir:taps:cutoff_hz:oversample
                 (linear-phase decimation filter: its pure delay), or none; applied as its frequency response on
                 every harmonic (exact in steady state)
  daq_delay_s    a pure delay [s] on top of the filter (what the DAQ's alignment left); with a column
                 daq_delay_removed it is the filter's own group delay instead, and daq_delay_removed = 1 says the
                 DAQ moved the time stamps back by it (0: left in the data)
  daq_clock_ppm  sample-clock error [ppm]: sample n was taken at (1 + ppm 1e-6) n / fs while t_s says n / fs
  (delay and clock: the model is sampled at the true instants).  Where a series run declares none of them, a
  delay per channel and a clock error are estimated as nuisance parameters, profiled out of every model's fit
  (never a §6 effect; setting estimate_chain); report.json 'recording' gives them as located at the final model's
  fit, each sd at least the jackknife's over the runs (a filter makes the clock uncertain by tens of ppm:
  docs/identification.md).  Saturated samples (>= 3 identical values at a channel's extreme, flat tops or single
  samples with noisy neighbours) mark the ADC's range: the model is clipped there too, in the sensor's frame (the
  record's offset and drift against the model added), with a note; a channel saturated in more than 50 % of its
  samples is not used, a run with no usable channel is skipped and named.  Mains hum (50 or 60 Hz lines standing
  out on two runs or more) is fitted beside the forcing harmonics, and the harmonics a mains line sits on carry its
  amplitude in their sd (report.json 'recording.hum')."""

EPILOG = """\
params.yaml section 'diagnose' (all optional; defaults in brackets):
  max_harmonic_hz [per system: indenter 1000, drill 3000, pendulum 100, rimd 200]
                           harmonics of f up to this frequency are features (least squares on the record's
                           own time base: any sampling rate, any record length >= 2 cycles)
  holdout_every [4]        single split: every n-th run (sorted by static force, frequency) is held out, moved
                           to the next frequency of its level where that one is held out already
  min_runs_holdout [8]     a system with fewer runs is cross-validated leave-one-run-out
  n_starts [2]             base-model starts (defaults + seeded random points)
  grid [4]                 grid points per effect parameter for a candidate's starting point
  profile_points [2]       best grid points at which the base parameters are refitted with the effect held
  profile_nfev [3]         iterations of that refit (0: start from the grid's best point as it is)
  candidate_starts [2 indenter, 1 others]  candidate fits start from the grid's best point at the calibrated base (1) and also
                           at the default base parameters (2); with 1, the two leading candidates also start there
                           when the leader has not reached the noise level
  max_nfev [15 indenter, 10 others]  least-squares iterations per start
  diff_step [0.01]         finite-difference step in log10 of a parameter (2.3 %); every fit ends with 6
                           iterations at 0.002 (0.46 %)
  bic_margin [10]          a candidate must beat the base model's BIC by this much (calibration runs)
  test_margin [25]         ... and its held-out chi2 by this much
  explained_nrms [2]       held-out residual/noise at or below this counts as adequate ...
  systematic_tol [0.005]   ... and so does a held-out systematic error (record halves) at or below this,
  systematic_nrms_cap [4]  ... with a held-out nrms at or below this (further above the noise is a model error)
  nrms_ratio [0.5]         a candidate cutting the base's held-out nrms to this fraction gains materially
  max_effects [2]          when the best effect improves but leaves held-out nrms above pair_nrms, add each
                           other effect to it and judge the pairs against it by the same rule (report.json
                           'second_effect', and 'pair_stage': whether it ran and why; the rig file then carries
                           both); 1: one effect only
  pair_nrms [2]            the pair stage's trigger (1: also look for a weaker second effect within explained_nrms)
  max_proposals [3]        unexplained: re-fit at most this many discrepancy proposals (0: no discovery)
  empirical_gain [0.2]     still unexplained: an empirical ROP correction is adopted when it cuts the held-out
                           ROP error by this fraction (1: never)
  model_floor [0.001]      feature sd floor: this x the signal's RMS harmonic amplitude, in quadrature with
                           the noise (what two correct simulations and a rig's sampling may differ by)
  summary_floor [0.01]     summary feature sd floor: this x the value
  effects [all]            list of candidate effects to try
  fs_sim_hz [20000]        model sample rate for summary-only runs
  sim_settings [{rtol: 1e-7, window: 2, max_step_frac: 0.05}]   simulator settings while fitting (series runs are
                           sampled at the record's own instants, a window that covers the record)
  record_window [64]       a steady-state series is compared over its first this many cycles (0 = all)
  summary_sd [{}]          e.g. {peak_decel_g: [rel, 0.05], impacts_per_cycle: [abs, 0.5]}
  seed [0]                 seed of the random starts
  estimate_chain [model]   estimate an undeclared DAQ chain (delay per channel, clock) as nuisance beside every
                           fit, never as an effect (default true; the pendulum's false); false: the records are
                           taken as the rig's signals unfiltered
  antialias [auto]         true: low-pass the model below each record's Nyquist frequency before sampling it, as a
                           DAQ's anti-alias filter does the signal (an impact's content above it would fold onto
                           the harmonics); auto (unset): where runs.csv declares a filter or the undeclared chain's
                           delays show one (>= 0.5 sample, and in proportion to the sample interval where a
                           channel has two rates); false: the records are point samples of the rig
  fit_unreproducible [false]  true: also fit and judge on runs whose model response is chaotic (report
                           'unreproducible'); false: they are left out of every fold, the split kept
  scheduler [null]         Dask scheduler (tcp://host:8786) or local:N that runs the fits; null = this process
                           (--threads simulation threads); not part of the report: the numbers are the same
examples:
  vibro synth --out data/synth-coil --system indenter-metal --effect shaker_coil
  vibro diagnose data/synth-coil --out results/diagnose-coil
  vibro diagnose measured/seed000-published --out results/diagnose-seed000 --metrics results/diagnose.json
  vibro diagnose DATA --out DIR --params params.yaml --setting max_nfev=10 --effects shaker_coil sensor_lowpass
  vibro diagnose DATA --out DIR --scheduler tcp://10.0.0.5:8786     # the fits on a Dask cluster
  vibro diagnose DATA --out DIR --scheduler local:2                 # ... on a throw-away 2-worker LocalCluster"""


def add_parser(sub) -> None:
    p = sub.add_parser("diagnose", help="calibrate against measured data, find the missing effect, report errors",
                       description=DESCRIPTION, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dataset", help="measured dataset directory (MODELS.md §7)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (report.json, report.md, figures)")
    p.add_argument("--params", metavar="FILE.yaml", help="read settings from this file's 'diagnose' section")
    p.add_argument("--setting", "--set", dest="sets", action="append", metavar="KEY=VALUE",
                   help="override one 'diagnose' setting (repeatable), e.g. --setting max_nfev=10 or "
                        "--setting estimate_chain=false; "
                        "alias --set (older spelling)")
    p.add_argument("--effects", nargs="+", metavar="EFFECT", help="only try these candidate effects")
    p.add_argument("--metrics", metavar="FILE.json",
                   help="also write the headline numbers (errors, noise floor, selected effect) to this JSON file")
    add_workers(p, dest="threads", help="simulation threads of a local run (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="send the independent fits (folds x models x starts) to an existing Dask distributed "
                        "cluster (tcp://host:port), or to a throw-away LocalCluster with local:N (N single-threaded "
                        "worker processes); the report's numbers are those of a local run, bit for bit (docs/scale.md)")
    A.add_overwrite(p, "diagnosis")
    p.add_argument("--no-mlflow", action="store_true", help="do not log to MLflow")
    add_quiet(p)
    p.set_defaults(func=run)


_BOOL_WORDS = {"true": True, "false": False}
TEXT_DIAGNOSE_SETTINGS: dict[str, dict[str, bool | None]] = {
    "estimate_chain": _BOOL_WORDS, "fit_unreproducible": _BOOL_WORDS, "antialias": {**_BOOL_WORDS, "auto": None}}
"""Settings whose ``--setting`` value is text, not a number: the words each takes and their values (auto: unset)."""


def load_config(path: str | None, sets: dict, effects: list[str] | None, threads: int | None):
    """DiagnoseConfig from params.yaml's 'diagnose' section + overrides (UserError naming bad keys); numbers
    given as text or 6.0 become the config's types here, and the config checks its bounds when built."""
    from pipeline.core.params import read_section
    from pipeline.diagnosis.run import DiagnoseConfig

    values: dict = dict(read_section(path, "diagnose"))
    values.pop("scheduler", None)              # where the fits run, not how (scheduler_of)
    values.update(sets)
    if effects:
        values["effects"] = effects
    if threads:
        values["n_threads"] = threads
    return DiagnoseConfig(**typed_settings(values))


def check_setting_names(names) -> None:
    """UserError naming the first of ``names`` that is not a diagnose setting, with the closest one."""
    from pipeline.diagnosis.run import DiagnoseConfig
    from vibrobase.errors import did_you_mean

    known = [f.name for f in fields(DiagnoseConfig)]
    for k in names:
        if k not in known:
            raise UserError(f"diagnose setting '{k}' is unknown{did_you_mean(k, known)} (known: {', '.join(known)})")


def typed_settings(values: dict) -> dict:
    """``values`` (setting -> value, numbers and true/false possibly as text) with every setting of its
    DiagnoseConfig type; UserError naming an unknown setting or a bad value."""
    from pipeline.diagnosis.config import FLOAT_BOUNDS, INT_BOUNDS, ZERO_ALLOWED

    values = dict(values)
    check_setting_names(values)
    for k, v in list(values.items()):
        if k in TEXT_DIAGNOSE_SETTINGS and isinstance(v, str):
            words = TEXT_DIAGNOSE_SETTINGS[k]
            if v.strip().lower() not in words:
                *head, last = words
                raise UserError(f"diagnose setting '{k}' must be {', '.join(head)} or {last}, got {v!r}")
            values[k] = words[v.strip().lower()]
        elif k in INT_BOUNDS and v is not None:
            lo, hi = INT_BOUNDS[k]
            hi = A.MAX_THREADS if k == "n_threads" else hi
            values[k] = A.number(v, f"diagnose setting '{k}'", integer=True, lo=lo, hi=hi)
        elif k in FLOAT_BOUNDS and v is not None:
            values[k] = A.number(v, f"diagnose setting '{k}'", lo=0.0, lo_open=k not in ZERO_ALLOWED, hi=FLOAT_BOUNDS[k])
    if values.get("sim_settings") is not None:
        values["sim_settings"] = A.check_settings(values["sim_settings"], "diagnose setting 'sim_settings'")
    return values


def scheduler_of(path: str | None, flag: str | None) -> str | None:
    """The Dask scheduler of the fits: ``--scheduler``, else the params file's 'diagnose.scheduler'; None: this
    process (UserError for a value that cannot name one)."""
    from pipeline.core.dask_client import check_address
    from pipeline.core.params import read_section

    if flag is not None:
        return check_address(flag)
    value = read_section(path, "diagnose").get("scheduler")
    if value is None:
        return None
    if not isinstance(value, str):
        raise UserError(f"{path}: diagnose.scheduler must be tcp://host:port or local:N, got {value!r}")
    return check_address(value, f"{path}: diagnose.scheduler")


def run(args) -> int:
    from tqdm import tqdm

    from pipeline import tracking
    from pipeline.cli.args import parse_assignments
    from pipeline.core.executors import open_executor
    from vibrobase.files import atomic_write_text
    from vibrobase.jsonable import dump_json
    from pipeline.core.outdir import check_out_file, prepare_out, record_out_file
    from pipeline.datasets.measured import load_dataset
    from pipeline.diagnosis.workflow import diagnose
    from pipeline.diagnosis.outputs import write_outputs

    check_setting_names(item.partition("=")[0].strip() for item in args.sets or [] if "=" in item)
    sets = parse_assignments(args.sets, "--setting", words=TEXT_DIAGNOSE_SETTINGS)
    cfg = load_config(args.params, sets, args.effects, check_workers(args.threads))
    scheduler = scheduler_of(args.params, args.scheduler)
    ds = load_dataset(args.dataset)
    check_signals(ds)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out '{out}' exists and is not a directory")
    log = (lambda s: None) if args.quiet else (lambda s: tqdm.write(s, file=sys.stderr))
    from dataclasses import asdict

    inputs = [args.dataset, args.params, args.metrics]
    if args.metrics:
        check_out_file(args.metrics, flag="--metrics", kind="json", inputs=[args.dataset, args.params, out],
                       overwrite=args.overwrite)
    with open_executor(scheduler) as executor, \
            prepare_out(out, inputs=inputs, overwrite=args.overwrite, marker="diagnose") as tmp:
        bar = StageBars(disable=args.quiet)
        executor.on_task_done = bar.task_done
        with tracking.run("diagnose", {"dataset": args.dataset, **asdict(cfg), "scheduler": scheduler or "local"},
                          enabled=not args.no_mlflow, variant=Path(args.dataset).resolve().name) as mlflow:
            result = diagnose(ds, cfg, log=log, progress=bar, executor=executor)
            bar.close()
            result = write_outputs(result, tmp)
            report = result.report
            check_report(report)
            headline = report.headline()
            if mlflow is not None:
                mlflow.log_metrics({k: float(v) for k, v in _flat_metrics(report).items()})
                mlflow.set_tag("vibro.selected", json.dumps(headline["selected"]))
                mlflow.set_tag("vibro.proposal_adopted", json.dumps(headline["proposal_adopted"]))
                mlflow.log_artifacts(str(tmp), artifact_path="diagnose")
                for rig_file in sorted(Path(tmp).glob("rig*.yaml")):     # the corrected rig, also on its own
                    mlflow.log_artifact(str(rig_file), artifact_path="rig")
                mlflow.set_tag("vibro.rig_explained", str(report.explained).lower())
    if args.metrics:
        atomic_write_text(args.metrics, dump_json(headline))
        record_out_file(args.metrics, command="diagnose", kind="json")
    if not args.quiet:
        print("\n".join(summary_lines(report)))
        print(cost_line(report.cost))
        print(f"report: {out / 'report.md'}" + (f"; headline numbers: {args.metrics}" if args.metrics else ""))
    return 0


class StageBars:
    """The diagnosis's progress on stderr (``pipeline.diagnosis.progress.Progress``): one line per stage with the
    time the last one took, and a bar of its fit tasks with tqdm's estimate of the time left."""

    def __init__(self, disable: bool = False) -> None:
        self.disable, self.bar, self.k = disable, None, 0

    def stage(self, name: str, tasks: int | None = None) -> None:
        from tqdm import tqdm

        self.close()
        self.k += 1
        self.bar = tqdm(total=tasks, desc=f"[stage {self.k}] {name}", unit="fit", disable=self.disable,
                        file=sys.stderr, leave=True,
                        bar_format=None if tasks else "{desc}: {elapsed}")

    def task_done(self) -> None:
        if self.bar is not None:
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


SIGNALS_CHECKED = ("accel_m_s2", "force_n")
SUMMARY_CHECKED = ("peak_decel_g", "impacts_per_cycle", "rop_m_s", "peak_force_n", "spectral_ratio")


def check_signals(ds) -> None:
    """UserError when a run's acceleration or force series is constant (e.g. all zero): it carries no
    feature to fit, and the fit's error would be meaningless."""
    import numpy as np

    if ds.summary is not None:
        feats = ds.summary[[c for c in SUMMARY_CHECKED if c in ds.summary.columns]].to_numpy(dtype=float)
        feats = feats[np.isfinite(feats)]
        if feats.size and not np.any(feats):
            raise UserError("summary.csv: every feature (" + ", ".join(c for c in SUMMARY_CHECKED if c in ds.summary.columns)
                            + ") is zero in every run; nothing to diagnose")
    for rid, df in ds.series.items():
        for col in SIGNALS_CHECKED:
            if col in df.columns:
                v = df[col].to_numpy(dtype=float)
                if v.size and np.ptp(v) == 0:
                    raise UserError(f"series/{rid}.csv: column '{col}' is constant ({v[0]:g} in every row); "
                                    f"nothing to diagnose")


def check_report(report: DiagnoseReport) -> None:
    """UserError when the diagnosis produced no finite error (features the model cannot match at all)."""
    import math

    for key, model in (("default_error", "default"), ("base_error", "base"), ("final_error", "final")):
        for v in [getattr(s.errors, model).error for s in report.systems]:
            if v is None or not math.isfinite(float(v)) or float(v) > 1e100:   # 1e100: an overflow, not a fit
                raise UserError(f"diagnosis {key} = {v!r}: the dataset's features are degenerate "
                                f"(the model cannot be compared with them); check the measured signals")


VERDICT_WORDS = {"nothing missing": "nothing missing (the calibrated base model is adequate)",
                 "unexplained": "unexplained (no §6 effect brings the model to the data)"}


def summary_lines(report: DiagnoseReport) -> list[str]:
    """A few lines per system for the terminal: the verdict, the held-out nrms before/after, error and noise floor
    (report.md has the tables, report.json every number)."""
    lines = []
    for r in report.systems:
        e = r.errors
        verdict = f"{'+'.join(r.selected)} selected" if r.selected else VERDICT_WORDS.get(r.verdict, r.verdict)
        if r.proposal_adopted:
            verdict += f"; adopted discrepancy term {' + '.join(r.proposal_adopted)}"
        lines.append(f"{r.system}: {verdict}")
        lines.append(f"  held-out nrms {e.base.nrms:.3g} (calibrated base) -> {e.final.nrms:.3g} (final); "
                     f"1 = the noise level")
        if e.final.error is not None and e.noise_floor is not None:
            lines.append(f"  held-out error {e.final.error:.3g} against a noise floor of {e.noise_floor:.3g} "
                         f"(error / floor = nrms)")
        err = r.rig.rop_model_error if r.rig else None
        if err:         # the rig file's model_error, which compare's ROP spread adds to the parameters'
            floor = err.get("noise_floor_rel")
            lines.append(f"  model error in the rig file: held-out ROP error {100 * err['rop_rel']:.3g} % (rms, "
                         f"relative" + ("" if floor is None else f"; noise floor {100 * floor:.3g} %") + ")")
        if r.empirical is not None:
            lines.append(f"  {r.empirical.text}")
    return lines


def cost_line(cost: dict) -> str:
    """One line of report.json ``cost``'s totals for the terminal (report.md has the table per stage)."""
    t = cost["total"]
    return (f"cost: {t['simulations']} simulations, {t['cpu_s']:.1f} s CPU, {t['wall_s']:.1f} s wall "
            f"(load average {cost['load_avg'][0]:g}; per stage: report.md)")


def _flat_metrics(report: DiagnoseReport) -> dict:
    out = {"wall_time_s": report.wall_time_s}
    for rep in report.systems:
        tag, e = rep.system.split("-")[-1], rep.errors
        out.update({f"{tag}.noise_floor": e.noise_floor, f"{tag}.default_error": e.default.error,
                    f"{tag}.base_error": e.base.error, f"{tag}.final_error": e.final.error,
                    f"{tag}.default_nrms": e.default.nrms, f"{tag}.base_nrms": e.base.nrms,
                    f"{tag}.final_nrms": e.final.nrms, f"{tag}.explained": 1.0 if rep.explained else 0.0})
        emp = rep.empirical
        if emp is not None and emp.heldout_rop_error_before is not None:      # the last resort was tried
            out.update({f"{tag}.empirical_adopted": 1.0 if emp.adopted else 0.0,
                        f"{tag}.empirical_heldout_rop_error_before": emp.heldout_rop_error_before,
                        f"{tag}.empirical_heldout_rop_error_after": emp.heldout_rop_error_after})
    return out
