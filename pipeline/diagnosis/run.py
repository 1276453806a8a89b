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

import numpy as np

from pipeline.diagnosis.config import DiagnoseConfig  # noqa: F401  (re-exported: the commands import it from here)
from pipeline.diagnosis.progress import NoProgress, Progress, fit_tasks
from pipeline.diagnosis.features import CONTROL_NAMES, Target, series_target, simulated_features, summary_target
from pipeline.core.executors import Executor, InlineExecutor
from pipeline.diagnosis.calibrate import fit_additions, fit_models
from pipeline.diagnosis.discovery import discover, proposal_terms, report as discovery_report
from pipeline.diagnosis.fit import FitResult
from pipeline.diagnosis.heldout import fold_errors, heldout_errors as _errors, systematic_error  # noqa: F401
from pipeline.diagnosis.result import SystemDiagnosis
from pipeline.diagnosis.verdict import (SELECTED, UNEXPLAINED, ModelStats, Verdict, VerdictRule, closeness, decide,
                                        indistinguishable)
from pipeline.diagnosis.model import (Evaluator, calibratable, candidates, default_fit_settings,
                                      default_max_harmonic_hz, supported_systems)
from pipeline.core.errors import UserError


def build_targets(ds, cfg: DiagnoseConfig) -> dict[str, list[Target]]:
    """Targets per system, in runs.csv order (series preferred over summary when both exist).  Each
    target carries its run's controls (the model's own control names), the known rig parameters
    (preset / parameter columns) and ``record_start_s`` (None where not given: steady state)."""
    import sim

    out: dict[str, list[Target]] = {}
    sd = {k: tuple(v) for k, v in cfg.summary_sd.items()}
    for row in ds.runs.to_dict("records"):
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
                    duration_s=float(row["duration_s"]))
        mh = cfg.max_harmonic_hz or default_max_harmonic_hz(system)
        if row["run_id"] in ds.series:
            tg = series_target(tg, ds.series[row["run_id"]], mh, model_floor=cfg.model_floor,
                               max_cycles=cfg.record_window)
        else:
            tg = summary_target(tg, ds.summary.loc[row["run_id"]], mh, sd, floor=cfg.summary_floor)
        out.setdefault(system, []).append(tg)
    return out


def make_folds(targets: list[Target], cfg: DiagnoseConfig) -> tuple[str, list[tuple[list[int], list[int]]]]:
    """Deterministic split.  >= min_runs_holdout runs: one split, every holdout_every-th run of the
    (static force, frequency)-sorted list held out (offset 1, so both ends stay in calibration);
    fewer: leave-one-run-out."""
    n = len(targets)
    c = [targets[i].controls for i in range(n)]
    order = sorted(range(n), key=lambda i: (c[i].get("static_force_n", 0.0), c[i].get("gap_m", 0.0),
                                            c[i].get("amplitude_n", c[i].get("amplitude_m", 0.0)),
                                            c[i]["frequency_hz"], targets[i].run_id))
    if n >= max(cfg.min_runs_holdout, 3):
        test = sorted(order[j] for j in range(n) if j % cfg.holdout_every == 1)
        cal = sorted(set(range(n)) - set(test))
        return "holdout", [(cal, test)]
    if n < 2:
        raise UserError(f"system '{targets[0].system}': only {n} run; need at least 2 to hold one out")
    return "leave-one-run-out", [([j for j in range(n) if j != i], [i]) for i in range(n)]


def absorbed_parameters(fits: dict[str, FitResult], v: Verdict, cal_names: list[str]) -> dict:
    """Calibrated parameters that moved between the base fit and the fit with the leading candidate (selected, or
    the best partial explanation) by more than 3 combined sd and 2 %: the base fit compensated part of the missing
    physics with them.  {parameter: {"base", "with", "change"}}; empty when nothing leads."""
    other = v.leader
    if other is None or other not in fits:
        return {}
    b, w = fits["base"], fits[other]
    out = {}
    for n in cal_names:
        vb, vw = b.values[n], w.values[n]
        sd = math.hypot(b.sd.get(n, 0.0), w.sd.get(n, 0.0))
        if abs(vw - vb) > max(3.0 * sd, 0.02 * abs(vw)):
            out[n] = {"base": vb, "with": vw, "change": vb / vw - 1.0, "effect": other}
    return out


NOISE_NRMS = 1.0
"""Held-out nrms of a model at the noise floor (residual / noise sd)."""

REPRODUCIBLE_RTOL_FACTOR = 0.01
"""A run is checked by solving its equations again at this × the settings' rtol."""


def unreproducible_runs(ev: Evaluator, cfg: DiagnoseConfig) -> dict[str, float]:
    """Series runs whose model response at the rig's nominal parameters is not reproducible: solved again at a
    hundredth of the tolerance, its features move by more than the noise (nrms > 1).  Such a response is chaotic
    or sits between coexisting orbits (the pendulum at 7.25 Hz, gap 1 mm); no trajectory of the model can be
    compared with the rig's cycle by cycle, and the fit may bend the parameters to hit one realisation: the report
    names these runs so the user can leave them out.  Run id -> nrms of the difference."""
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


def _second_effect(ev: Evaluator, cfg: DiagnoseConfig, scheme: str, folds: list, first: str, cands: dict,
                   fits_per_fold: list[dict], warm: dict | None, first_stats: ModelStats, executor: Executor,
                   log) -> tuple[dict, dict, dict, Verdict]:
    """Greedy forward selection's second step: ``first`` with each other candidate, fitted on every fold's
    calibration runs and judged on its held-out runs against ``first`` alone by the same rule.  Returns the reported
    fits, the held-out errors and statistics of every pair, and the verdict with ``first`` as the base."""
    warm_pairs = None
    if scheme != "holdout":
        [warm_pairs] = fit_additions(ev, [list(range(len(ev.targets)))], cfg, first, cands, [warm[first]], executor)
    fold_pairs = fit_additions(ev, [cal for cal, _ in folds], cfg, first, cands, [f[first] for f in fits_per_fold],
                               executor)
    names = list(fold_pairs[0])
    err, stats = fold_errors(ev, folds, fold_pairs, names)
    for m in names:
        log(f"  {m}: held-out nrms {err[m]['nrms']:.4g}")
    v2 = decide(first_stats, [stats[m] for m in names], cfg.rule())
    return (fold_pairs[0] if scheme == "holdout" else warm_pairs), err, stats, v2


def _second_report(first: str, fits: dict, stats: dict, v2: Verdict, rule: VerdictRule,
                   cal_names: list[str]) -> dict:
    """report.json ``second_effect``: every pair tried against ``first`` alone, the call, and the pairs the data
    cannot tell apart."""
    rows = [{"name": m, "effects": m.split("+"),
             "params": {p: fits[m].values[p] for p in fits[m].free if p not in cal_names},
             "param_sd": {p: fits[m].sd[p] for p in fits[m].free if p not in cal_names},
             **{k: v2.checks[m][k] for k in ("nrms", "systematic", "delta_bic", "delta_chi2", "improves", "adequate")}}
            for m in sorted(stats, key=lambda m: stats[m].bic)]
    lead = v2.leader
    if lead is None:
        text = (f"no second effect improves on {first} alone (best: {rows[0]['name']}, held-out nrms "
                f"{rows[0]['nrms']:.3g} against {v2.checks[first]['nrms']:.3g})" if rows else "no other effect to add")
    else:
        c = v2.checks[lead]
        text = (f"{lead}: held-out nrms {v2.checks[first]['nrms']:.3g} → {c['nrms']:.3g}, ΔBIC {c['delta_bic']:.3g} and "
                f"held-out Δχ² {c['delta_chi2']:.3g} against {first} alone; "
                + ("adequate: both effects selected" if c["adequate"] else f"still above the noise (limit {rule.explained_nrms:g})"))
    same = indistinguishable(v2, stats, rule)
    if same:
        text += f"; indistinguishable on these data from {', '.join(same)} (ΔBIC < {rule.bic_margin:g})"
    return {"first": first, "candidates": rows, "leader": lead, "indistinguishable": same, "text": text}


def _param_report(fr: FitResult) -> dict:
    return {n: {"value": fr.values[n], "sd": fr.sd[n], "ci95": list(fr.ci95[n])} for n in fr.free}


def diagnose_system(system: str, targets: list[Target], cfg: DiagnoseConfig, log=print,
                    progress: Progress | None = None, executor: Executor | None = None) -> SystemDiagnosis:
    """Diagnose one system's runs: its report entry, with the evaluator, the reported fits, the held-out runs
    and the final model the figures and the corrected rig need.  The fits run on ``executor`` (default: in this
    process, on ``cfg.n_threads`` simulation threads); ``progress`` hears of each stage."""
    from dataclasses import replace

    progress = progress or NoProgress()
    progress.stage(f"{system}: checking the model's response is reproducible")

    cfg = replace(cfg, **{k: v for k, v in default_fit_settings(system).items() if getattr(cfg, k) is None})
    ev = Evaluator(system, targets, dict(cfg.sim_settings), cfg.fs_sim_hz, cfg.n_threads)
    unreproducible = unreproducible_runs(ev, cfg)
    if unreproducible:
        log(f"{system}: model response not reproducible (chaotic or multi-stable): {', '.join(unreproducible)}")
    cands = candidates(system)
    if cfg.effects is not None:
        unknown = [e for e in cfg.effects if e not in cands]
        if unknown:
            raise UserError(f"diagnose.effects: {', '.join(unknown)} not an effect of {system} "
                            f"(known: {', '.join(cands)})")
        cands = {e: cands[e] for e in cfg.effects}
    scheme, folds = make_folds(targets, cfg)
    rng = np.random.default_rng(cfg.seed)
    names = ["base", *cands]
    test_res = {m: [] for m in ["default", *names]}
    test_halves = {m: [] for m in ["default", *names]}
    test_idx: list[int] = []
    bic = {m: 0.0 for m in names}
    cal_chi2 = {m: 0.0 for m in names}
    fits_per_fold = []
    warm = None
    executor = executor or InlineExecutor()

    def n_fit_tasks(n_folds: int, warm_start: bool) -> int:
        return fit_tasks(n_folds, len(cands), cfg.n_starts, cfg.candidate_starts, warm_start)
    if scheme != "holdout":   # reported parameters: a fit on all runs (also the folds' starting point)
        log(f"{system}: fit on all {len(targets)} runs (reported parameters)")
        progress.stage(f"{system}: base + {len(cands)} candidates on all {len(targets)} runs", n_fit_tasks(1, False))
        [(warm, lines)] = fit_models(ev, [list(range(len(targets)))], cfg, cands, rng, executor)
        for line in lines:
            log(line)
    progress.stage(f"{system}: base + {len(cands)} candidates on {len(folds)} fold(s)",
                   n_fit_tasks(len(folds), bool(warm)))
    fold_fits = fit_models(ev, [cal for cal, _ in folds], cfg, cands, rng, executor, warm)
    progress.stage(f"{system}: held-out errors of {len(cands) + 1} models")
    for fi, ((cal, test), (fits, lines)) in enumerate(zip(folds, fold_fits)):
        log(f"{system}: fold {fi + 1}/{len(folds)} ({len(cal)} calibration, {len(test)} held-out runs)")
        for line in lines:
            log(line)
        fits_per_fold.append(fits)
        sets = [{}] + [fits[m].values for m in names]
        for m, (res, halves) in zip(["default", *names], ev.held_out(sets, test)):
            test_res[m] += res
            test_halves[m] += halves
        test_idx += test
        for m in names:
            bic[m] += fits[m].bic()
            cal_chi2[m] += fits[m].chi2
    err = {m: {**_errors(ev, test_idx, test_res[m]), "systematic": systematic_error(ev, test_idx, test_halves[m])}
           for m in test_res}
    # reported parameters: the single split's calibration fit, or a fit on all runs (leave-one-out)
    final_fits = fits_per_fold[0] if scheme == "holdout" else warm
    stats = {m: ModelStats(m, bic[m], err[m]["chi2"], err[m]["n"], err[m]["systematic"]) for m in names}
    v = first = decide(stats["base"], [stats[m] for m in cands], cfg.rule())
    cal_names = [q.name for q in calibratable(system)]
    second = None
    # the second step runs whenever the leader leaves the held-out residual above the noise floor (nrms 1), adequate
    # or not: a weaker second effect (the drill's tip blunting beside guide friction) hides inside explained_nrms
    if (cfg.max_effects >= 2 and v.leader is not None and v.checks[v.leader]["nrms"] > NOISE_NRMS
            and len(cands) > 1):
        log(f"{system}: {v.leader} improves on the base but leaves the residual above the noise: adding a second effect")
        progress.stage(f"{system}: {v.leader} + each of {len(cands) - 1} other effects")
        pair_fits, pair_err, pair_stats, v2 = _second_effect(ev, cfg, scheme, folds, v.leader, cands, fits_per_fold,
                                                             warm, stats[v.leader], executor, log)
        second = _second_report(v.leader, pair_fits, pair_stats, v2, cfg.rule(), cal_names)
        final_fits = {**final_fits, **pair_fits}
        err.update(pair_err)
        pair_adequate = v2.leader is not None and v2.checks[v2.leader]["adequate"]
        if pair_adequate or (v2.leader is not None and v.kind != SELECTED):   # an adequate single stays
            kind = SELECTED if pair_adequate else UNEXPLAINED
            v = replace(v, kind=kind, selected=v2.leader if kind == SELECTED else None, leader=v2.leader)
    final = v.selected or "base"
    found = None
    if v.kind == UNEXPLAINED and cfg.max_proposals >= 1:
        log(f"{system}: no §6 effect explains the residual: proposing the missing term")
        progress.stage(f"{system}: proposing the missing term")
        found = discover(ev, cfg, scheme, folds, fits_per_fold, warm, stats["base"], executor, log)
    if found is not None and found.accepted:
        final = found.accepted
        final_fits = {**final_fits, final: found.fits[final]}
        err[final] = found.err[final]
    call = closeness(first, stats, cfg.rule())
    if second is not None:
        call["text"] = f"one effect: {call['text']}; two effects: {second['text']}"
    cand_list = [{"effect": m, "params": {p: final_fits[m].values[p] for p in final_fits[m].free if p not in cal_names},
                  "param_sd": {p: final_fits[m].sd[p] for p in final_fits[m].free},
                  "calibrated": final_fits[m].values,
                  "error": err[m]["error"], "nrms": err[m]["nrms"], "systematic": err[m]["systematic"],
                  "score": bic[m], "delta_score": bic[m] - bic["base"], "delta_chi2_heldout": v.checks[m]["delta_chi2"],
                  "improves": v.checks[m]["improves"], "adequate": v.checks[m]["adequate"],
                  "calibration_chi2": cal_chi2[m]} for m in sorted(cands, key=lambda m: bic[m])]
    report = {
        "system": system,
        "n_runs": len(targets),
        "unreproducible": unreproducible,
        "data": sorted({t.kind for t in targets}),
        "split": {"scheme": scheme, "held_out": [targets[i].run_id for i in sorted(set(test_idx))],
                  "folds": [{"calibration": [targets[i].run_id for i in c], "held_out": [targets[i].run_id for i in t]}
                            for c, t in folds]},
        "verdict": v.kind,
        "calibrated": final_fits["base"].values,
        "calibrated_uncertainty": _param_report(final_fits["base"]),
        "noise_floor": err["base"]["noise_floor"],
        "noise_sd": {t.run_id: t.noise for t in targets if t.noise},
        "default_error": err["default"]["error"], "base_error": err["base"]["error"],
        "final_error": err[final]["error"],
        "default_nrms": err["default"]["nrms"], "base_nrms": err["base"]["nrms"], "final_nrms": err[final]["nrms"],
        "base_systematic": err["base"]["systematic"], "final_systematic": err[final]["systematic"],
        "heldout_n": err["base"]["n"],
        "error_by_group": {"default": err["default"]["error_by_group"], "base": err["base"]["error_by_group"],
                           "final": err[final]["error_by_group"], "noise": err["base"]["noise_by_group"]},
        "base_score": bic["base"],
        "candidates": cand_list,
        "selected": v.selected,
        "selected_effects": v.selected.split("+") if v.selected else [],
        "leader": v.leader,
        "runner_up": v.runner_up,
        "selected_params": _param_report(final_fits[final]) if final != "base" else None,
        "explained": v.explained,
        "best_partial_candidate": v.leader if v.kind == UNEXPLAINED else None,
        "absorbed": absorbed_parameters(final_fits, v, cal_names),
        "call": call,
        "indistinguishable": indistinguishable(first, stats, cfg.rule()),
        "second_effect": second,
        "discrepancy": discovery_report(found, err["base"], cal_names) if found is not None else None,
        "proposal_adopted": proposal_terms(found.accepted) if found is not None and found.accepted else None,
        "n_simulations": ev.n_sims,
    }
    return SystemDiagnosis(report=report, evaluator=ev, fits=final_fits, held_out=test_idx, final=final)
