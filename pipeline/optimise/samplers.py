"""Optuna samplers a study can use, one factory each: ``(seed, n_objectives, n_startup) -> sampler``.

The command picks one by name (``pipeline/cli/optimise.py`` ``SAMPLERS``); study.py's docstring says why TPE is
the default and why CMA-ES is not offered.
"""
from __future__ import annotations

from typing import Callable

from pipeline.core.errors import UserError

SamplerFactory = Callable[[int, int, int], object]
"""(seed, number of objectives, startup trials) -> an optuna sampler."""


def tpe_sampler(seed: int, n_objectives: int, n_startup: int = 20):
    """Multivariate TPE with the constant liar (batches), constraints native; the default."""
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
    """Gaussian-process Bayesian optimisation; needs PyTorch."""
    import optuna

    try:
        import torch  # noqa: F401
    except ImportError:
        raise UserError("sampler 'gp' needs PyTorch (pip install torch); use --sampler tpe") from None
    return optuna.samplers.GPSampler(seed=seed, n_startup_trials=n_startup)
