"""Model selection by K-fold cross-validation on the training split (never the held-out split).

Each candidate's out-of-fold (OOF) predictions are kept: the winner's OOF residuals
calibrate its prediction intervals (surrogate.intervals)."""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
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


def select_regressor(names: list[str], X: np.ndarray, z: np.ndarray, tf: TargetTransform, folds: int, seed: int,
                     max_gp_points: int) -> RegSelection:
    """CV every candidate on (X, z=transformed target); pick the lowest RMSE in transformed units (the
    models' own loss: for log targets original-unit RMSE is ruled by a few points of the heavy tail)."""
    kf = KFold(n_splits=min(folds, len(z)), shuffle=True, random_state=seed)
    y = tf.inverse(z)
    best = None
    scores, scores_orig, errors, oofs = {}, {}, {}, {}
    for name in names:
        oof = np.empty_like(z)
        std = np.full_like(z, np.nan)
        try:
            for tr, te in kf.split(X):
                est = candidates.regressor(name, seed, max_gp_points)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    est.fit(X[tr], z[tr])
                pred, s = _predict(est, X[te], True)
                oof[te] = pred
                if s is not None:
                    std[te] = s
        except (ValueError, np.linalg.LinAlgError) as e:
            errors[name] = f"{type(e).__name__}: {e}"
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
    return RegSelection(best, oofs[best][0], oofs[best][1], scores, scores_orig, errors)


def select_classifier(names: list[str], X: np.ndarray, labels: np.ndarray, folds: int, seed: int) -> ClsSelection:
    """CV every candidate; pick the highest accuracy.  One class only -> a constant classifier."""
    classes = sorted(set(labels))
    if len(classes) == 1:
        proba = np.ones((len(labels), 1))
        return ClsSelection("constant", proba, classes, {"constant": 1.0})
    counts = np.array([np.sum(labels == c) for c in classes])
    k = min(folds, len(labels))
    splitter = (StratifiedKFold(k, shuffle=True, random_state=seed) if counts.min() >= k
                else KFold(k, shuffle=True, random_state=seed))
    best, scores, errors, oofs = None, {}, {}, {}
    for name in names:
        proba = np.zeros((len(labels), len(classes)))
        try:
            for tr, te in splitter.split(X, labels):
                est = fit_classifier(name, X[tr], labels[tr], seed)
                p = est.predict_proba(X[te])
                for j, c in enumerate(est.classes_):
                    proba[te, classes.index(c)] = p[:, j]
        except ValueError as e:
            errors[name] = f"{type(e).__name__}: {e}"
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
