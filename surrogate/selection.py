"""Model selection by K-fold cross-validation on the training split (never the held-out split).

Each candidate's out-of-fold (OOF) predictions are kept: the winner's OOF residuals
calibrate its prediction intervals (surrogate.intervals)."""
from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field

import numpy as np
from joblib import Parallel, delayed
from sklearn.dummy import DummyClassifier
from sklearn.model_selection import KFold, StratifiedKFold

from surrogate import candidates
from surrogate.features import TargetTransform


@dataclass
class RegSelection:
    name: str
    oof: np.ndarray              # OOF predictions in transformed units
    oof_std: np.ndarray | None   # OOF GP posterior std (transformed units), when the winner is a GP
    scores: dict[str, float] = field(default_factory=dict)   # candidate -> CV RMSE, transformed units (selects)
    scores_original: dict[str, float] = field(default_factory=dict)   # candidate -> CV RMSE, original units
    errors: dict[str, str] = field(default_factory=dict)     # candidate -> why it was skipped
    fitted: object | None = None  # the winner fitted on every row, when the selection already did (beside the folds)


@dataclass
class ClsSelection:
    name: str
    oof_proba: np.ndarray
    classes: list[str]
    scores: dict[str, float] = field(default_factory=dict)   # candidate -> CV accuracy
    errors: dict[str, str] = field(default_factory=dict)


def _predict(est, X, want_std: bool):
    if want_std and isinstance(est, candidates.SubsampledGP):
        return est.predict(X, return_std=True)
    return est.predict(X), None


def _cv_regressor(name: str, X: np.ndarray, z: np.ndarray, tr: np.ndarray, te: np.ndarray, seed: int,
                  max_gp_points: int, params: dict | None = None):
    """One fold of one regressor candidate (``params`` set on it: its ``cv_params``): (held-out predictions, GP std
    or None), or why it failed."""
    est = candidates.regressor(name, seed, max_gp_points).set_params(**(params or {}))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            est.fit(X[tr], z[tr])
        return _predict(est, X[te], True)
    except (ValueError, np.linalg.LinAlgError) as e:
        return f"{type(e).__name__}: {e}"


class _OrphanFreeParallel(Parallel):
    """joblib Parallel whose worker processes die with this process (surrogate.lifetime)."""

    def __call__(self, iterable):
        from surrogate.lifetime import in_worker

        me = os.getpid()
        return super().__call__((in_worker, (me, fn, *args), kwargs) for fn, args, kwargs in iterable)


def parallel(n_jobs: int | None, **kwargs) -> Parallel:
    """joblib processes for independent fits (``n_jobs`` None: all cores; 1: in this process).  Results do not
    depend on ``n_jobs``: every fit is seeded and returned in submission order.  The workers die with this process."""
    return _OrphanFreeParallel(n_jobs=n_jobs if n_jobs else -1, **kwargs)


def _folds_of(name: str, jobs: list, results: list, errors: dict):
    """(held-out indices, result) of candidate ``name``'s folds, stopping at its first failed fold (recorded in
    ``errors``)."""
    for (jname, _, te), res in zip(jobs, results):
        if jname != name:
            continue
        if isinstance(res, str):
            errors[name] = res
            return
        yield te, res


def release_workers() -> None:
    """Stop joblib's reusable worker processes (so their CPU time is accounted to this process's children)."""
    from joblib.externals.loky import reusable_executor

    ex = getattr(reusable_executor, "_executor", None)
    if ex is not None:
        ex.shutdown(wait=True)


def _fit_all_rows(name: str, X: np.ndarray, z: np.ndarray, seed: int, max_gp_points: int):
    """Candidate ``name`` fitted on every row, or why it failed."""
    try:
        return fit_regressor(name, X, z, seed, max_gp_points)
    except (ValueError, np.linalg.LinAlgError) as e:
        return f"{type(e).__name__}: {e}"


def _fold_params(name: str, max_gp_points: int) -> dict | None:
    """Candidate ``name``'s settings for CV folds (``cv_params``: a cheaper search than its final fit), or None."""
    est = candidates.regressor(name, 0, max_gp_points)
    return est.cv_params() if hasattr(est, "cv_params") else None


def _cv_results(names: list[str], X, z, splits: list, seed: int, max_gp_points: int, n_jobs: int | None,
                final: bool):
    """Every candidate's fold results in ``jobs`` order, and the fits on every row made beside them.

    With ``final``, a candidate whose folds run with cheaper settings than its final fit (``cv_params``: the GP) has
    that final fit made in the same batch as the folds, which balances the processes; it is the final model when it
    wins."""
    cheap = {n: _fold_params(n, max_gp_points) for n in names}
    early = [n for n in names if final and cheap[n] is not None]
    jobs = [(name, tr, te) for name in names for tr, te in splits]
    done = parallel(n_jobs)([delayed(_fit_all_rows)(n, X, z, seed, max_gp_points) for n in early]
                            + [delayed(_cv_regressor)(n, X, z, tr, te, seed, max_gp_points, cheap[n])
                               for n, tr, te in jobs])
    full = {n: f for n, f in zip(early, done[:len(early)]) if not isinstance(f, str)}
    return jobs, done[len(early):], full


def select_regressor(names: list[str], X: np.ndarray, z: np.ndarray, tf: TargetTransform, folds: int, seed: int,
                     max_gp_points: int, n_jobs: int | None = 1, final: bool = True) -> RegSelection:
    """CV every candidate on (X, z=transformed target); pick the lowest RMSE in transformed units (the
    models' own loss: for log targets original-unit RMSE is ruled by a few points of the heavy tail).
    The candidates' folds run in ``n_jobs`` processes; a GP's folds search without its random restart.
    ``final`` False: only the scores are wanted (no final model is fitted beside the folds)."""
    kf = KFold(n_splits=min(folds, len(z)), shuffle=True, random_state=seed)
    splits = list(kf.split(X))
    y = tf.inverse(z)
    jobs, results, full = _cv_results(names, X, z, splits, seed, max_gp_points, n_jobs, final)
    best = None
    scores, scores_orig, errors, oofs = {}, {}, {}, {}
    for name in names:
        oof = np.empty_like(z)
        std = np.full_like(z, np.nan)
        for te, res in _folds_of(name, jobs, results, errors):
            oof[te] = res[0]
            if res[1] is not None:
                std[te] = res[1]
        if name in errors:
            continue
        rmse = float(np.sqrt(np.mean((oof - z) ** 2)))
        if not np.isfinite(rmse):
            errors[name] = "non-finite CV predictions"
            continue
        scores[name] = rmse
        with np.errstate(over="ignore"):
            scores_orig[name] = float(np.sqrt(np.mean((tf.inverse(oof) - y) ** 2)))
        oofs[name] = (oof, std if np.isfinite(std).all() else None)
        if best is None or rmse < scores[best]:
            best = name
    if best is None:
        raise ValueError(f"no regressor candidate could be fitted: {errors}")
    return RegSelection(best, oofs[best][0], oofs[best][1], scores, scores_orig, errors, full.get(best))


def _cv_classifier(name: str, X: np.ndarray, labels: np.ndarray, tr: np.ndarray, te: np.ndarray, seed: int):
    """One fold of one classifier candidate: (its classes, held-out probabilities), or why it failed."""
    try:
        est = fit_classifier(name, X[tr], labels[tr], seed)
        return list(est.classes_), est.predict_proba(X[te])
    except ValueError as e:
        return f"{type(e).__name__}: {e}"


def select_classifier(names: list[str], X: np.ndarray, labels: np.ndarray, folds: int, seed: int,
                      n_jobs: int | None = 1) -> ClsSelection:
    """CV every candidate (folds in ``n_jobs`` processes); pick the highest accuracy.  One class only -> a
    constant classifier."""
    classes = sorted(set(labels))
    if len(classes) == 1:
        proba = np.ones((len(labels), 1))
        return ClsSelection("constant", proba, classes, {"constant": 1.0})
    counts = np.array([np.sum(labels == c) for c in classes])
    k = min(folds, len(labels))
    splitter = (StratifiedKFold(k, shuffle=True, random_state=seed) if counts.min() >= k
                else KFold(k, shuffle=True, random_state=seed))
    jobs = [(name, tr, te) for name in names for tr, te in splitter.split(X, labels)]
    results = parallel(n_jobs)(delayed(_cv_classifier)(name, X, labels, tr, te, seed) for name, tr, te in jobs)
    best, scores, errors, oofs = None, {}, {}, {}
    for name in names:
        proba = np.zeros((len(labels), len(classes)))
        for te, res in _folds_of(name, jobs, results, errors):
            for j, c in enumerate(res[0]):
                proba[te, classes.index(c)] = res[1][:, j]
        if name in errors:
            continue
        acc = float(np.mean(np.array(classes)[proba.argmax(1)] == labels))
        scores[name] = acc
        oofs[name] = proba
        if best is None or acc > scores[best]:
            best = name
    if best is None:
        raise ValueError(f"no classifier candidate could be fitted: {errors}")
    return ClsSelection(best, oofs[best], classes, scores, errors)


def fit_classifier(name: str, X: np.ndarray, labels: np.ndarray, seed: int):
    """Fit classifier ``name``; a training set with one class gets a constant classifier."""
    if name == "constant" or len(set(labels)) == 1:
        return DummyClassifier(strategy="most_frequent").fit(X, labels)
    est = candidates.classifier(name, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            est.fit(X, labels)
        except ValueError:
            if name != "mlp":
                raise
            est.set_params(early_stopping=False)   # a class too rare for a stratified validation split
            est.fit(X, labels)
    return est


def fit_regressor(name: str, X: np.ndarray, z: np.ndarray, seed: int, max_gp_points: int):
    est = candidates.regressor(name, seed, max_gp_points)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est.fit(X, z)
    return est
