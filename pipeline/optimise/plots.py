"""Figures of an optimisation: history, parameter importances, Pareto front, prediction vs simulation (PNG)."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pipeline.core import units  # noqa: E402


def _save(fig, path: Path) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=110, bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)
    return str(path)


def plot_history(trials: pd.DataFrame, path: Path, title: str) -> str:
    """ROP of every trial (feasible dots, infeasible crosses) and the best feasible ROP so far [mm/s]."""
    fig, ax = plt.subplots(figsize=(8, 4.5))
    if len(trials):
        t = trials.sort_values("trial")
        f = t["feasible"].to_numpy(bool)
        v = t["value"].to_numpy(float) * units.factor("rop_m_s")
        ax.scatter(t["trial"][f], v[f], s=8, color="C0", label="feasible")
        ax.scatter(t["trial"][~f], v[~f], s=8, marker="x", color="0.6", label="infeasible")
        best = np.maximum.accumulate(np.where(f, v, -np.inf))
        ok = np.isfinite(best)
        ax.step(t["trial"][ok], best[ok], where="post", color="C3", label="best feasible so far")
    ax.set_xlabel("trial")
    units.set_label(ax, "y", "rop_m_s")
    ax.set_title(title)
    ax.legend(loc="lower right")
    return _save(fig, path)


def plot_importances(study, path: Path, title: str) -> str | None:
    """Importance (optuna's default evaluator) of each input for the (first) objective; None if too few trials."""
    import optuna

    # single objective: optuna knows the direction; two objectives: ROP, negated (the evaluator ranks low values)
    target = None if len(study.directions) == 1 else (lambda t: -t.values[0])
    import warnings

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)   # "importance for low target values": target is -ROP
            imp = optuna.importance.get_param_importances(study, target=target)
    except (RuntimeError, ValueError, ZeroDivisionError):
        return None
    if not imp:
        return None
    fig, ax = plt.subplots(figsize=(6, 0.6 * len(imp) + 1.5))
    names = list(imp)[::-1]
    ax.barh(names, [imp[n] for n in names], color="C0")
    ax.set_xlabel("importance for ROP (optuna default evaluator, sums to 1)")
    ax.set_title(title)
    return _save(fig, path)


def plot_pareto(trials: pd.DataFrame, front: pd.DataFrame, verified: pd.DataFrame | None, path: Path,
                title: str, names: list[str] | tuple[str, str] = ("rop_m_s", "power_w")) -> str:
    """First objective (y) against the second (x), in engineering units: feasible trials, their front,
    and the verified points (arrow from the study's value to the simulator's)."""
    (ny, nx) = names[0], names[1]
    fig, ax = plt.subplots(figsize=(8, 5))
    fy, fx = units.set_label(ax, "y", ny), units.set_label(ax, "x", nx)
    feas = trials[trials["feasible"] & np.isfinite(trials["value_2"].astype(float))]
    ax.scatter(feas["value_2"] * fx, feas["value"] * fy, s=6, color="0.7", label="feasible trials")
    f = front.sort_values("value_2")
    ax.plot(f["value_2"] * fx, f["value"] * fy, "o-", color="C0", ms=4, label="Pareto front (study)")
    if verified is not None and len(verified) and f"{nx}_sim" in verified:
        v = verified[np.isfinite(verified[f"{nx}_sim"].astype(float))]
        for _, r in v.iterrows():
            ax.annotate("", xy=(r[f"{nx}_sim"] * fx, r[f"{ny}_sim"] * fy),
                        xytext=(r[f"{nx}_pred"] * fx, r[f"{ny}_pred"] * fy),
                        arrowprops=dict(arrowstyle="->", color="C3", lw=0.8))
        ax.scatter(v[f"{nx}_sim"] * fx, v[f"{ny}_sim"] * fy, s=30, color="C3", marker="D",
                   label="verified by the simulator")
    if len(feas) and (feas["value_2"] > 0).all() and feas["value_2"].max() > 30 * feas["value_2"].min():
        ax.set_xscale("log")
    ax.set_title(title)
    ax.legend()
    return _save(fig, path)


def plot_verification(table: pd.DataFrame, path: Path, title: str) -> str:
    """Predicted against simulated ROP [mm/s] with the 90 % interval when the surrogate gives one."""
    fig, ax = plt.subplots(figsize=(5.5, 5))
    k = units.factor("rop_m_s")
    p = table["rop_m_s_pred"].astype(float) * k
    s = table["rop_m_s_sim"].astype(float).fillna(0.0) * k
    if "rop_m_s_lo" in table and "rop_m_s_hi" in table:
        lo = table["rop_m_s_lo"].astype(float) * k
        hi = table["rop_m_s_hi"].astype(float) * k
        ax.errorbar(s, p, yerr=[np.clip(p - lo, 0, None), np.clip(hi - p, 0, None)], fmt="none", ecolor="0.6")
    wrong = table["surrogate_wrong"].to_numpy(bool)
    ax.scatter(s[~wrong], p[~wrong], color="C0", label="agrees")
    ax.scatter(s[wrong], p[wrong], color="C3", marker="x", label="surrogate wrong")
    vals = np.concatenate([p.to_numpy(), s.to_numpy()])
    vals = vals[np.isfinite(vals)]
    if vals.size:
        a, b = float(vals.min()), float(vals.max())
        pad = 0.05 * (b - a if b > a else max(abs(b), 1e-6))
        ax.plot([a - pad, b + pad], [a - pad, b + pad], "k--", lw=0.8)
    units.set_label(ax, "x", "rop_m_s_sim")
    units.set_label(ax, "y", "rop_m_s_pred")
    ax.set_title(title)
    ax.legend()
    return _save(fig, path)
