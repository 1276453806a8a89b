"""The diagnosis: split runs, calibrate the base model, fit and rank every applicable §6 effect,
select one only if it brings the held-out residual to the noise level (the report dictionary).

Errors (all on held-out runs, never on the runs a model was fitted to):
- ``nrms``  = sqrt(mean of squared noise-normalised residuals) — 1 means "at the noise level";
- ``error`` = noise-weighted relative error ||(model - measured)/sd|| / ||measured/sd||; ``noise_floor`` is the
  same quantity for a residual of pure noise (sqrt(n) / ||measured/sd||), so ``error / noise_floor = nrms``
  (pipeline.diagnosis.heldout).
Ranking: ``score`` = BIC on the calibration runs, χ² + k ln n (noise sd known from the data), summed
over folds.  Selection: the best-scoring candidate whose BIC beats the base model's by ``bic_margin``
and whose held-out nrms is <= ``explained_nrms``; if the calibrated base model is already within
``explained_nrms`` nothing is selected; otherwise the residual is reported as unexplained.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from pipeline.diagnosis.config import DiagnoseConfig  # noqa: F401  (re-exported: the commands import it from here)
from pipeline.diagnosis.cost import CostRecorder, remote_cpu_of
from pipeline.diagnosis.progress import NoProgress, Progress, fit_tasks
from pipeline.diagnosis import mains
from pipeline.diagnosis.features import (CONTROL_NAMES, Target, UnusableRecord, series_target, simulated_features,
                                         summary_target)
from pipeline.core.executors import Executor, InlineExecutor
from pipeline.diagnosis.calibrate import fit_added, fit_additions, fit_models, refit
from pipeline.diagnosis.empirical import EmpiricalStage, rop_runs, try_correction
from pipeline.diagnosis.discovery import (NUMBERS_PER_PARAM, calibration_numbers, discover, proposal_terms,
                                          report as discovery_report, spanned_effect, supported)
from pipeline.diagnosis.fit import FitResult
from pipeline.diagnosis.nuisance import ChainEstimate, estimate_chain, locate_chain
from pipeline.diagnosis.heldout import HeldOut, systematic_error  # noqa: F401  (systematic_error re-exported)
from pipeline.diagnosis.judge import (FoldScheme, Fitter, Holdout, Judged, judge,  # noqa: F401  (make_folds
                                      make_folds, without_runs)                  # re-exported)
from pipeline.diagnosis import report_types as R
from pipeline.diagnosis.report_types import PairStage, effects_of
from pipeline.diagnosis.result import SystemDiagnosis
from sim.empirical import LABEL
from pipeline.diagnosis.verdict import (SELECTED, UNEXPLAINED, ModelStats, Verdict, VerdictRule, closeness, decide,
                                        indistinguishable)
from pipeline.diagnosis.model import (Evaluator, calibratable, candidates, default_fit_settings,
                                      default_max_harmonic_hz, supported_systems)
from pipeline.core.errors import UserError


def build_targets(ds, cfg: DiagnoseConfig, skipped: dict[str, list[str]] | None = None) -> dict[str, list[Target]]:
    """Targets per system, in runs.csv order (series preferred over summary when both exist).  Each
    target carries its run's controls (the model's own control names), the known rig parameters
    (preset / parameter columns), ``record_start_s`` (None where not given: steady state) and the DAQ chain
    runs.csv declares for it.  A record that cannot be used (every channel saturated) is left out and named in
    ``skipped`` (system -> notes).  Where the series runs show mains hum (``mains.detect``), they are built again with
    its lines fitted beside the harmonics and its amplitude in the sd of the harmonics it sits on."""
    out: dict[str, list[Target]] = {}
    rows = {r["run_id"]: r for r in ds.runs.to_dict("records")}
    for row in rows.values():
        tg = _target_of(ds, cfg, row, skipped)
        if tg is not None:
            out.setdefault(row["system"], []).append(tg)
    for tgs in out.values():
        hum = mains.detect([t.lines for t in tgs if t.kind == "series"])
        if not hum:
            continue
        families = tuple(sorted({fm for v in hum.values() for fm in v}))
        for i, t in enumerate(tgs):
            if t.kind == "series":
                tgs[i] = _target_of(ds, cfg, rows[t.run_id], None, families)
                mains.allow_for(tgs[i], hum)
        tgs[0].notes.insert(0, f"mains hum: {mains.describe(hum)}; its lines apart from the forcing harmonics are "
                               "fitted beside them, and the harmonics a line sits on carry its amplitude in their sd")
    return out


def _target_of(ds, cfg: DiagnoseConfig, row: dict, skipped: dict[str, list[str]] | None,
               hum_hz: tuple[float, ...] = ()) -> Target | None:
    """One run's target (``build_targets``); None for a record that cannot be used (named in ``skipped``)."""
    import sim

    system = row["system"]
    if system not in supported_systems():
        raise UserError(f"runs.csv, run '{row['run_id']}': system '{system}' cannot be diagnosed "
                        f"(supported: {', '.join(supported_systems())})")
    names = sim.get_model(system).param_names
    rs = row.get("record_start_s")
    tg = Target(run_id=row["run_id"], system=system, kind="",
                controls={c: float(row[c]) for c in CONTROL_NAMES if c in names and c in row},
                known=dict(ds.known.get(row["run_id"], {})),
                record_start_s=None if rs is None or not np.isfinite(rs) else float(rs),
                duration_s=float(row["duration_s"]), chain=getattr(ds, "chains", {}).get(row["run_id"]))
    mh = cfg.max_harmonic_hz or default_max_harmonic_hz(system)
    if row["run_id"] not in ds.series:
        sd = {k: tuple(v) for k, v in cfg.summary_sd.items()}
        return summary_target(tg, ds.summary.loc[row["run_id"]], mh, sd, floor=cfg.summary_floor)
    try:
        tg = series_target(tg, ds.series[row["run_id"]], mh, model_floor=cfg.model_floor,
                           max_cycles=cfg.record_window, hum_hz=hum_hz)
    except UnusableRecord as e:
        if skipped is None:
            raise
        skipped.setdefault(system, []).append(str(e))
        return None
    declared = tg.chain is not None and tg.chain.filter is not None
    tg.antialias = declared if cfg.antialias is None else cfg.antialias
    return tg


def absorbed_parameters(fits: dict[str, FitResult], v: Verdict, cal_names: list[str]) -> dict[str, R.Absorption]:
    """Calibrated parameters that moved between the base fit and the fit with the leading candidate (selected, or
    the best partial explanation) by more than 3 combined sd and 2 %: the base fit compensated part of the missing
    physics with them.  Parameter -> its ``Absorption``; empty when nothing leads."""
    other = v.leader
    if other is None or other not in fits:
        return {}
    b, w = fits["base"], fits[other]
    out = {}
    for n in cal_names:
        vb, vw = b.values[n], w.values[n]
        sd = math.hypot(b.sd.get(n, 0.0), w.sd.get(n, 0.0))
        if abs(vw - vb) > max(3.0 * sd, 0.02 * abs(vw)):
            out[n] = R.Absorption(vb, vw, vb / vw - 1.0, effects_of(other))
    return out


REPRODUCIBLE_RTOL_FACTOR = 0.01
"""A run is checked by solving its equations again at this × the settings' rtol."""


def unreproducible_runs(ev: Evaluator, cfg: DiagnoseConfig) -> dict[str, float]:
    """Series runs whose model response at the rig's nominal parameters is not reproducible: solved again at a
    hundredth of the tolerance, its features move by more than the noise (nrms > 1).  Such a response is chaotic
    or sits between coexisting orbits (the pendulum at 7.25 Hz, gap 1 mm); no trajectory of the model can be
    compared with the rig's cycle by cycle, and the fit may bend the parameters to hit one realisation: the report
    names these runs, and the folds leave them out (``judge.without_runs``; setting fit_unreproducible keeps
    them).  Run id -> nrms of the difference."""
    idx = [i for i, t in enumerate(ev.targets) if t.kind == "series"]
    if not idx:
        return {}
    tight = dict(cfg.sim_settings)
    tight["rtol"] = float(tight.get("rtol", 1e-7)) * REPRODUCIBLE_RTOL_FACTOR
    ev_tight = Evaluator(ev.system, ev.targets, tight, cfg.fs_sim_hz, ev.n_threads)
    a, b = ev.simulate([{}], idx)[0], ev_tight.simulate([{}], idx)[0]
    ev.n_sims += ev_tight.n_sims
    out = {}
    for i, ra, rb in zip(idx, a, b):
        fa, fb = simulated_features(ev.targets[i], ra), simulated_features(ev.targets[i], rb)
        if fa is None or fb is None:
            continue
        nrms = float(np.sqrt(np.mean(((fa - fb) / ev.targets[i].sd) ** 2)))
        if nrms > 1.0:
            out[ev.targets[i].run_id] = nrms
    return out


def pair_stage(cfg: DiagnoseConfig, v: Verdict, n_candidates: int) -> PairStage:
    """The pair stage runs when the single-effect leader improves on the base but leaves its held-out nrms above
    ``cfg.pair_nrms`` (adequate or not): the data ask for more than one effect.  A log one effect explains to the
    noise costs nothing more."""
    if cfg.max_effects < 2:
        return PairStage(False, "max_effects 1: one effect only")
    if n_candidates < 2:
        return PairStage(False, "fewer than two candidate effects")
    if v.leader is None:
        return PairStage(False, "no effect improves on the calibrated base, so none to add a second to")
    nrms = v.checks[v.leader].nrms
    if nrms <= cfg.pair_nrms:
        return PairStage(False, f"{v.leader} alone leaves held-out nrms {nrms:.3g}, within pair_nrms "
                                f"{cfg.pair_nrms:g} of the noise: no pair tried")
    return PairStage(True, f"{v.leader} improves on the base but leaves held-out nrms {nrms:.3g}, above pair_nrms "
                           f"{cfg.pair_nrms:g}")


def _second_effect(d: _Diagnosis, first: str, first_fits: tuple[list[dict], dict] | None = None) -> Judged:
    """Greedy forward selection's second step: ``first`` with each other candidate, fitted on every fold's
    calibration runs (from the fold's fit with ``first``) and judged on its held-out runs against ``first`` alone by
    the same rule; the reported fits start from the reported fit with ``first``.  ``first_fits``: ``first``'s
    fits (per fold, reported) fitted again under a relocated chain, then judged here beside the pairs.  Where the
    undeclared chain is located again at the leading pair (``relocated``), that pair and ``first`` are fitted
    again, in turn with the chain, and ``first`` is judged here beside the pairs, under the same chain."""
    ev, cfg, cands, ex, effects = d.ev, d.cfg, d.cands, d.executor, d.effects
    added = {f"{first}+{e}": [*cands[first], *cands[e]] for e in cands if e != first} | {first: list(cands[first])}
    fold_starts, reported_start = first_fits or ([f[first] for f in effects.fold_fits], effects.fits[first])
    moved: list[str] = [first] if first_fits else []

    def fit_on(sets: list[list[int]], starts: list[FitResult], folds: bool) -> list[dict]:
        fits = [{**f, first: s} for f, s in zip(fit_additions(ev, sets, cfg, first, cands, starts, ex), starts)]
        lead = relocated(d, fits, first, added) if folds else None
        if lead is not None:
            moved[:] = [first, lead]
            for _ in range(RELOCATE_ROUNDS):     # the clock and the pair's parameters settle together
                fits = refit(ev, sets, cfg, {m: added[m] for m in moved}, fits, ex)
                clock = d.chain.clock_ppm
                d.chain = locate_chain(ev, d.chain, lead, fits[0][lead].values, d.log)
                if abs(d.chain.clock_ppm - clock) < 1.0:
                    break
        if len(moved) == 2:
            fits = refit(ev, sets, cfg, {m: added[m] for m in moved}, fits, ex)
        return fits if moved else [{m: f[m] for m in f if m != first} for f in fits]
    fold_fits = fit_on([cal for cal, _ in d.scheme.folds], fold_starts, True)
    fitter = Fitter(lambda sets: fold_fits, lambda: fit_on([d.scheme.reported_runs], [reported_start], False)[0])
    j = judge(ev, d.scheme, fitter, cfg.rule(), against=first if moved else d.stats[first])
    for m in j.stats:
        d.log(f"  {m}: held-out nrms {j.err[m].nrms:.4g}")
    return j


RELOCATE_ROUNDS = 3
"""Times at most the pair stage fits its leader again and locates the chain's clock again at the new fit."""


def _second_report(first: str, fits: dict, stats: dict, v2: Verdict, rule: VerdictRule,
                   cal_names: list[str]) -> R.SecondEffect:
    """report.json ``second_effect``: every pair tried against ``first`` alone, the call, and the pairs the data
    cannot tell apart."""
    rows = [R.PairCandidate(effects=effects_of(m),
                            params={p: fits[m].values[p] for p in fits[m].free if p not in cal_names},
                            param_sd={p: fits[m].sd[p] for p in fits[m].free if p not in cal_names},
                            nrms=c.nrms, systematic=c.systematic, delta_bic=c.delta_bic, delta_chi2=c.delta_chi2,
                            improves=c.improves, adequate=c.adequate)
            for m, c in ((m, v2.checks[m]) for m in sorted(stats, key=lambda m: stats[m].bic) if m != first)]
    lead = v2.leader
    if lead is None:
        text = (f"no second effect improves on {first} alone (best: {'+'.join(rows[0].effects)}, held-out nrms "
                f"{rows[0].nrms:.3g} against {v2.checks[first].nrms:.3g})" if rows else "no other effect to add")
    else:
        c = v2.checks[lead]
        text = (f"{lead}: held-out nrms {v2.checks[first].nrms:.3g} → {c.nrms:.3g}, ΔBIC {c.delta_bic:.3g} and "
                f"held-out Δχ² {c.delta_chi2:.3g} against {first} alone; "
                + ("adequate: both effects selected" if c.adequate else f"still above the noise (limit {rule.explained_nrms:g})"))
    same = indistinguishable(v2, stats, rule)
    if same:
        text += f"; indistinguishable on these data from {', '.join(same)} (ΔBIC < {rule.bic_margin:g})"
    return R.SecondEffect(first=effects_of(first), candidates=tuple(rows), leader=effects_of(lead),
                          indistinguishable=tuple(effects_of(m) for m in same), text=text)


def recording_report(targets: list[Target], chain: ChainEstimate | None) -> R.Recording:
    """report.json ``recording``: the DAQ chain each run declares, the undeclared chain estimated as nuisance
    (delay per channel and clock, with sd; None when every series run declares its chain or estimation is off),
    the fraction of saturated samples per run and channel, and the mains hum found."""
    declared = {t.run_id: R.DeclaredChain(None if t.chain.filter is None else t.chain.filter.text(), t.chain.delay_s,
                                          t.chain.clock_ppm)
                for t in targets if t.chain is not None}
    return R.Recording(declared=declared, estimated=chain.to_record() if chain is not None else None,
                       clipped={t.run_id: dict(t.clipped) for t in targets if t.clipped},
                       hum=next((mains.as_record(t.hum) for t in targets if t.hum), None),
                       antialiased=tuple(t.run_id for t in targets if t.antialias) or None)


@dataclass(frozen=True)
class AsEffect:
    """An accepted proposal refitted as the §6 effect it spans: the effect, the start the proposal gave its parameter
    [SI], the refit's parameters [SI], its reported fit, held-out errors and statistics, calibration χ² summed over
    the folds, and a sentence."""

    effect: str
    start: dict[str, float]
    params: dict[str, float]
    fit: FitResult
    err: HeldOut
    stats: ModelStats
    fit_chi2: float
    text: str


def _as_effect(ev: Evaluator, cfg: DiagnoseConfig, scheme: FoldScheme, found, cands: dict,
               stats: dict[str, ModelStats], executor: Executor, log) -> AsEffect | None:
    """An accepted proposal that is a §6 effect in another form (``discovery.spanned_effect``): the effect refitted
    on every fold from the proposal's calibrated values with the parameter the proposal's coefficient gives (α = c / k)
    and judged on the held-out runs; None when the proposal spans no effect or the refit is no better than the
    effect's own fit (BIC)."""
    import sim

    fr = found.fits[found.accepted]
    values = {**sim.get_model(ev.system).defaults(), **ev.targets[0].known, **fr.values}
    hit = spanned_effect(ev.system, found.accepted, values, cands)
    if hit is None:
        return None
    eff, start = hit
    cal_names = [q.name for q in calibratable(ev.system)]
    base_start = replace(fr, values={n: fr.values[n] for n in cal_names})      # the calibration, without the term
    log(f"{ev.system}: the proposal {found.accepted} is {eff} in another form: refitting {eff} from "
        + ", ".join(f"{k} = {x:.4g}" for k, x in start.items()))

    def fit_on(sets: list[list[int]], starts: list[FitResult]) -> list[dict]:
        return fit_added(ev, sets, cfg, {eff: cands[eff]}, starts, executor, extra_starts={eff: start})
    fitter = Fitter.from_starts(fit_on, scheme, [base_start] * len(scheme.folds), base_start)
    j = judge(ev, scheme, fitter, cfg.rule(), keep=lambda j: j.stats[eff].bic < stats[eff].bic)
    if j.fits is None:
        log(f"  {eff} from the proposal: no better than its own fit")
        return None
    reported = j.fits[eff]
    params = {p: reported.values[p] for p in reported.free if p not in cal_names}
    text = (f"the accepted proposal {' + '.join(proposal_terms(found.accepted))} is {eff} in another form: refitted "
            f"from {', '.join(f'{k} = {x:.4g}' for k, x in start.items())} (c / k) to "
            f"{', '.join(f'{k} = {x:.4g}' for k, x in params.items())}, held-out nrms {j.err[eff].nrms:.3g}")
    log(f"  {text}")
    return AsEffect(eff, start, params, reported, j.err[eff], j.stats[eff], j.cal_chi2[eff], text)


def _param_report(fr: FitResult) -> dict[str, R.ParamEstimate]:
    return {n: R.ParamEstimate(fr.values[n], fr.sd[n], tuple(fr.ci95[n])) for n in fr.free}


@dataclass
class _Diagnosis:
    """The working state ``diagnose_system``'s stages hand on to each other (one field per quantity)."""

    system: str
    targets: list[Target]
    cfg: DiagnoseConfig
    ev: Evaluator
    executor: Executor
    log: Callable
    progress: Progress
    chain: ChainEstimate | None
    unreproducible: dict[str, float]
    cands: dict
    cost: CostRecorder
    scheme: FoldScheme | None = None
    warm: dict | None = None
    fold_fits: list[dict] = field(default_factory=list)
    effects: Judged | None = None
    err: dict[str, HeldOut] = field(default_factory=dict)
    final_fits: dict = field(default_factory=dict)
    stats: dict[str, ModelStats] = field(default_factory=dict)
    cal_chi2: dict[str, float] = field(default_factory=dict)
    first: Verdict | None = None
    v: Verdict | None = None
    cal_names: list[str] = field(default_factory=list)
    pair: PairStage | None = None
    second: R.SecondEffect | None = None
    final: str = "base"
    found: object = None
    named: AsEffect | None = None
    named_selected: bool = False
    call: R.Call | None = None
    empirical: EmpiricalStage | None = None
    notes: list[str] = field(default_factory=list)


def diagnose_system(system: str, targets: list[Target], cfg: DiagnoseConfig, log=print,
                    progress: Progress | None = None, executor: Executor | None = None) -> SystemDiagnosis:
    """Diagnose one system's runs: its report entry, with the evaluator, the reported fits, the held-out runs
    and the final model the figures and the corrected rig need.  The fits run on ``executor`` (default: in this
    process, on ``cfg.n_threads`` simulation threads); ``progress`` hears of each stage; the cost of each stage is
    recorded (``cost``)."""
    progress = progress or NoProgress()
    progress.stage(f"{system}: checking the model's response is reproducible")
    d = _prepare(system, targets, cfg, log, progress, executor or InlineExecutor())
    for name, step in (("calibration", _calibrate), ("held-out", _held_out), ("pairs", _pairs),
                       ("discovery", _discover)):
        with d.cost.stage(name):
            step(d)
    _make_call(d)
    if d.chain is not None:
        with d.cost.stage("DAQ chain at the final model"):
            d.chain = locate_chain(d.ev, d.chain, d.final, d.final_fits[d.final].values, d.log)
    if not d.v.explained and not (d.found is not None and d.found.accepted):
        with d.cost.stage("empirical correction"):
            _empirical(d)
    d.ev.cost = None
    return _assemble(d)


def _prepare(system: str, targets: list[Target], cfg: DiagnoseConfig, log, progress: Progress,
             executor: Executor) -> _Diagnosis:
    """The fit settings (system defaults where unset), the evaluator and the cost recorder counting its
    simulations, the DAQ chain estimate, the reproducibility check and the candidate effects (``cfg.effects``
    checked against the system's)."""
    cfg = replace(cfg, **{k: v for k, v in default_fit_settings(system).items() if getattr(cfg, k) is None})
    ev = Evaluator(system, targets, dict(cfg.sim_settings), cfg.fs_sim_hz, cfg.n_threads)
    ev.cost = cost = CostRecorder(system, lambda: ev.n_sims, remote_cpu_of(executor))
    with cost.stage("unreproducible-run check"):
        unreproducible = unreproducible_runs(ev, cfg)
    if unreproducible:
        log(f"{system}: model response not reproducible (chaotic or multi-stable): {', '.join(unreproducible)}")
    chain = None
    if cfg.estimate_chain:       # a run no trajectory of the model follows says nothing of the chain
        with cost.stage("DAQ chain"):
            chain = estimate_chain(ev, cfg, executor, log, exclude=set(unreproducible))
    cands = candidates(system)
    if cfg.effects is not None:
        unknown = [e for e in cfg.effects if e not in cands]
        if unknown:
            raise UserError(f"diagnose.effects: {', '.join(unknown)} not an effect of {system} "
                            f"(known: {', '.join(cands)})")
        cands = {e: cands[e] for e in cfg.effects}
    return _Diagnosis(system, targets, cfg, ev, executor, log, progress, chain, unreproducible, cands, cost)


def _calibrate(d: _Diagnosis) -> None:
    """Base + every candidate fitted on all runs (leave-one-out only: the reported parameters and the folds'
    starting point) and on every fold's calibration runs."""
    system, targets, cfg, log, progress = d.system, d.targets, d.cfg, d.log, d.progress
    d.scheme = make_folds(targets, cfg)
    if not cfg.fit_unreproducible:      # no trajectory of the model follows them: a fit would bend to one realisation
        d.scheme = without_runs(d.scheme, {i for i, t in enumerate(targets) if t.run_id in d.unreproducible})
    _drop_unsupported(d)
    cands = d.cands
    rng = np.random.default_rng(cfg.seed)

    def n_fit_tasks(n_folds: int, warm_start: bool) -> int:
        return fit_tasks(n_folds, len(cands), cfg.n_starts, cfg.candidate_starts, warm_start)

    def fit_all() -> dict:      # the reported parameters: a fit on all runs (also the folds' starting point)
        n = len(d.scheme.reported_runs)
        log(f"{system}: fit on all {n} runs (reported parameters)")
        progress.stage(f"{system}: base + {len(cands)} candidates on all {n} runs", n_fit_tasks(1, False))
        [(fits, lines)] = fit_models(d.ev, [d.scheme.reported_runs], cfg, cands, rng, d.executor)
        for line in lines:
            log(line)
        return fits
    d.warm = d.scheme.warm(fit_all)
    folds = d.scheme.folds
    progress.stage(f"{system}: base + {len(cands)} candidates on {len(folds)} fold(s)",
                   n_fit_tasks(len(folds), bool(d.warm)))
    fold_fits = fit_models(d.ev, [cal for cal, _ in folds], cfg, cands, rng, d.executor, d.warm)
    for fi, ((cal, test), (_, lines)) in enumerate(zip(folds, fold_fits)):
        log(f"{system}: fold {fi + 1}/{len(folds)} ({len(cal)} calibration, {len(test)} held-out runs)")
        for line in lines:
            log(line)
    d.fold_fits = [fits for fits, _ in fold_fits]


def _drop_unsupported(d: _Diagnosis) -> None:
    """Leave out the effects the data cannot judge: as for a proposal (``discovery.NUMBERS_PER_PARAM``), an effect
    is fitted only where every fold's calibration runs hold 2 measured numbers per free parameter (calibratable +
    the effect's); with fewer a fit interpolates its runs and the held-out test is no evidence.  The published
    seed-000 log (4 runs of 2-3 summary numbers per indenter) leaves 6 numbers per fold, 8 needed for a
    one-parameter effect on 3 calibratables: its base is fitted and judged, no effect is, and the report says why."""
    n_numbers = calibration_numbers(d.ev, d.scheme)
    d.cands, dropped = supported(d.cands, n_numbers, len(calibratable(d.system)))
    if dropped:
        d.notes.append(f"not fitted, too few numbers to judge them (the smallest fold's calibration runs hold "
                       f"{n_numbers} measured numbers, {NUMBERS_PER_PARAM} per free parameter needed): "
                       f"{', '.join(dropped)}")
        d.log(f"{d.system}: {d.notes[-1]}")


def _leader_relocated(d: _Diagnosis, lead: str) -> tuple[list[dict], dict] | None:
    """The pairs start from the chain located at the leader's fit (the base's is biased by what the leader adds)
    and from the leader fitted again under it: its fits per fold and reported; None when the chain did not move."""
    if relocated(d, [d.effects.fits], "base", {lead: list(d.cands[lead]), "base": []}) is None:
        return None
    one = {lead: list(d.cands[lead])}
    folds = refit(d.ev, [cal for cal, _ in d.scheme.folds], d.cfg, one, d.effects.fold_fits, d.executor)
    reported = (folds[0] if isinstance(d.scheme, Holdout) else
                refit(d.ev, [d.scheme.reported_runs], d.cfg, one, [d.effects.fits], d.executor)[0])
    return [f[lead] for f in folds], reported[lead]


def relocated(d: _Diagnosis, fits: list[dict[str, FitResult]], reference: str, added: dict) -> str | None:
    """Locate an undeclared chain again at the fit of the model that leads ``fits`` (per fold, or the reported
    fits; BIC summed), when it beats ``reference`` by the BIC margin; that model, or None when nothing moved.  On
    records from rest the clock was located at the base model's fit, which missing physics biases, and each fit
    profiles on top of it only a rotation, which a transient does not follow exactly.  Nothing to do for
    steady-state records.  Done where two effects are tried, not before the single effects are judged
    (docs/diagnose.md says what that did)."""
    ev = d.ev
    if d.chain is None or all(ev.targets[i].record_start_s is None for i in ev.profile_runs) or d.cfg.refine_nfev <= 0:
        return None
    bic = {m: sum(f[m].bic() for f in fits) for m in added if m != reference}
    lead = min(bic, key=bic.get, default=None)
    if lead is None or bic[lead] + d.cfg.bic_margin >= sum(f[reference].bic() for f in fits):
        return None
    d.chain = locate_chain(ev, d.chain, lead, fits[0][lead].values, d.log)
    return lead


def _held_out(d: _Diagnosis) -> None:
    """The held-out errors of the nominal ('default'), base and every candidate model, their statistics summed
    over the folds, the reported fits and the single-effect verdict."""
    d.progress.stage(f"{d.system}: held-out errors of {len(d.cands) + 1} models")
    fitter = Fitter(lambda sets: d.fold_fits, lambda: d.warm)
    d.effects = judge(d.ev, d.scheme, fitter, d.cfg.rule(), against="base", fixed={"default": {}})
    d.err, d.stats, d.cal_chi2 = dict(d.effects.err), dict(d.effects.stats), dict(d.effects.cal_chi2)
    d.final_fits = dict(d.effects.fits)
    d.v = d.first = d.effects.verdict
    d.cal_names = [q.name for q in calibratable(d.system)]


def _pairs(d: _Diagnosis) -> None:
    """The greedy pair stage: the leader with each other effect, when the data ask for more than one effect."""
    system, cfg, cands, v = d.system, d.cfg, d.cands, d.v
    d.pair = pair_stage(cfg, v, len(cands))
    if not d.pair.tried:
        return
    d.log(f"{system}: {d.pair.reason}: adding a second effect")
    first_fits = _leader_relocated(d, v.leader)
    d.progress.stage(f"{system}: {v.leader} + each of {len(cands) - 1} other effects")
    pairs = _second_effect(d, v.leader, first_fits)
    v2 = pairs.verdict
    d.second = _second_report(v.leader, pairs.fits, pairs.stats, v2, cfg.rule(), d.cal_names)
    d.final_fits = {**d.final_fits, **pairs.fits}
    d.err.update(pairs.err)
    pair_adequate = v2.leader is not None and v2.checks[v2.leader].adequate
    if pair_adequate or (v2.leader is not None and v.kind != SELECTED):   # an adequate single stays
        kind = SELECTED if pair_adequate else UNEXPLAINED
        d.v = replace(v, kind=kind, selected=v2.leader if kind == SELECTED else None, leader=v2.leader)
    elif v2.leader is None and v.kind != SELECTED and v.leader in pairs.stats:
        _leader_again(d, pairs.stats[v.leader])


def _leader_again(d: _Diagnosis, stats: ModelStats) -> None:
    """No pair improves on the leader, which the pair stage fitted again under the chain located at its own fit: the
    leader is judged against the base again with those fits, its report row from the same numbers (a leader the
    base's chain left at held-out nrms 6 may be at the noise under its own)."""
    v = d.v
    check = decide(d.stats["base"], [stats], d.cfg.rule()).checks[v.leader]
    d.stats[v.leader] = stats
    selected = check.improves and check.adequate
    d.v = replace(v, kind=SELECTED if selected else v.kind, selected=v.leader if selected else v.selected,
                  checks={**v.checks, v.leader: check})
    d.first = d.v                                       # the one-effect call is this one
    if selected:
        d.log(f"{d.system}: {v.leader} fitted again under the chain located at its fit: held-out nrms "
              f"{check.nrms:.3g}, adequate")


def _discover(d: _Diagnosis) -> None:
    """Nothing explains the residual: propose the missing term; an accepted proposal becomes the final model, and
    is refitted as the §6 effect it spans, if any."""
    d.final = d.v.selected or "base"
    if d.v.kind == UNEXPLAINED and d.cfg.max_proposals >= 1:
        d.log(f"{d.system}: no §6 effect explains the residual: proposing the missing term")
        d.progress.stage(f"{d.system}: proposing the missing term")
        d.found = discover(d.ev, d.cfg, d.scheme, d.effects, d.stats["base"], d.executor, d.log)
    if d.found is not None and d.found.accepted:
        d.final = d.found.accepted
        d.final_fits = {**d.final_fits, d.final: d.found.fits[d.final]}
        d.err[d.final] = d.found.err[d.final]
        d.named = _as_effect(d.ev, d.cfg, d.scheme, d.found, d.cands, d.stats, d.executor, d.log)


def _empirical(d: _Diagnosis) -> None:
    """Nothing brought the residual to the noise: try an empirical correction of ROP over the operating point,
    judged on the folds' held-out runs (with leave-one-run-out folds the final model's reported fit has seen the
    held-out run, so its error before the correction is an in-sample one)."""
    idx = list(range(len(d.targets)))
    [(res, _)] = d.ev.held_out([d.final_fits[d.final].values], idx)
    d.empirical = try_correction(rop_runs(d.targets, res), d.scheme.folds, d.cfg.seed, d.cfg.empirical_gain)
    d.log(f"{d.system}: {LABEL}: {_trial_word(d.empirical)}, {d.empirical.reason}")


def _empirical_report(st: EmpiricalStage | None) -> R.EmpiricalReport | None:
    if st is None:
        return None
    inputs = st.correction.inputs if st.correction is not None else ()
    return R.EmpiricalReport(label=LABEL, adopted=st.adopted, inputs=tuple(inputs),
                             heldout_rop_error_before=st.before, heldout_rop_error_after=st.after,
                             heldout_runs=st.n_held_out, halved=st.halved,
                             text=f"{LABEL}: {_trial_word(st)} ({st.reason})")


def _trial_word(st: EmpiricalStage) -> str:
    return "adopted" if st.adopted else ("not adopted" if st.before is not None else "not tried")


def _make_call(d: _Diagnosis) -> None:
    """report.json ``call``: how close the call is, for one effect, two, and the proposal read as an effect (which
    replaces the verdict when it is adequate)."""
    d.call = closeness(d.first, d.stats, d.cfg.rule())
    if d.second is not None:
        d.call = replace(d.call, text=f"one effect: {d.call.text}; two effects: {d.second.text}")
    named = d.named
    if named is None:
        return
    eff = named.effect
    d.cal_chi2[eff] = named.fit_chi2
    d.stats[eff], d.err[eff], d.final_fits[eff] = named.stats, named.err, named.fit
    v_named = decide(d.stats["base"], [d.stats[m] for m in d.cands], d.cfg.rule())
    d.named_selected = v_named.selected == eff
    d.v = replace(d.v, checks={**d.v.checks, eff: v_named.checks[eff]})
    if d.named_selected:
        d.v, d.final = v_named, eff
        d.call = closeness(v_named, d.stats, d.cfg.rule())
    d.call = replace(d.call, text=d.call.text + f"; {named.text}"
                     + ("" if d.named_selected else " (not adequate: the proposal stays)"))


def _candidate_rows(d: _Diagnosis) -> tuple[R.Candidate, ...]:
    """report.json ``candidates``: every single effect, best BIC first."""
    final_fits, err, v = d.final_fits, d.err, d.v
    bic = {m: d.stats[m].bic for m in ["base", *d.cands]}
    return tuple(R.Candidate(
        effects=(m,), params={p: final_fits[m].values[p] for p in final_fits[m].free if p not in d.cal_names},
        param_sd={p: final_fits[m].sd[p] for p in final_fits[m].free}, calibrated=final_fits[m].values,
        error=err[m].error, nrms=err[m].nrms, systematic=err[m].systematic, score=bic[m],
        delta_score=bic[m] - bic["base"], delta_chi2_heldout=v.checks[m].delta_chi2,
        improves=v.checks[m].improves, adequate=v.checks[m].adequate, calibration_chi2=d.cal_chi2[m])
        for m in sorted(d.cands, key=lambda m: bic[m]))


def _model_errors(e: HeldOut, systematic: bool = True) -> R.ModelErrors:
    return R.ModelErrors(e.error, e.nrms, e.systematic if systematic else None, e.error_by_group)


def _assemble(d: _Diagnosis) -> SystemDiagnosis:
    """The system's report entry (report.json), with the evaluator, the reported fits, the held-out runs and the
    final model."""
    targets, err, v, final, final_fits, found, named = d.targets, d.err, d.v, d.final, d.final_fits, d.found, d.named
    ids = [t.run_id for t in targets]
    report = R.SystemReport(
        system=d.system, n_runs=len(targets), unreproducible=d.unreproducible,
        data=tuple(sorted({t.kind for t in targets})),
        split=R.Split(d.scheme.name, tuple(ids[i] for i in sorted(set(d.effects.held_out))),
                      tuple(R.Fold(tuple(ids[i] for i in c), tuple(ids[i] for i in t)) for c, t in d.scheme.folds)),
        verdict=v.kind, calibrated=final_fits["base"].values,
        calibrated_uncertainty=_param_report(final_fits["base"]),
        noise_sd={t.run_id: t.noise for t in targets if t.noise},
        errors=R.HeldOutErrors(default=_model_errors(err["default"], systematic=False),
                               base=_model_errors(err["base"]), final=_model_errors(err[final]),
                               noise_floor=err["base"].noise_floor, noise_by_group=err["base"].noise_by_group,
                               n=err["base"].n),
        base_score=d.stats["base"].bic, candidates=_candidate_rows(d),
        selected=effects_of(v.selected), leader=effects_of(v.leader), runner_up=effects_of(v.runner_up),
        selected_params=_param_report(final_fits[final]) if final != "base" else None,
        explained=v.explained, best_partial_candidate=effects_of(v.leader) if v.kind == UNEXPLAINED else None,
        absorbed=absorbed_parameters(final_fits, v, d.cal_names), call=d.call,
        indistinguishable=tuple(effects_of(m) for m in indistinguishable(d.first, d.stats, d.cfg.rule())),
        second_effect=d.second, pair_stage=d.pair,
        discrepancy=discovery_report(found, err["base"], d.cal_names) if found is not None else None,
        proposal_adopted=(tuple(proposal_terms(found.accepted)) if found is not None and found.accepted
                          and not d.named_selected else None),
        proposal_as_effect=(R.ProposalAsEffect(named.effect, named.start, named.params, d.named_selected, named.text)
                            if named is not None else None),
        recording=recording_report(targets, d.chain), n_simulations=d.ev.n_sims, notes=tuple(d.notes),
        empirical=_empirical_report(d.empirical))
    correction = d.empirical.correction if d.empirical is not None and d.empirical.adopted else None
    return SystemDiagnosis(report=report, evaluator=d.ev, fits=final_fits, held_out=d.effects.held_out, final=final,
                           cost=d.cost.rows(), empirical=correction)
