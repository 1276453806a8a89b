"""Held-out metrics in original units."""
from __future__ import annotations

import numpy as np

from surrogate.features import is_constant


def regression(y: np.ndarray, pred: np.ndarray, lo: np.ndarray | None = None, hi: np.ndarray | None = None) -> dict:
    """R², MAE, RMSE (units of y) and, given bounds, the fraction of y inside [lo, hi]."""
    y = np.asarray(y, dtype=float)
    pred = np.asarray(pred, dtype=float)
    n = y.size
    out = {"n": int(n)}
    if n == 0:
        return out
    err = pred - y
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    out["mae"] = float(np.mean(np.abs(err)))
    out["rmse"] = float(np.sqrt(np.mean(err ** 2)))
    # R² is undefined for a (numerically) constant target, e.g. peak force pinned at Pr in the
    # progressing regime: report None rather than a meaningless huge negative number.
    constant = is_constant(y)
    out["r2"] = None if constant or ss_tot <= 0 else float(1.0 - np.sum(err ** 2) / ss_tot)
    if lo is not None and hi is not None:
        out["coverage"] = float(np.mean((y >= lo) & (y <= hi)))
        out["mean_width"] = float(np.mean(hi - lo))
    return out


def classification(labels: np.ndarray, pred: np.ndarray, classes: list[str]) -> dict:
    """Accuracy and confusion matrix (rows = true class, columns = predicted, order ``classes``)."""
    labels = np.asarray(labels, dtype=object)
    pred = np.asarray(pred, dtype=object)
    cm = [[int(np.sum((labels == a) & (pred == b))) for b in classes] for a in classes]
    return {"n": int(labels.size), "accuracy": float(np.mean(labels == pred)) if labels.size else None,
            "classes": list(classes), "confusion": cm}
