"""The training report: figures under the output directory and flat metrics for MLflow / --metrics."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from surrogate import plots


def figures(bundle, test: pd.DataFrame, out: Path, adaptive: dict | None = None,
            units: dict | None = None) -> dict[str, str]:
    """parity.png, learning_curve.png, confusion.png (+ adaptive.png); returns name -> path.  ``units``: the
    display table of the targets (``plots.parity``)."""
    out = Path(out)
    r = bundle.report
    figs = {"parity": plots.parity(bundle, test, out / "parity.png", units),
            "confusion": plots.confusion(r["held_out"]["classification"], out / "confusion.png")}
    if r.get("learning_curve"):
        figs["learning_curve"] = plots.learning_curve(r["learning_curve"], list(bundle.regressors),
                                                      out / "learning_curve.png")
    if adaptive:
        figs["adaptive"] = plots.adaptive(adaptive, out / "adaptive.png")
    return figs


def flat_metrics(report: dict) -> dict[str, float]:
    """Numbers worth a metric: held-out accuracy, per-target R² / MAE / RMSE / coverage, training sizes,
    simulations needed for each goal, adaptive-sampling savings."""
    out: dict[str, float] = {"n_train": report["n_train"], "n_test": report["n_test"],
                             "accuracy": report["held_out"]["classification"]["accuracy"]}
    for t, m in report["held_out"]["targets"].items():
        for k in ("r2", "r2_log10", "mae", "rmse", "coverage"):
            if m.get(k) is not None:
                out[f"{t}_{k}"] = m[k]
    for k, v in (report.get("simulations_needed") or {}).items():
        if v is not None:
            out[f"sims_needed_{k}"] = v
    for k, v in (report.get("adaptive", {}).get("savings") or {}).items():
        for kk in ("adaptive_sims", "space_filling_sims", "saved"):
            if v.get(kk) is not None:
                out[f"adaptive_{k}_{kk}"] = v[kk]
    return {k: float(v) for k, v in out.items() if v is not None}
