"""``optimise(cfg, out)``: the whole workflow of ``vibro optimise`` with its fallback, as one call.

The study runs on the surrogate or the simulator; the verified points go to the feedback file; a surrogate the
simulator contradicted (:func:`workflow.surrogate_failed` says when) is first retrained where the study looked
(``infill.infill_until_right``) and, if still wrong, never recommends: a study straight on the simulator does.
The report, tables and figures are written under ``out`` and returned as an :class:`OptimiseOutcome`.
The command (``pipeline/cli/optimise.py``) picks the paths, opens MLflow and prints.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from vibrobase.files import atomic_write_text
from vibrobase.jsonable import dump_json
from pipeline.optimise import outputs
from pipeline.optimise.config import OptimiseConfig
from pipeline.optimise.strategies import build_strategies
from pipeline.optimise.verify import append_feedback
from pipeline.optimise.workflow import (OptimisePlan, OptimiseResult, fallback_config, plan_optimise, run_optimise,
                                        seed_with_verified, surrogate_failed)

__all__ = ["OptimiseOutcome", "feedback_file", "optimise", "plan_study", "recommendation_spread"]

SPREAD_SAMPLES = 32
"""Samples of a rig's fitted parameters behind the recommendation's ROP spread (as ``vibro compare``)."""


@dataclass(frozen=True)
class OptimiseOutcome:
    """What :func:`optimise` did: the studies, the fallback decision, the report and the files it wrote."""
    plan: OptimisePlan                  # the first study's plan (its run parameters: outputs.run_params)
    result: OptimiseResult              # the study that recommends: the fallback's when there was one
    failed: OptimiseResult | None       # the surrogate study the simulator contradicted, when a fallback replaced it
    verification_failed: str | None     # why the surrogate failed its verification (None: it passed, or no surrogate)
    report: dict                        # report.json (outputs.REPORT_KEYS)
    feedback_file: str | None           # where the verified points went (None: nowhere)
    feedback_rows: int | None           # rows now in the feedback file
    figures: tuple[str, ...]            # figures written (history, importances, ..., limit maps)
    tables: tuple[Path, ...]            # verified.csv, trials.csv
    reports: tuple[Path, ...]           # report.json, report.md
    metrics_file: Path | None = None    # the small metrics JSON, when asked for

    @property
    def fell_back(self) -> bool:
        """True when a study straight on the simulator replaced the surrogate's."""
        return self.failed is not None

    @property
    def recommendation(self) -> dict | None:
        """The best verified feasible point (report.json 'recommendation'), None when nothing is recommended."""
        return self.report["recommendation"]

    @property
    def outcome(self) -> str:
        """One sentence: the answer or why there is none."""
        return self.report["outcome"]


def feedback_file(cfg: OptimiseConfig, out: Path) -> str | None:
    """Where verified points go: ``cfg.feedback``; a surrogate study without one: beside the bundle, else in ``out``."""
    if cfg.feedback is not None or cfg.mode != "surrogate":
        return cfg.feedback
    sur = Path(str(cfg.surrogate))
    return str(sur / "feedback.parquet") if sur.is_dir() else str(out / "feedback.parquet")


def recommendation_spread(cfg: OptimiseConfig, rig, recommendation: dict, n_samples: int = SPREAD_SAMPLES):
    """The recommended point's ROP spread on ``rig`` (:class:`~pipeline.optimise.robustness.RopSpread`): its
    fitted parameters sampled, its model error added; the config's fixed values (the rig's and ``--set``) kept."""
    from pipeline.optimise.robustness import rop_spread

    point = {**(cfg.fixed or {}), **recommendation["params"]}
    return rop_spread(rig, point, n_samples=n_samples, seed=cfg.seed, settings=cfg.settings, n_threads=cfg.n_threads)


def plan_study(cfg: OptimiseConfig, bundle=None) -> OptimisePlan:
    """``cfg``'s study planned on its strategies; ``bundle`` (a loaded surrogate) replaces loading ``cfg.surrogate``."""
    return plan_optimise(cfg, build_strategies(cfg, bundle))


def optimise(cfg: OptimiseConfig, out_dir, *, bundle=None, plan: OptimisePlan | None = None,
             metrics_path: str | Path | None = None, progress: bool = True,
             notify: Callable[[str], None] | None = None, rig=None) -> OptimiseOutcome:
    """Run the study of ``cfg``, append the verified points to the feedback file, fall back to a study on the
    simulator when the surrogate failed its verification, and write the report, tables and figures under ``out_dir``.

    ``plan``: ``plan_study(cfg, bundle)`` made beforehand (the command logs its parameters first).  ``notify`` is
    told, in one line, why a fallback study runs before it does.  Nothing recommended is no error: the outcome's
    ``recommendation`` is None and its report says what was tried.  ``rig``: the corrected rig (``sim.Rig``) the
    study ran on; the recommendation's ROP spread over its fitted parameters and model error goes to report.json
    'spread' (:func:`~pipeline.optimise.robustness.rop_spread`).  UserError from planning (bad constraints, a
    stored study run with other settings)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plan = plan_study(cfg, bundle) if plan is None else plan
    res = run_optimise(plan, progress=progress)
    fb, rows = feedback_file(cfg, out), None
    if fb and res.simulated is not None:
        rows = append_feedback(res.simulated, fb, source=f"optimise-{cfg.mode}", study=res.study_name,
                               wrong=res.verified["surrogate_wrong"].tolist(), inputs=res.problem.space.names)
    infill = None
    if surrogate_failed(res) and cfg.infill_rounds > 0 and fb:     # first simulate where it looked, retrain
        from pipeline.optimise.infill import infill_until_right

        infill = infill_until_right(res, plan.strategies.evaluator.bundle, build_strategies, fb, progress=progress,
                                    notify=notify)
        res, rows = infill.result, infill.feedback_rows or rows
    failed = None
    why = surrogate_failed(res)
    if why and cfg.fallback_trials > 0:     # never recommend from a surrogate the simulator contradicted
        if notify is not None:
            notify(f"{why}; running {cfg.fallback_trials} trials straight on the simulator")
        sim_cfg = fallback_config(res)
        sim_plan = plan_study(sim_cfg)
        seed_with_verified(sim_plan, res)       # the study starts from the points already verified
        failed, res = res, run_optimise(sim_plan, progress=progress)
    tables = outputs.write_tables(res, out)
    figs = outputs.write_figures(res, out)
    map_sims = 0
    if cfg.limit_map and res.recommendation is not None:
        from pipeline.optimise.limitmap import write_limit_maps

        maps, map_sims = write_limit_maps(res, out)
        figs = [*figs, *maps]
    spread = None if rig is None or res.recommendation is None else recommendation_spread(cfg, rig, res.recommendation)
    rep = outputs.report_dict(res, figs, rows, fb, failed=failed, infill=infill and infill.report, spread=spread)
    if map_sims:
        rep["metrics"]["limit_map_simulations"] = map_sims
    reports = outputs.write_report(rep, res, out)
    metrics_file = Path(metrics_path) if metrics_path else None
    if metrics_file is not None:
        atomic_write_text(metrics_file, dump_json(rep["metrics"]))
    return OptimiseOutcome(plan, res, failed, why, rep, fb, rows, tuple(figs), tuple(tables), tuple(reports),
                           metrics_file)
