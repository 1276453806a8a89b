"""ROP optimisation: optuna studies on the surrogate or the simulator, verified by the simulator.

``run_optimise(OptimiseConfig(...), out_dir)`` runs (or resumes) a study, re-simulates the
recommended points, compares prediction and simulation, appends the verified points to a
feedback file (closing the loop) and writes ``report.json``, ``report.md``, ``verified.csv``,
``trials.csv`` and figures under ``out_dir``.  The recommendation is always the best *verified*
feasible point, never an unverified prediction.  Parts live in ``pipeline/optim/``.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
from collections import Counter
from dataclasses import asdict, dataclass, field, fields
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.core.jsonable import dump_json
from pipeline.core.errors import UserError
from sim.registry import DEFAULT_MODEL
from pipeline.optimise import plots
from pipeline.optimise.constraints import UPPER_LIMITS, Constraints, progress_force_floor
from pipeline.optimise.evaluators import SimulatorEvaluator, SurrogateEvaluator
from pipeline.core.names import display
from pipeline.optimise.space import Space, default_space, describe_bounds, space_from_mapping
from pipeline.optimise.study import (DEFAULT_PARETO, OBJECTIVES, SAMPLERS, default_storage, make_sampler, open_study,
                                     parse_objectives, pick_candidates, run_study, run_study_buffered, trials_frame,
                                     pareto_mask, value_columns)
from pipeline.optimise.verify import append_feedback, best_verified, compare
from pipeline.core.files import atomic_write_text, atomic_write_with

MODES = ("surrogate", "simulator")
DEFAULT_TRIALS = {"surrogate": 600, "simulator": 200}


@dataclass
class OptimiseConfig:
    """Keys of the ``optimise`` section of params.yaml (CLI flags override them).

    mode: 'surrogate' (study on the bundle at ``surrogate``, then verification) or 'simulator'
    (study directly on the simulator).  objective: 'rop' (maximise ROP) or 'pareto' (the front of
    ``objectives``, default ROP against the mean power: ``["rop_m_s", "power_w"]``; any labels, each with
    an optional ``max:``/``min:`` prefix, ROP maximised and the rest minimised by default).  max_power_w [W],
    max_decel_g [g]: the exciter's power rating and the bit's deceleration limit (None = unconstrained).  ranges: {name: [low, high]} — default: the surrogate's training
    ranges / the model's published space (ModelSpec.search_spaces).  n_trials: total complete trials
    of the study (a resumed study runs only the rest; default 600 on the surrogate, 200 on the
    simulator = simulator calls).  n_verify: points re-simulated (distinct best / spread along the
    front).  rel_tol: relative ROP error above which the surrogate is called wrong.
    """

    mode: str = "surrogate"
    surrogate: str | None = "models/surrogate"
    model: str = DEFAULT_MODEL
    preset: str | None = "lab"
    objective: str = "rop"
    ranges: dict = field(default_factory=dict)
    fixed: dict = field(default_factory=dict)
    sampler: str = "tpe"
    n_trials: int | None = None
    batch_size: int = 8
    seed: int = 0
    max_peak_force_n: float | None = None
    peak_force_static_ratio: float | None = None
    max_specific_energy_j_m: float | None = None
    max_power_w: float | None = None
    max_decel_g: float | None = None
    objectives: list[str] | None = None
    allow_not_settled: bool = False
    n_verify: int = 10
    rel_tol: float = 0.10
    storage: str | None = None
    study_name: str | None = None
    feedback: str | None = None
    n_threads: int | None = None
    settings: dict | None = None

    @classmethod
    def from_mapping(cls, d: dict | None) -> "OptimiseConfig":
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d or {}) - known)
        if unknown:
            raise UserError(f"params.yaml optimise: unknown key(s) {unknown}; known: {', '.join(sorted(known))}")
        return cls(**(d or {}))

    def validate(self) -> "OptimiseConfig":
        if self.mode not in MODES:
            raise UserError(f"mode must be one of {MODES}, got '{self.mode}'")
        if self.objective not in OBJECTIVES:
            raise UserError(f"objective must be one of {OBJECTIVES}, got '{self.objective}'")
        if self.sampler not in SAMPLERS:
            raise UserError(f"sampler must be one of {SAMPLERS}, got '{self.sampler}'")
        for name in ("batch_size", "n_verify"):
            if int(getattr(self, name)) < 1:
                raise UserError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.n_trials is not None and int(self.n_trials) < 1:
            raise UserError(f"n_trials must be >= 1, got {self.n_trials}")
        if not (self.rel_tol > 0):
            raise UserError(f"rel_tol must be > 0, got {self.rel_tol}")
        self.objective_list()
        if self.mode == "surrogate" and not self.surrogate:
            raise UserError("mode 'surrogate' needs a surrogate bundle (--surrogate DIR or MLflow run id)")
        return self

    def objective_list(self) -> list[tuple[str, str]]:
        """[(label, 'maximize'|'minimize')] of the study: ROP alone, or the Pareto objectives."""
        from sim import LABELS

        if self.objective == "rop":
            return [("rop_m_s", "maximize")]
        return parse_objectives(self.objectives or list(DEFAULT_PARETO), LABELS)

    def constraints(self) -> Constraints:
        return Constraints(max_peak_force_n=self.max_peak_force_n, peak_force_static_ratio=self.peak_force_static_ratio,
                           max_specific_energy_j_m=self.max_specific_energy_j_m, max_power_w=self.max_power_w,
                           max_decel_g=self.max_decel_g,
                           require_settled=not self.allow_not_settled, require_progress=self.objective == "pareto")


def _check_surrogate_labels(evaluate, space: Space, objectives: list[str], cons: Constraints, ref) -> None:
    """UserError naming the label when the surrogate predicts no value for an objective or a constrained label."""
    needed = list(objectives) + [label for key, (label, attr) in UPPER_LIMITS.items() if getattr(cons, attr) is not None]
    centre = pd.DataFrame([{n: 0.5 * (lo + hi) for n, (lo, hi) in space.ranges.items()}])
    have = set(evaluate(centre).columns)
    missing = [n for n in dict.fromkeys(needed) if n not in have]
    if missing:
        raise UserError(f"the surrogate {ref} predicts no {', '.join(missing)}: retrain it (vibro train) with "
                        f"{', '.join(missing)} among train.targets, or optimise with --simulator")


def _binding(cons: Constraints, row) -> list[str]:
    """Limits the verified point sits at (within 5 % below the limit): the constraints that shape the answer."""
    out = []
    for key, (label, attr) in UPPER_LIMITS.items():
        lim, v = getattr(cons, attr), row.get(f"{label}_sim")
        if lim is not None and v is not None and not pd.isna(v) and float(v) >= 0.95 * lim:
            out.append(f"{label} {float(v):.4g} of its limit {lim:g}")
    return out


def _outcome(rec: dict) -> str:
    """One sentence: the verified point, the limits it sits at, and any bound of the search space it lies on."""
    text = (f"recommended point verified by the simulator: ROP {rec['rop_m_s_sim'] * 1e3:.4g} mm/s at "
            + ", ".join(f"{n} = {v:.4g}" for n, v in rec["params"].items()))
    if rec.get("binding"):
        text += "; at the limit(s): " + ", ".join(rec["binding"])
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


def _setup(cfg: OptimiseConfig, bundle):
    """Model, preset, fixed values, space and evaluators of a run (validated)."""
    import sim

    if cfg.mode == "surrogate":
        model, preset = bundle.model, bundle.preset
        fixed = {**bundle.fixed, **cfg.fixed}     # the sweep's conditions, overridden by the user's
        full = Space({n: (float(bundle.ranges[n][0]), float(bundle.ranges[n][1])) for n in bundle.inputs})
        space = space_from_mapping(cfg.ranges) if cfg.ranges else full
        if cfg.ranges:
            missing = [n for n in bundle.inputs if n not in space.ranges]
            for n in missing:   # inputs the user did not restrict keep the surrogate's range
                space.ranges[n] = full.ranges[n]
            outside = full.contains(space)
            if outside:
                raise UserError(f"range(s) {outside} leave the surrogate's training ranges "
                                f"{ {n: full.ranges[n] for n in outside if n in full.ranges} }: "
                                f"the surrogate cannot be trusted there (sweep and train on a wider space)")
    else:
        model, preset, fixed = cfg.model, cfg.preset, dict(cfg.fixed)
        space = space_from_mapping(cfg.ranges) if cfg.ranges else default_space(model, preset)
        if space is None:
            raise UserError(f"no search space: give ranges (--range NAME=LOW:HIGH) — model '{model}' preset "
                            f"'{preset}' publishes no default space")
    spec = sim.get_model(model)
    space.validate(spec.param_names)
    clash = sorted(set(fixed) & set(space.ranges))
    if clash:
        raise UserError(f"parameter(s) {clash} are both fixed and searched; drop one")
    settings = cfg.settings if cfg.settings is not None or bundle is None else (bundle.settings or None)
    simulator = SimulatorEvaluator(model, preset, fixed, settings=settings, n_threads=cfg.n_threads)
    study_eval = SurrogateEvaluator(bundle, fixed) if cfg.mode == "surrogate" else simulator
    return model, preset, fixed, space, simulator, study_eval


def _signature(cfg: OptimiseConfig, model, preset, fixed, space: Space, cons: Constraints, bundle) -> dict:
    return {"mode": cfg.mode, "model": model, "preset": preset, "fixed": fixed, "space": space.to_dict(),
            "constraints": cons.to_dict(), "objective": cfg.objective,
            "objectives": [f"{d[:3]}:{n}" for n, d in cfg.objective_list()], "sampler": cfg.sampler, "seed": cfg.seed,
            "surrogate_fingerprint": getattr(bundle, "fingerprint", None) if bundle is not None else None,
            "settings": cfg.settings}


def _fmt(v, unit: str = "") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.4g}{unit}"
    return f"{v}{unit}"


def _eng(name: str, v) -> str:
    """A value of a label or control in its engineering unit (mm/s, kW, g, kN: pipeline.core.names.DISPLAY_UNITS)."""
    if v is None or isinstance(v, (bool, str)) or (isinstance(v, float) and math.isnan(v)):
        return _fmt(v)
    return _fmt(display(name, v)[0])


def _head(name: str, suffix: str = "") -> str:
    """Column heading 'name suffix [unit]'."""
    unit = display(name, 0.0)[1]
    return f"{name}{suffix}" + (f" [{unit}]" if unit else "")


def _markdown(rep: dict, table: pd.DataFrame | None) -> str:
    t = rep["tried"]
    lines = [f"# Optimisation report — {rep['study_name']}", "", f"**Outcome:** {rep['outcome']}", ""]
    rec = rep.get("recommendation")
    if rec:
        labels = [k for k in ("rop_m_s", "power_w", "peak_decel_g", "peak_force_n", "specific_energy_j_m")
                  if rec.get(f"{k}_sim") is not None]
        lines += ["## Recommendation (verified by the simulator)", "",
                  "| " + " | ".join(_head(n) for n in rec["params"]) + " | "
                  + " | ".join(_head(k, " simulated") for k in labels) + " | ROP predicted [mm/s] | status |",
                  "|" + "---|" * (len(rec["params"]) + len(labels) + 2),
                  "| " + " | ".join(_eng(n, v) for n, v in rec["params"].items()) + " | "
                  + " | ".join(_eng(k, rec[f"{k}_sim"]) for k in labels)
                  + f" | {_eng('rop_m_s', rec.get('rop_m_s_pred'))} | {rec['status_sim']} |", ""]
        if rec.get("binding"):
            lines += ["At the limit(s): " + ", ".join(rec["binding"]) + ".", ""]
        if rec.get("on_bounds"):
            lines += ["**On the edge of the search space:** " + describe_bounds(rec["on_bounds"])
                      + ". The optimum may lie beyond this bound; widen that range (sweep and train on it) to know.", ""]
        else:
            lines += ["The recommendation lies inside the search space (no control within 2 % of a bound).", ""]
    lines += ["## What was tried", "",
              f"- mode: {t['mode']} (study on the {'surrogate, then re-simulated' if t['mode'] == 'surrogate' else 'simulator'}),"
              f" objective: {t['objective']} ({', '.join(t.get('objectives', []))}), sampler: {t['sampler']}, seed {t['seed']}",
              f"- model: {t['model']}, preset: {t['preset']}, fixed: {t['fixed'] or 'none'}",
              f"- space: " + ", ".join(f"{n} ∈ [{r['low']:g}, {r['high']:g}]" for n, r in t["space"].items()),
              f"- constraints: " + (", ".join(f"{k} = {v}" for k, v in t["constraints"].items() if v not in (None, False))
                                    or "none"),
              f"- trials: {t['n_trials']} complete ({t['n_trials_run_now']} run now), feasible: {t['n_feasible']}, "
              f"statuses: {t['status_counts']}",
              f"- simulator calls: {t['simulator_calls']} (study {t['simulator_calls_study']}, verification "
              f"{t['n_verified']})", f"- storage: {t['storage']}", ""]
    if t.get("closest"):
        lines += [f"- closest point to feasibility: {t['closest']}", ""]
    if table is not None and len(table):
        shown = ["rop_m_s", *[o for o in t.get("objectives", []) if o != "rop_m_s"]]
        shown += [k for k in ("power_w", "peak_decel_g") if k not in shown and f"{k}_sim" in table]
        cols = [c for c in table.columns if c in rep["inputs"]]
        for k in shown:
            cols += [c for c in (f"{k}_pred", f"{k}_sim") if c in table.columns]
        cols += [c for c in ("status_pred", "status_sim", "feasible_sim", "surrogate_wrong", "why") if c in table.columns]
        heads = [_head(c[:-5], " pred") if c.endswith("_pred") and c[:-5] in shown else
                 _head(c[:-4], " sim") if c.endswith("_sim") and c[:-4] in shown else _head(c) if c in rep["inputs"]
                 else c for c in cols]
        name_of = {c: (c[:-5] if c.endswith("_pred") else c[:-4] if c.endswith("_sim") else c) for c in cols}
        lines += ["## Prediction next to the simulator (every optimised objective)", "",
                  "| " + " | ".join(heads) + " |", "|" + "---|" * len(cols)]
        for _, r in table.iterrows():
            lines.append("| " + " | ".join(_eng(name_of[c], r[c]) if name_of[c] in shown or c in rep["inputs"]
                                           else _fmt(r[c]) for c in cols) + " |")
        lines.append("")
    if rep.get("surrogate_note"):
        lines += ["## Surrogate check", "", rep["surrogate_note"], ""]
    front = rep.get("pareto_verified")
    if rep.get("objectives"):
        names = rep["objectives"]
        lines += [f"## Verified Pareto front ({' vs '.join(names)})", ""]
        if front:
            lines += [f"{len(front)} distinct non-dominated points, each re-simulated:", "",
                      "| " + " | ".join(_head(n) for n in names) + " | " + " | ".join(_head(n) for n in rep["inputs"])
                      + " |", "|" + "---|" * (len(names) + len(rep["inputs"]))]
            for p in front:
                lines.append("| " + " | ".join(_eng(n, p[n]) for n in names) + " | "
                             + " | ".join(_eng(n, p["params"][n]) for n in rep["inputs"]) + " |")
            if len(front) < 2:
                lines += ["", f"Only {len(front)} verified point is non-dominated: within these constraints "
                              f"{' and '.join(names)} do not trade off (one point is best in every objective)."]
        else:
            lines += ["No feasible verified point."]
        lines.append("")
    return "\n".join(lines)


def run_optimise(cfg: OptimiseConfig, out_dir: str | os.PathLike, bundle=None, metrics_path: str | None = None,
                 progress: bool = True, mlflow_enabled: bool = True) -> dict:
    """Run or resume a study, verify, close the loop, write the report; returns the report dict.

    Raises UserError after writing the report when no point is feasible (the report says what was tried).
    """
    from pipeline import tracking

    cfg.validate()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if cfg.mode == "surrogate" and bundle is None:
        from pipeline.tracking import load_bundle

        bundle = load_bundle(str(cfg.surrogate))
    model, preset, fixed, space, simulator, study_eval = _setup(cfg, bundle)
    cons = cfg.constraints()
    objectives = cfg.objective_list()
    obj_names = [n for n, _ in objectives]
    if cfg.mode == "surrogate":
        _check_surrogate_labels(study_eval, space, obj_names, cons, cfg.surrogate)
    static = space.ranges.get("static_force_n") or (simulator.resolved["static_force_n"],) * 2
    cons.check(static, progress_force_floor(model, simulator.resolved))
    sig = _signature(cfg, model, preset, fixed, space, cons, bundle)
    digest = hashlib.sha256(json.dumps(sig, sort_keys=True, default=str).encode()).hexdigest()[:10]
    name = cfg.study_name or f"{cfg.mode}-{cfg.objective}-{model}-{preset}-{digest}"
    storage = cfg.storage
    n_trials = int(cfg.n_trials or DEFAULT_TRIALS[cfg.mode])
    n_obj = len(objectives)
    sampler = make_sampler(cfg.sampler, cfg.seed, n_obj, n_startup=min(20, max(n_trials // 5, 5)))
    study = open_study(storage, name, objectives, sampler, sig)

    params = {**{k: v for k, v in asdict(cfg).items() if k not in ("ranges", "fixed", "settings", "objectives")},
              "objectives": ",".join(obj_names),
              "study_name": name, "space": json.dumps(space.to_dict()), "fixed": json.dumps(fixed)}
    from pipeline.optimise.coordination import StudyGuard, batch_seed

    def sampler_factory(n_done: int):      # per-batch seed: a resumed study proposes what an uninterrupted one did
        return make_sampler(cfg.sampler, batch_seed(cfg.seed, n_done), n_obj, n_startup=min(20, max(n_trials // 5, 5)))

    guard = StudyGuard.for_url(storage or default_storage())
    with tracking.run("optimise", params, enabled=mlflow_enabled) as mlflow:
        if cfg.mode == "surrogate":
            study, ran = run_study_buffered(study, sampler, study_eval, space, cons, objectives, n_trials,
                                            cfg.batch_size, progress=progress, desc="optimise surrogate",
                                            sampler_factory=sampler_factory, guard=guard)
        else:
            ran = run_study(study, study_eval, space, cons, objectives, n_trials, cfg.batch_size,
                            progress=progress, desc="optimise simulator", sampler_factory=sampler_factory,
                            guard=guard)
        study_sim_calls = simulator.calls
        trials = trials_frame(study, space)
        cands = pick_candidates(trials, space, cfg.objective, cfg.n_verify, directions=[d for _, d in objectives])
        status_counts = dict(Counter(trials["status"].astype(str))) if len(trials) else {}
        tried = {"mode": cfg.mode, "objective": cfg.objective, "objectives": obj_names, "sampler": cfg.sampler, "seed": cfg.seed,
                 "model": model, "preset": preset, "fixed": fixed, "space": space.to_dict(),
                 "constraints": cons.to_dict(), "n_trials": int(len(trials)), "n_trials_run_now": ran,
                 "n_feasible": int(trials["feasible"].sum()) if len(trials) else 0, "status_counts": status_counts,
                 "storage": storage or "sqlite optuna.db at the project root",
                 "simulator_calls_study": study_sim_calls, "n_verified": 0}
        rep = {"study_name": name, "inputs": space.names, "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
               "tried": tried, "recommendation": None}
        table = None
        if cands.empty:
            if len(trials):
                c = trials.sort_values("violation").iloc[0]
                tried["closest"] = {**{n: float(c[n]) for n in space.names}, "violation": float(c["violation"]),
                                    "status": c.get("status")}
            rep["outcome"] = (f"no feasible point among {len(trials)} trials of the {cfg.mode} study: nothing verified, "
                              f"nothing recommended — relax the constraints or widen the ranges")
        else:
            inputs_df = cands[space.names]
            pred = study_eval(inputs_df) if cfg.mode == "surrogate" else cands.rename(columns={})
            simres = simulator(inputs_df)
            tried["n_verified"] = len(simres)
            table = compare(pred, simres, space.names, cons, cfg.rel_tol, objectives=obj_names)
            n_wrong = int(table["surrogate_wrong"].sum())
            fb = cfg.feedback
            if fb is None and cfg.mode == "surrogate":
                fb = str(Path(cfg.surrogate) / "feedback.parquet") if Path(str(cfg.surrogate)).is_dir() \
                    else str(out / "feedback.parquet")
            if fb:
                rep["feedback_rows"] = append_feedback(simres, fb, source=f"optimise-{cfg.mode}", study=name,
                                                       wrong=table["surrogate_wrong"].tolist(), inputs=space.names)
                rep["feedback_file"] = fb
            if cfg.mode == "surrogate":
                rep["surrogate_note"] = (
                    f"The surrogate was wrong at {n_wrong} of {len(table)} verified points "
                    f"({'; '.join(sorted(set(w for w in table['why'] if w)))}). "
                    if n_wrong else f"The surrogate agreed with the simulator at all {len(table)} verified points "
                                    f"({', '.join(obj_names)} within {cfg.rel_tol:.0%}, same feasibility). ")
                if fb:
                    rep["surrogate_note"] += f"All {len(table)} verified points were appended to {fb} for retraining."
            best = best_verified(table)
            if best is None:
                rep["outcome"] = (f"none of the {len(table)} points the study found feasible is feasible when simulated "
                                  f"(statuses {dict(Counter(table['status_sim']))}): nothing recommended")
            else:
                rec = {"params": {n: float(best[n]) for n in space.names},
                       **{k: (None if pd.isna(best.get(k)) else float(best[k])) for k in
                          ("rop_m_s_sim", "rop_m_s_pred", "rop_m_s_lo", "rop_m_s_hi", "peak_force_n_sim",
                           "specific_energy_j_m_sim", "impacts_per_cycle_sim", "power_w_sim", "power_w_pred",
                           "peak_decel_g_sim", "peak_decel_g_pred", "rop_rel_error") if k in best},
                       "status_sim": best["status_sim"], "surrogate_wrong": bool(best["surrogate_wrong"])}
                rec["on_bounds"] = space.on_bounds(rec["params"])
                rec["binding"] = _binding(cons, best)
                rep["recommendation"] = rec
                rep["outcome"] = _outcome(rec)
            if cfg.objective == "pareto":
                rep["pareto_verified"] = _verified_front(table, objectives, space)
                rep["objectives"] = obj_names
            atomic_write_with(out / "verified.csv", lambda tmp: table.to_csv(tmp, index=False))
        tried["simulator_calls"] = simulator.calls
        if len(trials):
            atomic_write_with(out / "trials.csv", lambda tmp: trials.to_csv(tmp, index=False))
        figs = [plots.plot_history(trials, out / "history.png", f"{name}: ROP per trial ({cfg.mode})")]
        imp = plots.plot_importances(study, out / "importances.png", f"{cfg.mode} study: input importance")
        if imp:
            figs.append(imp)
        if table is not None:
            figs.append(plots.plot_verification(table, out / "verification.png", "surrogate vs simulator"
                                                if cfg.mode == "surrogate" else "study vs re-simulation"))
        if cfg.objective == "pareto" and len(trials) and trials["feasible"].any():
            cols = value_columns(n_obj)
            feas = trials[trials["feasible"] & np.all(np.isfinite(trials[cols].to_numpy(float)), axis=1)]
            front = feas[pareto_mask(*(feas[c].to_numpy(float) for c in cols), directions=[d for _, d in objectives])]
            figs.append(plots.plot_pareto(trials, front, table, out / "pareto.png",
                                          f"{name}: {obj_names[0]} vs {obj_names[1]}", obj_names[:2]))
        rep["figures"] = figs
        metrics = {"feasible": rep["recommendation"] is not None, "n_trials": tried["n_trials"],
                   "n_feasible_trials": tried["n_feasible"], "simulator_calls": tried["simulator_calls"],
                   "n_verified": tried["n_verified"],
                   "n_surrogate_wrong": int(table["surrogate_wrong"].sum()) if table is not None else 0}
        if cfg.objective == "pareto":
            metrics["n_pareto_verified"] = len(rep.get("pareto_verified") or [])
        if rep["recommendation"]:
            r = rep["recommendation"]
            metrics.update({"best_rop_m_s": r["rop_m_s_sim"], "best_rop_m_s_predicted": r.get("rop_m_s_pred"),
                            "best_rop_rel_error": r.get("rop_rel_error"), "best_power_w": r.get("power_w_sim"),
                            "best_peak_decel_g": r.get("peak_decel_g_sim"), "best_n_on_bounds": len(r["on_bounds"]),
                            **{f"best_{n}": v for n, v in r["params"].items()}})
        rep["metrics"] = metrics
        atomic_write_text(out / "report.json", dump_json(rep))
        atomic_write_text(out / "report.md", _markdown(rep, table))
        if metrics_path:
            atomic_write_text(Path(metrics_path), dump_json(metrics))
        if mlflow is not None:
            mlflow.log_metrics({k: float(v) for k, v in metrics.items()
                                if isinstance(v, (int, float)) and v is not None and math.isfinite(float(v))})
            if rep["recommendation"]:
                mlflow.log_params({f"best_{n}": v for n, v in rep["recommendation"]["params"].items()})
            for f in figs + [str(out / "report.json"), str(out / "report.md")]:
                mlflow.log_artifact(f)
            if table is not None:
                mlflow.log_artifact(str(out / "verified.csv"))
    if rep["recommendation"] is None:
        raise UserError(f"{rep['outcome']}; report: {out / 'report.md'}")
    return rep
