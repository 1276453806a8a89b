"""Optuna samplers a study can use, one factory each: ``(seed, n_objectives, n_startup) -> sampler``.

A study picks one by name (``strategies.SAMPLER_FACTORIES``); study.py's docstring says which is the
default and why CMA-ES is not offered (its factory serves bench/bench_search.py).
"""
from __future__ import annotations

from typing import Callable

from pipeline.core.errors import UserError

SamplerFactory = Callable[[int, int, int], object]
"""(seed, number of objectives, startup trials) -> an optuna sampler."""


def tpe_sampler(seed: int, n_objectives: int, n_startup: int = 20):
    """Multivariate TPE with the constant liar (batches), constraints native; the default of a Pareto study."""
    import optuna

    return optuna.samplers.TPESampler(seed=seed, multivariate=True, constant_liar=True, n_startup_trials=n_startup)


def random_sampler(seed: int, n_objectives: int, n_startup: int = 20):
    """Uniform random proposals: the benchmark's baseline."""
    import optuna

    return optuna.samplers.RandomSampler(seed=seed)


def nsga2_sampler(seed: int, n_objectives: int, n_startup: int = 20):
    """NSGA-II (genetic, multi-objective, constraints)."""
    import optuna

    return optuna.samplers.NSGAIISampler(seed=seed)


def gp_sampler(seed: int, n_objectives: int, n_startup: int = 20):
    """Gaussian-process Bayesian optimisation, noise-free (the simulator and a surrogate are deterministic); needs PyTorch."""
    import optuna

    try:
        import torch  # noqa: F401
    except ImportError:
        raise UserError("sampler 'gp' needs PyTorch (pip install torch); use --sampler tpe") from None
    return optuna.samplers.GPSampler(seed=seed, n_startup_trials=n_startup, deterministic_objective=True)


def sobol_local_sampler(seed: int, n_objectives: int, n_startup: int = 20):
    """A Sobol' pass of twice ``n_startup`` trials, then a compass search that reaches the box's bounds exactly, with
    restarts (pipeline/optimise/sobol_local.py); a function of the trials alone (``seed`` is unused), so workers
    sharing a study propose distinct points.  One objective."""
    if n_objectives > 1:
        raise UserError("sampler 'sobol-local' searches one objective; use --sampler tpe or nsga2 for a Pareto study")
    from pipeline.optimise.sobol_local import SobolLocalSampler

    return SobolLocalSampler(n_startup=2 * n_startup, seed=seed)


def cmaes_sampler(seed: int, n_objectives: int, n_startup: int = 20):
    """CMA-ES (optuna >= 4.4 dropped its restarts to OptunaHub); ignores optuna's constraints, so the benchmark runs
    it on the cases without limits only; needs the cmaes package."""
    import optuna

    try:
        import cmaes  # noqa: F401
    except ImportError:
        raise UserError("sampler 'cmaes' needs the cmaes package (pip install cmaes); use --sampler sobol-local") \
            from None
    if n_objectives > 1:
        raise UserError("sampler 'cmaes' searches one objective; use --sampler tpe or nsga2 for a Pareto study")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return optuna.samplers.CmaEsSampler(seed=seed, n_startup_trials=n_startup, warn_independent_sampling=False)
