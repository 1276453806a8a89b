"""What ``vibro optimise`` writes of an :class:`~pipeline.optimise.workflow.OptimiseResult`: the report.json dict
(fixed keys, read by ``vibro report`` and ``vibro compare``), report.md, verified.csv, trials.csv and figures.

Called by ``outcome.optimise``; the command (``pipeline/cli/optimise.py``) picks the folder and logs the files to MLflow.
"""
from __future__ import annotations

import json
from collections import Counter
from dataclasses import asdict
from pathlib import Path

import numpy as np

from vibrobase.files import atomic_write_text, atomic_write_with
from vibrobase.jsonable import dump_json
from pipeline.optimise import plots
from pipeline.optimise.markdown import markdown
from pipeline.optimise.study import pareto_mask, value_columns
from pipeline.optimise.workflow import OptimisePlan, OptimiseResult, surrogate_failed

REPORT_KEYS = ("study_name", "inputs", "created", "tried", "recommendation", "feedback_rows", "feedback_file",
               "surrogate_note", "infill", "fallback", "outcome", "spread", "pareto_verified", "objectives", "figures", "metrics")
"""Keys of report.json in their order; feedback_rows/feedback_file, surrogate_note, infill, fallback, spread,
pareto_verified/objectives only when they apply."""


def run_params(plan: OptimisePlan) -> dict:
    """The run's parameters (MLflow params): the config's scalars, the objectives, the study, space and fixed values."""
    cfg, p = plan.config, plan.strategies.problem
    return {**{k: v for k, v in asdict(cfg).items() if k not in ("ranges", "fixed", "settings", "objectives")},
            "objectives": ",".join(plan.objective_names), "study_name": plan.study_name,
            "space": json.dumps(p.space.to_dict()), "fixed": json.dumps(p.fixed)}


def tried(res: OptimiseResult) -> dict:
    """report.json 'tried': the study's settings and what it did."""
    cfg, p = res.config, res.problem
    status_counts = dict(Counter(res.trials["status"].astype(str))) if len(res.trials) else {}
    out = {"mode": cfg.mode, "objective": cfg.objective, "objectives": res.objective_names, "sampler": cfg.sampler,
           "seed": cfg.seed, "model": p.model, "preset": p.preset, "fixed": p.fixed, "space": p.space.to_dict(),
           "constraints": res.constraints.to_dict(), "n_trials": int(len(res.trials)),
           "n_trials_run_now": res.n_trials_run_now, "n_feasible": res.n_feasible, "status_counts": status_counts,
           "storage": cfg.storage or "sqlite optuna.db at the project root",
           "simulator_calls_study": res.simulator_calls_study, "n_verified": res.n_verified}
    if res.closest is not None:
        out["closest"] = res.closest
    out["simulator_calls"] = res.simulator_calls
    return out


def surrogate_note(res: OptimiseResult, feedback_file: str | None) -> str:
    """Where the surrogate was wrong (or that it agreed), and where the verified points went."""
    table, names = res.verified, res.objective_names
    n_wrong = res.n_surrogate_wrong
    note = (f"The surrogate was wrong at {n_wrong} of {len(table)} verified points "
            f"({'; '.join(sorted(set(w for w in table['why'] if w)))}). "
            if n_wrong else f"The surrogate agreed with the simulator at all {len(table)} verified points "
                            f"({', '.join(names)} within {res.config.rel_tol:.0%}, same feasibility). ")
    if feedback_file:
        note += f"All {len(table)} verified points were appended to {feedback_file} for retraining."
    return note


def report_dict(res: OptimiseResult, figures: list[str], feedback_rows: int | None = None,
                feedback_file: str | None = None, failed: OptimiseResult | None = None, infill=None,
                spread=None) -> dict:
    """report.json of ``res``: keys :data:`REPORT_KEYS`; ``feedback_rows`` rows now in ``feedback_file``.
    ``failed``: the surrogate study that failed its verification, when ``res`` is the simulator study replacing it.
    ``infill``: the infill loop's :class:`~pipeline.optimise.infill.InfillReport`, when one ran.  ``spread``: the
    recommendation's ROP spread on the rig (:class:`~pipeline.optimise.robustness.RopSpread`), when one was taken."""
    rep = {"study_name": res.study_name, "inputs": res.problem.space.names, "created": res.created,
           "tried": tried(res), "recommendation": res.recommendation}
    first = failed or res
    if first.verified is not None:
        if feedback_file:
            rep["feedback_rows"] = feedback_rows
            rep["feedback_file"] = feedback_file
        if first.config.mode == "surrogate":
            rep["surrogate_note"] = surrogate_note(first, feedback_file)
    if infill is not None:
        rep["infill"] = infill.to_json()
    if failed is not None:
        why = surrogate_failed(failed)
        best = failed.recommendation or {}
        rep["fallback"] = {"reason": why, "surrogate_study": failed.study_name,
                           "surrogate_outcome": failed.outcome, "simulator_study": res.study_name,
                           "n_trials": int(len(res.trials)),
                           "surrogate_n_wrong": failed.n_surrogate_wrong,
                           "surrogate_n_verified": int(len(failed.verified)),
                           "surrogate_best_rop_m_s_pred": best.get("rop_m_s_pred"),
                           "surrogate_best_rop_m_s_sim": best.get("rop_m_s_sim"),
                           "text": f"{why}: the recommendation comes from a study of "
                                   f"{len(res.trials)} trials straight on the simulator, not from the surrogate"}
    rep["outcome"] = res.outcome
    if spread is not None:
        rep["spread"] = spread.to_dict()
    if res.pareto_verified is not None:
        rep["pareto_verified"] = res.pareto_verified
        rep["objectives"] = res.objective_names
    rep["figures"] = figures
    # the surrogate's wrong count is the surrogate study's, also when the simulator study replaced it: one number
    rep["metrics"] = {**res.metrics(), "n_surrogate_wrong": first.n_surrogate_wrong,
                      "surrogate_fallback": failed is not None}
    if infill is not None:      # what the loop cost: infill points and the later rounds' verifications
        rep["metrics"].update({"infill_rounds": infill.n_rounds, "infill_simulations": infill.simulations,
                               "infill_agreed": infill.agreed})
    if spread is not None:      # its half-widths, and the simulations it took (the nominal point and the samples)
        rep["metrics"].update({"spread_simulations": spread.n_samples + 1,
                               "rop_m_s_parameter_half_width": spread.parameter_half_width_m_s,
                               "rop_m_s_combined_half_width": spread.combined_half_width_m_s})
    return rep


def write_tables(res: OptimiseResult, out: Path) -> list[Path]:
    """verified.csv (when something was verified) and trials.csv (when the study holds trials); returns the files."""
    files = []
    if res.verified is not None:
        atomic_write_with(out / "verified.csv", lambda tmp: res.verified.to_csv(tmp, index=False))
        files.append(out / "verified.csv")
    if len(res.trials):
        atomic_write_with(out / "trials.csv", lambda tmp: res.trials.to_csv(tmp, index=False))
        files.append(out / "trials.csv")
    return files


def write_figures(res: OptimiseResult, out: Path) -> list[str]:
    """history.png, importances.png (when optuna can rank the inputs), verification.png, pareto.png; their paths."""
    cfg, trials, table, names = res.config, res.trials, res.verified, res.objective_names
    figs = [plots.plot_history(trials, out / "history.png", f"{res.study_name}: ROP per trial ({cfg.mode})")]
    imp = plots.plot_importances(res.study, out / "importances.png", f"{cfg.mode} study: input importance")
    if imp:
        figs.append(imp)
    if table is not None:
        figs.append(plots.plot_verification(table, out / "verification.png", "surrogate vs simulator"
                                            if cfg.mode == "surrogate" else "study vs re-simulation"))
    if cfg.objective == "pareto" and len(trials) and trials["feasible"].any():
        cols = value_columns(len(res.objectives))
        feas = trials[trials["feasible"] & np.all(np.isfinite(trials[cols].to_numpy(float)), axis=1)]
        front = feas[pareto_mask(*(feas[c].to_numpy(float) for c in cols), directions=[d for _, d in res.objectives])]
        figs.append(plots.plot_pareto(trials, front, table, out / "pareto.png",
                                      f"{res.study_name}: {names[0]} vs {names[1]}", names[:2]))
    return figs


def write_report(rep: dict, res: OptimiseResult, out: Path) -> list[Path]:
    """report.json and report.md of ``rep``; returns the two files."""
    atomic_write_text(out / "report.json", dump_json(rep))
    atomic_write_text(out / "report.md", markdown(rep, res.verified))
    return [out / "report.json", out / "report.md"]
