"""The objects a study runs with: the problem, the sampler, the evaluator it asks, the executor, the simulator.

:func:`build_strategies` turns the config's names into them (``BUILDERS`` and ``SAMPLER_FACTORIES``, the one place
names become objects) with :func:`surrogate_strategies` or :func:`simulator_strategies`; ``workflow.plan_optimise``
takes them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import pandas as pd

import sim
from pipeline.core.errors import UserError
from pipeline.optimise.config import OptimiseConfig
from pipeline.optimise.constraints import UPPER_LIMITS, Constraints
from pipeline.optimise.evaluators import RopCorrected, SimulatorEvaluator, SurrogateEvaluator
from pipeline.optimise import samplers
from pipeline.optimise.samplers import SamplerFactory
from pipeline.optimise.space import Space, default_space, space_from_mapping
from pipeline.optimise.study import run_study, run_study_buffered

Evaluator = Callable[[pd.DataFrame], pd.DataFrame]
"""Inputs (one row per point) -> label rows in the same order (pipeline/optimise/evaluators.py)."""


class Executor(Protocol):
    """Runs the ask/evaluate/tell loop until the study holds ``n_trials``; returns (study, trials run now)."""

    def __call__(self, study, sampler, evaluate: Evaluator, space: Space, constraints: Constraints,
                 objectives: list[tuple[str, str]], n_trials: int, batch_size: int, *, progress: bool, desc: str,
                 sampler_factory: Callable[[int], object], guard) -> tuple[object, int]: ...


def run_direct(study, sampler, evaluate: Evaluator, space: Space, constraints: Constraints,
               objectives: list[tuple[str, str]], n_trials: int, batch_size: int, *, progress: bool = True,
               desc: str = "study", sampler_factory: Callable[[int], object] | None = None,
               guard=None) -> tuple[object, int]:
    """Executor for costly evaluators (the simulator): every trial goes straight to the storage."""
    ran = run_study(study, evaluate, space, constraints, objectives, n_trials, batch_size, progress=progress,
                    desc=desc, sampler_factory=sampler_factory, guard=guard)
    return study, ran


def run_buffered(study, sampler, evaluate: Evaluator, space: Space, constraints: Constraints,
                 objectives: list[tuple[str, str]], n_trials: int, batch_size: int, *, progress: bool = True,
                 desc: str = "study", sampler_factory: Callable[[int], object] | None = None,
                 guard=None) -> tuple[object, int]:
    """Executor for cheap evaluators (the surrogate): trials run in memory, stored every 100."""
    return run_study_buffered(study, sampler, evaluate, space, constraints, objectives, n_trials, batch_size,
                              progress=progress, desc=desc, sampler_factory=sampler_factory, guard=guard)


@dataclass(frozen=True)
class Problem:
    """What a study searches: the model and preset, the fixed values [SI], the search space, simulator settings."""
    model: str
    preset: str | None
    fixed: dict
    space: Space
    settings: dict | None


@dataclass(frozen=True)
class Strategies:
    """The problem and the objects that solve it, injected into ``workflow.plan_optimise``.

    ``evaluator`` labels the study's trials; ``simulator`` re-simulates the candidates (and counts simulator
    calls).  When they are the same object the study's trials already hold the simulator's labels."""
    problem: Problem
    sampler: SamplerFactory
    evaluator: Evaluator
    executor: Executor
    simulator: SimulatorEvaluator
    fingerprint: str | None = None      # the surrogate's dataset fingerprint, part of the study's signature


def _check_problem(problem: Problem) -> None:
    """UserError for a space that names unknown parameters, or a parameter both fixed and searched."""
    problem.space.validate(sim.get_model(problem.model).param_names)
    clash = sorted(set(problem.fixed) & set(problem.space.ranges))
    if clash:
        raise UserError(f"parameter(s) {clash} are both fixed and searched; drop one")


def _check_surrogate_labels(evaluate: Evaluator, space: Space, objectives: list[str], cons: Constraints,
                            ref) -> None:
    """UserError naming the label when the surrogate predicts no value for an objective or a constrained label."""
    needed = list(objectives) + [label for key, (label, attr) in UPPER_LIMITS.items() if getattr(cons, attr) is not None]
    centre = pd.DataFrame([{n: 0.5 * (lo + hi) for n, (lo, hi) in space.ranges.items()}])
    have = set(evaluate(centre).columns)
    missing = [n for n in dict.fromkeys(needed) if n not in have]
    if missing:
        raise UserError(f"the surrogate {ref} predicts no {', '.join(missing)}: retrain it (vibro train) with "
                        f"{', '.join(missing)} among train.targets, or optimise with --simulator")


def _envelope(cfg: OptimiseConfig, space: Space):
    """The rig's exciter envelope (None without one), checked against the search space."""
    env = cfg.constraints().envelope
    if env is not None:
        env.check_space(space.ranges)
    return env


def surrogate_strategies(cfg: OptimiseConfig, bundle, sampler: SamplerFactory) -> Strategies:
    """A study on ``bundle`` (its model, preset, fixed values and training ranges, narrowed by ``cfg``), verified by
    the simulator under the bundle's conditions."""
    if cfg.rop_correction:
        raise UserError("an empirical ROP correction (a rig file's empirical_correction) needs --simulator: the "
                        "surrogate learnt the model's ROP without it")
    fixed = {**bundle.fixed, **cfg.fixed}     # the sweep's conditions, overridden by the user's
    full = Space({n: (float(bundle.ranges[n][0]), float(bundle.ranges[n][1])) for n in bundle.inputs})
    space = space_from_mapping(cfg.ranges) if cfg.ranges else full
    if cfg.ranges:
        space.validate(sim.get_model(bundle.model).param_names)    # a mistyped name first, with its likely spelling
        not_inputs = [n for n in space.ranges if n not in full.ranges]
        if not_inputs:
            raise UserError(f"range(s) {not_inputs}: not an input of the surrogate {cfg.surrogate} (its inputs: "
                            f"{', '.join(bundle.inputs)}); sweep and train with them varied, or optimise with --simulator")
        for n in bundle.inputs:     # inputs the user did not restrict keep the surrogate's range
            if n not in space.ranges:
                space.ranges[n] = full.ranges[n]
        outside = full.contains(space)
        if outside:
            raise UserError(f"range(s) {outside} leave the surrogate's training ranges "
                            f"{ {n: full.ranges[n] for n in outside if n in full.ranges} }: "
                            f"the surrogate cannot be trusted there (sweep and train on a wider space)")
    settings = cfg.settings if cfg.settings is not None else (bundle.settings or None)
    problem = Problem(bundle.model, bundle.preset, fixed, space, settings)
    _check_problem(problem)
    env = _envelope(cfg, space)
    if env is not None and env.needs_history:
        raise UserError("the rig's exciter limits on stroke or velocity need --simulator: the surrogate predicts "
                        "neither (its force envelope alone works on the surrogate)")
    simulator = SimulatorEvaluator(problem.model, problem.preset, fixed, settings=settings, n_threads=cfg.n_threads)
    evaluator = SurrogateEvaluator(bundle, fixed)
    _check_surrogate_labels(evaluator, space, [n for n, _ in cfg.objective_list()], cfg.constraints(), cfg.surrogate)
    return Strategies(problem, sampler, evaluator, run_buffered, simulator, getattr(bundle, "fingerprint", None))


def simulator_strategies(cfg: OptimiseConfig, sampler: SamplerFactory) -> Strategies:
    """A study straight on the simulator: ``cfg``'s model, preset, fixed values and ranges (else the published
    space of the model's preset)."""
    space = space_from_mapping(cfg.ranges) if cfg.ranges else default_space(cfg.model, cfg.preset)
    if space is None:
        raise UserError(f"no search space: give ranges (--range NAME=LOW:HIGH) — model '{cfg.model}' preset "
                        f"'{cfg.preset}' publishes no default space")
    problem = Problem(cfg.model, cfg.preset, dict(cfg.fixed), space, cfg.settings)
    _check_problem(problem)
    env = _envelope(cfg, space)
    simulator = SimulatorEvaluator(problem.model, problem.preset, problem.fixed, settings=cfg.settings,
                                   n_threads=cfg.n_threads, history_labels=env is not None and env.needs_history)
    if cfg.rop_correction:          # the rig's empirical ROP correction: the study and its verification both see it
        from sim.empirical import EmpiricalCorrection

        simulator = RopCorrected(simulator, EmpiricalCorrection.from_mapping(cfg.rop_correction))
    return Strategies(problem, sampler, simulator, run_direct, simulator)


# ------------------------------------------------------------------ lookup tables: the one place names become objects
def _surrogate_study(cfg: OptimiseConfig, sampler: SamplerFactory, bundle=None) -> Strategies:
    """A study on the surrogate bundle ``bundle``, else the one at ``cfg.surrogate`` (folder or MLflow run id)."""
    from pipeline.tracking import load_bundle

    return surrogate_strategies(cfg, load_bundle(str(cfg.surrogate)) if bundle is None else bundle, sampler)


def _simulator_study(cfg: OptimiseConfig, sampler: SamplerFactory, bundle=None) -> Strategies:
    """A study straight on the simulator (no bundle)."""
    return simulator_strategies(cfg, sampler)


BUILDERS = {"surrogate": _surrogate_study, "simulator": _simulator_study}
"""Config 'mode' (--surrogate / --simulator) -> builder of the study's problem, evaluator, executor and simulator."""

SAMPLER_FACTORIES = {"tpe": samplers.tpe_sampler, "sobol-local": samplers.sobol_local_sampler,
                     "gp": samplers.gp_sampler, "nsga2": samplers.nsga2_sampler, "random": samplers.random_sampler}
"""Config 'sampler' (--sampler) -> sampler factory (pipeline/optimise/samplers.py)."""


def build_strategies(cfg: OptimiseConfig, bundle=None) -> Strategies:
    """The strategies of ``cfg``; ``bundle`` (a loaded surrogate) replaces loading ``cfg.surrogate``."""
    return BUILDERS[cfg.mode](cfg, SAMPLER_FACTORIES[cfg.sampler], bundle)
