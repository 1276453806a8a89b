"""Candidate estimators (scikit-learn) for the regime classifier and the target regressors.

Inputs arrive already scaled to the unit cube (features.InputScaler); regression targets
already transformed (features.TargetTransform).  Every factory takes a seed.
"""
from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin, clone
from sklearn.compose import TransformedTargetRegressor
from sklearn.ensemble import ExtraTreesClassifier, HistGradientBoostingClassifier, HistGradientBoostingRegressor
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel
from sklearn.kernel_ridge import KernelRidge
from sklearn.neural_network import MLPClassifier, MLPRegressor
from sklearn.preprocessing import StandardScaler

from surrogate.errors import ConfigError

REGRESSORS = ("gp", "gbt", "mlp", "krr")
CLASSIFIERS = ("gbt", "mlp", "trees")


class SubsampledGP(RegressorMixin, BaseEstimator):
    """Gaussian process with an anisotropic Matern-5/2 kernel + white noise, fitted on at most
    ``max_points`` rows (a seeded subsample: the cost grows as n^3).  ``predict(X, return_std=True)``
    gives the posterior standard deviation.  ``restarts``: random restarts of the likelihood's maximisation
    after the search from the kernel's defaults."""

    def __init__(self, max_points: int = 600, restarts: int = 1, seed: int = 0):
        self.max_points = max_points
        self.restarts = restarts
        self.seed = seed

    @staticmethod
    def cv_params() -> dict:
        """Settings of the fits on CV folds: the search from the kernel's defaults only.  The random restart costs
        about two thirds of a fold's CPU and rarely moves its optimum (docs/train.md); the final fit keeps it."""
        return {"restarts": 0}

    def fit(self, X, y):
        X = np.asarray(X, dtype=float)
        y = np.asarray(y, dtype=float)
        if len(y) > self.max_points:
            idx = np.random.default_rng(self.seed).choice(len(y), self.max_points, replace=False)
            X, y = X[idx], y[idx]
        d = X.shape[1]
        kernel = (ConstantKernel(1.0, (1e-3, 1e3)) * Matern(length_scale=np.full(d, 0.3), length_scale_bounds=(1e-3, 1e2),
                                                            nu=2.5)
                  + WhiteKernel(1e-3, (1e-8, 1.0)))
        self.gp_ = GaussianProcessRegressor(kernel, normalize_y=True, n_restarts_optimizer=self.restarts,
                                            random_state=self.seed)
        import warnings

        from sklearn.exceptions import ConvergenceWarning
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            self.gp_.fit(X, y)
        return self

    def predict(self, X, return_std: bool = False):
        return self.gp_.predict(np.asarray(X, dtype=float), return_std=return_std)


def _scaled_y(est) -> TransformedTargetRegressor:
    return TransformedTargetRegressor(regressor=est, transformer=StandardScaler())


def regressor(name: str, seed: int = 0, max_gp_points: int = 600):
    """Unfitted regressor ``name`` (gp | gbt | mlp | krr)."""
    if name == "gp":
        return SubsampledGP(max_points=max_gp_points, seed=seed)
    if name == "gbt":
        return HistGradientBoostingRegressor(max_iter=400, learning_rate=0.05, max_leaf_nodes=31, min_samples_leaf=5,
                                             l2_regularization=1e-3, early_stopping=False, random_state=seed)
    if name == "mlp":
        return _scaled_y(MLPRegressor(hidden_layer_sizes=(64, 64), alpha=1e-4, learning_rate_init=3e-3, max_iter=1500,
                                      early_stopping=True, validation_fraction=0.1, n_iter_no_change=40,
                                      random_state=seed))
    if name == "krr":
        return _scaled_y(KernelRidge(kernel="rbf", alpha=1e-3, gamma=8.0))
    raise ConfigError(f"train.regressors: unknown candidate '{name}' (choose from {', '.join(REGRESSORS)})")


def classifier(name: str, seed: int = 0):
    """Unfitted classifier ``name`` (gbt | mlp | trees) with predict_proba."""
    if name == "gbt":
        return HistGradientBoostingClassifier(max_iter=300, learning_rate=0.05, max_leaf_nodes=31, min_samples_leaf=5,
                                              early_stopping=False, random_state=seed)
    if name == "mlp":
        return MLPClassifier(hidden_layer_sizes=(64, 64), alpha=1e-4, learning_rate_init=3e-3, max_iter=1500,
                             early_stopping=True, n_iter_no_change=40, random_state=seed)
    if name == "trees":
        return ExtraTreesClassifier(n_estimators=300, min_samples_leaf=1, random_state=seed, n_jobs=1)
    raise ConfigError(f"train.classifiers: unknown candidate '{name}' (choose from {', '.join(CLASSIFIERS)})")


def fresh(est):
    """An unfitted copy."""
    return clone(est)
