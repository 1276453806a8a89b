"""ROP optimisation: optuna studies on the surrogate or the simulator, verified by the simulator.

``plan_optimise(OptimiseConfig(...), strategies)`` checks the problem and opens (or resumes) the study;
``run_optimise(plan)`` runs it, re-simulates the candidates, compares prediction and simulation and returns an
:class:`OptimiseResult`.  The recommendation is always the best *verified* feasible point, never an unverified
prediction.  Nothing here writes a file but the optuna storage: ``outcome.optimise`` builds the strategies, appends
the feedback, runs the fallback study and writes the report (``outputs.py``); ``vibro optimise`` opens MLflow.
"""
from __future__ import annotations

import hashlib
import json
from collections import Counter
from dataclasses import dataclass, replace
from datetime import datetime, timezone

import numpy as np
import pandas as pd

from pipeline.optimise.config import DEFAULT_TRIALS, MODES, OptimiseConfig
from pipeline.optimise.constraints import LIMITED_LABELS, UPPER_LIMITS, Constraints, progress_force_floor
from pipeline.optimise.coordination import batch_seed, guard_for
from pipeline.optimise.space import Space, describe_bounds
from pipeline.optimise.strategies import Problem, Strategies
from pipeline.optimise.study import default_storage, open_study, pareto_mask, pick_candidates, trials_frame
from pipeline.optimise.verify import best_verified, compare

__all__ = ["DEFAULT_TRIALS", "MODES", "OptimiseConfig", "OptimisePlan", "OptimiseResult", "fallback_config",
           "plan_optimise", "run_optimise", "seed_with_verified", "surrogate_failed"]


@dataclass(frozen=True)
class OptimisePlan:
    """A checked problem with its study opened (or resumed) in the storage, ready to run."""
    config: OptimiseConfig
    strategies: Strategies
    constraints: Constraints
    objectives: list[tuple[str, str]]       # [(label, 'maximize'|'minimize')]
    study_name: str
    signature: dict                         # what a resumed study must match
    study: object                           # the optuna study
    sampler: object                         # the study's first sampler

    @property
    def objective_names(self) -> list[str]:
        return [n for n, _ in self.objectives]

    def sampler_for(self, n_done: int):
        """The sampler of the batch starting at trial ``n_done``: a resumed study proposes what an uninterrupted one did."""
        return self.strategies.sampler(batch_seed(self.config.seed, n_done), len(self.objectives),
                                       _n_startup(self.config.total_trials))


@dataclass(frozen=True)
class OptimiseResult:
    """What the study found and what the simulator said of it (ROP in m/s, power in W, forces in N)."""
    config: OptimiseConfig
    problem: Problem
    constraints: Constraints
    objectives: list[tuple[str, str]]
    study_name: str
    created: str                            # UTC ISO time the study's trials were read
    study: object                           # the optuna study: every complete trial
    trials: pd.DataFrame                    # complete trials (study.trials_frame)
    n_trials_run_now: int
    simulator_calls_study: int              # simulator calls of the study (0 on the surrogate)
    simulator_calls: int                    # ... plus the verification's
    verified: pd.DataFrame | None           # prediction next to simulation per candidate (verify.compare)
    simulated: pd.DataFrame | None          # the simulator's rows of the candidates (the feedback rows)
    recommendation: dict | None             # the best verified feasible point, None when none
    outcome: str                            # one sentence: the answer or why there is none
    pareto_verified: list[dict] | None      # objective='pareto' with candidates: the verified front
    closest: dict | None                    # no feasible trial: the one closest to feasibility

    @property
    def objective_names(self) -> list[str]:
        return [n for n, _ in self.objectives]

    @property
    def n_verified(self) -> int:
        return 0 if self.simulated is None else len(self.simulated)

    @property
    def n_surrogate_wrong(self) -> int:
        return int(self.verified["surrogate_wrong"].sum()) if self.verified is not None else 0

    @property
    def n_feasible(self) -> int:
        return int(self.trials["feasible"].sum()) if len(self.trials) else 0

    def metrics(self) -> dict:
        """The small metrics dict (report.json 'metrics', the --metrics file, MLflow)."""
        out = {"feasible": self.recommendation is not None, "n_trials": int(len(self.trials)),
               "n_feasible_trials": self.n_feasible, "simulator_calls": self.simulator_calls,
               "n_verified": self.n_verified, "n_surrogate_wrong": self.n_surrogate_wrong}
        if self.config.objective == "pareto":
            out["n_pareto_verified"] = len(self.pareto_verified or [])
        r = self.recommendation
        if r:
            out.update({"best_rop_m_s": r["rop_m_s_sim"], "best_rop_m_s_predicted": r.get("rop_m_s_pred"),
                        "best_rop_rel_error": r.get("rop_rel_error"), "best_power_w": r.get("power_w_sim"),
                        "best_peak_decel_g": r.get("peak_decel_g_sim"), "best_n_on_bounds": len(r["on_bounds"]),
                        **{f"best_{n}": v for n, v in r["params"].items()}})
            for m in r.get("margins", []):      # with --margin: the margin kept and the headroom left per limit
                out[f"margin_{m['label']}"] = m["margin"]
                out[f"headroom_{m['label']}"] = m["headroom"]
            if "on_envelope" in r:              # with a rig's exciter envelope: how many of its limits bind
                out["best_n_on_envelope"] = len(r["on_envelope"])
        return out


def _n_startup(n_trials: int) -> int:
    """Random startup trials of a sampler: a fifth of the study, between 5 and 20."""
    return min(20, max(n_trials // 5, 5))


def _binding(cons: Constraints, row) -> list[str]:
    """Limits the verified point sits at (within 5 % below the limit, less its margin): the constraints that shape
    the answer."""
    out = []
    for key, (label, attr) in UPPER_LIMITS.items():
        lim, v = getattr(cons, attr), row.get(f"{label}_sim")
        if lim is not None and v is not None and not pd.isna(v) and float(v) >= 0.95 * cons.limit_of(label, lim):
            kept = f" less its margin, {cons.limit_of(label, lim):.4g}" if label in cons.margins else ""
            out.append(f"{label} {float(v):.4g} of its limit {lim:g}{kept}")
    return out


def _margins(cons: Constraints, row) -> list[dict]:
    """The margin kept on each limit with one: label, limit, margin (fraction), the value kept below, the simulated
    value and its headroom below the limit (fraction of the limit, >= the margin when kept)."""
    out = []
    for label, attrs in LIMITED_LABELS.items():
        if label not in cons.margins:
            continue
        for attr in attrs:
            lim = getattr(cons, attr)
            if lim is None or attr == "peak_force_static_ratio":
                continue
            v = row.get(f"{label}_sim")
            v = None if v is None or pd.isna(v) else float(v)
            out.append({"label": label, "limit": float(lim), "margin": float(cons.margins[label]),
                        "kept_below": cons.limit_of(label, lim), "value_sim": v,
                        "headroom": None if v is None else (lim - v) / lim})
    return out


def _outcome(rec: dict) -> str:
    """One sentence: the verified point, the limits it sits at, and any bound of the search space it lies on."""
    text = (f"recommended point verified by the simulator: ROP {rec['rop_m_s_sim'] * 1e3:.4g} mm/s at "
            + ", ".join(f"{n} = {v:.4g}" for n, v in rec["params"].items()))
    if rec.get("binding"):
        text += "; at the limit(s): " + ", ".join(rec["binding"])
    if rec.get("margins"):
        text += "; margin kept: " + ", ".join(
            f"{m['label']} {m['value_sim']:.4g} <= {m['kept_below']:.4g} ({m['margin']:.0%} below {m['limit']:g})"
            for m in rec["margins"] if m["value_sim"] is not None)
    if rec.get("on_envelope"):
        text += "; ON THE SHAKER'S ENVELOPE: " + ", ".join(rec["on_envelope"])
    if rec.get("on_bounds"):
        text += ("; ON THE EDGE of the search space: " + describe_bounds(rec["on_bounds"])
                 + " (the optimum may lie beyond it: widen that range to know)")
    return text


def _verified_front(table: pd.DataFrame, objectives: list[tuple[str, str]], space: Space) -> list[dict]:
    """Non-dominated feasible verified points by their *simulated* objectives, sorted by the first."""
    names = [n for n, _ in objectives]
    cols = [f"{n}_sim" for n in names]
    ok = table[table["feasible_sim"]]
    ok = ok[np.all(np.isfinite(ok[cols].to_numpy(float)), axis=1)] if len(ok) else ok
    if ok.empty:
        return []
    m = pareto_mask(*(ok[c].to_numpy(float) for c in cols), directions=[d for _, d in objectives])
    front = ok[m].drop_duplicates(subset=cols).sort_values(cols[0])
    return [{**{n: float(r[c]) for n, c in zip(names, cols)}, "params": {n: float(r[n]) for n in space.names}}
            for _, r in front.iterrows()]


def _recommend(best, space: Space, cons: Constraints, sim_row: dict | None = None) -> dict:
    """The recommendation of the best verified row: controls, simulated (and predicted) labels, bounds, limits."""
    rec = {"params": {n: float(best[n]) for n in space.names},
           **{k: (None if pd.isna(best.get(k)) else float(best[k])) for k in
              ("rop_m_s_sim", "rop_m_s_pred", "rop_m_s_lo", "rop_m_s_hi", "peak_force_n_sim",
               "specific_energy_j_m_sim", "impacts_per_cycle_sim", "power_w_sim", "power_w_pred",
               "peak_decel_g_sim", "peak_decel_g_pred", "rop_rel_error") if k in best},
           "status_sim": best["status_sim"], "surrogate_wrong": bool(best["surrogate_wrong"])}
    rec["on_bounds"] = space.on_bounds(rec["params"])
    rec["binding"] = _binding(cons, best)
    if cons.margins:        # only then: report.json keeps the keys it always had
        rec["margins"] = _margins(cons, best)
    if cons.envelope is not None:
        row = {**{n: float(best[n]) for n in space.names}, **(sim_row or {})}
        rec["on_envelope"] = cons.envelope.on_envelope(row)
        rec.update({f"{k}_sim": sim_row.get(k) for k in ("stroke_m", "coil_velocity_m_s")
                    if sim_row and k in sim_row})
    return rec


def signature(cfg: OptimiseConfig, strategies: Strategies, cons: Constraints) -> dict:
    """What a study is: a resumed study must have the same (study.open_study), and its default name hashes it."""
    p = strategies.problem
    return {"mode": cfg.mode, "model": p.model, "preset": p.preset, "fixed": p.fixed, "space": p.space.to_dict(),
            "constraints": cons.to_dict(), "objective": cfg.objective,
            "objectives": [f"{d[:3]}:{n}" for n, d in cfg.objective_list()], "sampler": cfg.sampler, "seed": cfg.seed,
            "surrogate_fingerprint": strategies.fingerprint, "settings": cfg.settings,
            **({"rop_correction": cfg.rop_correction} if cfg.rop_correction else {})}


def plan_optimise(cfg: OptimiseConfig, strategies: Strategies) -> OptimisePlan:
    """Check the constraints against the problem, name the study and open (or resume) it in ``cfg.storage``.

    UserError for contradictory constraints, or a stored study of that name run with other settings."""
    cfg = replace(cfg)      # a copy, validated again: the caller may have changed fields since
    p = strategies.problem
    cons = cfg.constraints()
    objectives = cfg.objective_list()
    static = p.space.ranges.get("static_force_n") or (strategies.simulator.resolved["static_force_n"],) * 2
    cons.check(static, progress_force_floor(p.model, strategies.simulator.resolved))
    sig = signature(cfg, strategies, cons)
    digest = hashlib.sha256(json.dumps(sig, sort_keys=True, default=str).encode()).hexdigest()[:10]
    name = cfg.study_name or f"{cfg.mode}-{cfg.objective}-{p.model}-{p.preset}-{digest}"
    sampler = strategies.sampler(cfg.seed, len(objectives), _n_startup(cfg.total_trials))
    study = open_study(cfg.storage, name, objectives, sampler, sig, heartbeat_s=cfg.heartbeat_s)
    return OptimisePlan(cfg, strategies, cons, objectives, name, sig, study, sampler)


def run_optimise(plan: OptimisePlan, progress: bool = True) -> OptimiseResult:
    """Run the study of ``plan`` up to its trial count, re-simulate the candidates and pick the recommendation."""
    cfg, s, cons, objectives = plan.config, plan.strategies, plan.constraints, plan.objectives
    space = s.problem.space
    study, ran = s.executor(plan.study, plan.sampler, s.evaluator, space, cons, objectives, cfg.total_trials,
                            cfg.batch_size, progress=progress, desc=f"optimise {cfg.mode}",
                            sampler_factory=plan.sampler_for, guard=guard_for(cfg.storage or default_storage()))
    study_sim_calls = s.simulator.calls
    trials = trials_frame(study, space)
    created = datetime.now(timezone.utc).isoformat(timespec="seconds")
    cands = pick_candidates(trials, space, cfg.objective, cfg.n_verify, directions=[d for _, d in objectives])
    table = simres = rec = front = closest = None
    if cands.empty:
        if len(trials):
            c = trials.sort_values("violation").iloc[0]
            closest = {**{n: float(c[n]) for n in space.names}, "violation": float(c["violation"]),
                       "status": c.get("status")}
        outcome = (f"no feasible point among {len(trials)} trials of the {cfg.mode} study: nothing verified, "
                   f"nothing recommended — relax the constraints or widen the ranges")
    else:
        inputs = cands[space.names]
        # the study's own trials are the simulator's labels when it asked the simulator
        pred = cands.rename(columns={}) if s.evaluator is s.simulator else s.evaluator(inputs)
        simres = s.simulator(inputs)
        table = compare(pred, simres, space.names, cons, cfg.rel_tol, objectives=plan.objective_names)
        best = best_verified(table)
        if best is None:
            outcome = (f"none of the {len(table)} points the study found feasible is feasible when simulated "
                       f"(statuses {dict(Counter(table['status_sim']))}): nothing recommended")
        else:
            sim_row = simres.reset_index(drop=True).iloc[int(best.name)].to_dict()
            rec = _recommend(best, space, cons, {k: v for k, v in sim_row.items() if k in space.names or
                                                 k in ("stroke_m", "coil_velocity_m_s", "frequency_hz", "amplitude_n")})
            outcome = _outcome(rec)
        if cfg.objective == "pareto":
            front = _verified_front(table, objectives, space)
    return OptimiseResult(cfg, s.problem, cons, objectives, plan.study_name, created, study, trials, ran,
                          study_sim_calls, s.simulator.calls, table, simres, rec, outcome, front, closest)


def surrogate_failed(res: OptimiseResult) -> str | None:
    """Why a surrogate study failed its verification (its recommended point, or more than half of the verified
    points, wrong), None when it did not or was no surrogate study."""
    if res.config.mode != "surrogate" or res.verified is None or not len(res.verified):
        return None
    n, wrong = len(res.verified), res.n_surrogate_wrong
    rec_wrong = bool(res.recommendation and res.recommendation.get("surrogate_wrong"))
    if not (rec_wrong or wrong > n / 2):
        return None
    return (f"the surrogate was wrong at {wrong} of {n} verified points"
            + (", the recommended one among them" if rec_wrong else ""))


def seed_with_verified(plan: OptimisePlan, failed: OptimiseResult) -> int:
    """Queue the failed surrogate study's verified points as the first trials of ``plan``'s simulator study (once:
    a resumed study skips those it holds), so the fallback's answer is never worse than what was verified."""
    from pipeline.optimise.coordination import WORKER_ATTR, worker_id

    if failed.verified is None:
        return 0
    pts = failed.verified[failed.problem.space.names].to_dict("records")
    for pt in pts:      # tagged as this worker's: an untagged waiting trial is a dead worker's to the study guard
        plan.study.enqueue_trial({k: float(v) for k, v in pt.items()}, user_attrs={WORKER_ATTR: worker_id()},
                                 skip_if_exists=True)
    return len(pts)


def fallback_config(res: OptimiseResult) -> OptimiseConfig:
    """The study straight on the simulator that replaces a failed surrogate's: the same model, preset, fixed values
    (the rig), space, constraints and objective, ``fallback_trials`` trials."""
    p = res.problem
    return replace(res.config, mode="simulator", surrogate=None, model=p.model, preset=p.preset, fixed=dict(p.fixed),
                   ranges=p.space.to_dict(), n_trials=res.config.fallback_trials, study_name=None)
