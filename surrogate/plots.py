"""Report figures: parity plots, learning curve, confusion matrix, adaptive-vs-space-filling (PNG)."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from vibrobase.files import atomic_write_figure  # noqa: E402
from surrogate.data import domain_mask  # noqa: E402

UNITS = {"rop_m_s": "m/s", "peak_force_n": "N", "impacts_per_cycle": "-", "specific_energy_j_m": "J/m", "power_w": "W",
         "peak_decel_g": "g"}
NAMES = {"rop_m_s": "ROP", "peak_force_n": "peak impact force", "impacts_per_cycle": "impacts per cycle",
         "specific_energy_j_m": "specific energy", "power_w": "power", "peak_decel_g": "peak deceleration"}
"""Targets in words (figure titles)."""
SI = {t: (NAMES[t], UNITS[t], 1.0) for t in UNITS}
"""The default display table, target -> (words, unit, factor from SI): SI as stored.  The application passes its
own (engineering units: pipeline.core.units.ENGINEERING) so its figures and tables share one table."""


def _save(fig, path: Path) -> str:
    return str(atomic_write_figure(path, fig, dpi=110))


def parity(bundle, test: pd.DataFrame, path: Path, units: dict | None = None) -> str:
    """Predicted vs simulated value on the held-out split, one panel per target, with 90 % bars; values shown in
    ``units`` (target -> (words, unit, factor from SI); default :data:`SI`)."""
    units = {**SI, **(units or {})}
    pred = bundle.predict(test, conditional=True)
    ts = list(bundle.regressors)
    ncol = min(3, max(len(ts), 1))
    nrow = -(-len(ts) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.0 * ncol, 4.8 * nrow), squeeze=False)
    for ax in axes.ravel()[len(ts):]:
        ax.axis("off")
    for ax, t in zip(axes.ravel(), ts):
        tm = bundle.regressors[t]
        m = domain_mask(test, t, tm.domain)
        words, unit, k = units.get(t, (t, "", 1.0))
        y = test[t].to_numpy(float)[m] * k
        p, lo, hi = (pred[c].to_numpy(float)[m] * k for c in (t, f"{t}_lo", f"{t}_hi"))
        r2 = bundle.report.get("held_out", {}).get("targets", {}).get(t, {}).get("r2")
        name = f"{words} ({tm.name} on {tm.domain} points)"
        if y.size and np.ptp(y) <= 1e-9 * max(abs(float(y[0])), 1e-300):     # e.g. the peak force capped at Pr
            ax.text(0.5, 0.5, f"constant {y[0]:.4g} {unit} on every held-out point\n"
                    f"surrogate {np.nanmin(p):.4g} .. {np.nanmax(p):.4g}", ha="center", va="center",
                    transform=ax.transAxes, fontsize=10)
            ax.set_title(name, fontsize=10)
            ax.set_xticks([])
            ax.set_yticks([])
            continue
        inside = (y >= lo) & (y <= hi)
        ax.errorbar(y, p, yerr=[np.maximum(p - lo, 0), np.maximum(hi - p, 0)], fmt="none", ecolor="0.8", lw=0.6,
                    zorder=1)
        ax.scatter(y[inside], p[inside], s=10, c="C0", label="inside its 90 % interval", zorder=2)
        ax.scatter(y[~inside], p[~inside], s=14, c="C3", label="outside", zorder=3)
        if y.size:
            a, b = np.nanmin([y.min(), p.min()]), np.nanmax([y.max(), p.max()])
            ax.plot([a, b], [a, b], "k--", lw=0.8)
        if tm.transform.kind == "log":
            ax.set_xscale("log")
            ax.set_yscale("log")
        ax.set_title(name + (f"\nheld-out R² = {r2:.4f}" if r2 is not None else ""), fontsize=10)
        ax.set_xlabel(f"simulated {words} [{unit}]")
        ax.set_ylabel(f"surrogate {words} [{unit}]")
        ax.grid(alpha=0.3)
    handles = [a for a in axes.ravel() if a.get_legend_handles_labels()[0]]
    if handles:
        handles[0].legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def learning_curve(curve: list[dict], targets: list[str], path: Path) -> str:
    """Held-out RMSE per target and classification error against the number of training simulations."""
    df = pd.DataFrame(curve)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for t in targets:
        col = f"{t}_rmse"
        if col in df:
            ref = df[col].iloc[-1] if df[col].iloc[-1] else 1.0
            axes[0].plot(df["n_train"], df[col] / ref, "o-", label=f"{t} (÷ {ref:.3g} {UNITS.get(t, '')})")
    axes[0].set_xscale("log")
    axes[0].set_yscale("log")
    axes[0].set_xlabel("training simulations")
    axes[0].set_ylabel("held-out RMSE / final RMSE")
    axes[0].legend(fontsize=7)
    axes[1].plot(df["n_train"], 1 - df["accuracy"], "o-", c="C3")
    axes[1].set_xscale("log")
    axes[1].set_xlabel("training simulations")
    axes[1].set_ylabel("held-out regime misclassification rate")
    for a in axes:
        a.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return _save(fig, path)


def confusion(cls_report: dict, path: Path) -> str:
    """Held-out confusion matrix of the regime classifier."""
    cm = np.array(cls_report["confusion"])
    classes = cls_report["classes"]
    if len(classes) <= 1:   # a 1x1 "matrix" would look like a result; say what the data hold instead
        fig, ax = plt.subplots(figsize=(5, 2))
        ax.axis("off")
        ax.text(0.5, 0.5, f"one regime in the data: {', '.join(classes) or 'none'}\n"
                          f"({cls_report.get('n', 0)} held-out points)\nno classification to assess",
                ha="center", va="center")
        return _save(fig, path)
    fig, ax = plt.subplots(figsize=(1.2 * len(classes) + 2.5, 1.0 * len(classes) + 2))
    ax.imshow(cm, cmap="Blues")
    for i in range(cm.shape[0]):
        for j in range(cm.shape[1]):
            ax.text(j, i, str(cm[i, j]), ha="center", va="center", color="k" if cm[i, j] < cm.max() / 2 else "w")
    ax.set_xticks(range(len(classes)), classes, rotation=30)
    ax.set_yticks(range(len(classes)), classes)
    ax.set_xlabel("predicted regime")
    ax.set_ylabel("simulated regime")
    ax.set_title(f"held-out accuracy {cls_report['accuracy']:.3f} (n = {cls_report['n']})")
    fig.tight_layout()
    return _save(fig, path)


def adaptive(result: dict, path: Path) -> str:
    """Held-out ROP RMSE and regime error vs simulations: adaptive design against the space-filling one."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for key, ax, lab in (("rop_m_s_rmse", axes[0], "held-out ROP RMSE [m/s] (progressing)"),
                         ("error", axes[1], "held-out regime misclassification rate")):
        for name, style in (("space_filling", "o-"), ("adaptive", "s-")):
            c = pd.DataFrame(result[name])
            ax.plot(c["n_sims"], c[key], style, label=name.replace("_", "-"))
        ax.set_xlabel("simulations")
        ax.set_ylabel(lab)
        ax.set_yscale("log")
        ax.grid(alpha=0.3, which="both")
        ax.legend()
    fig.tight_layout()
    return _save(fig, path)
