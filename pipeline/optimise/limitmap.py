"""Maps of ROP around a recommendation with the limits drawn: where the answer sits and how far it is from them.

Two maps of the simulator over the search box: frequency × static force at the recommended amplitude, and
frequency × amplitude at the recommended static force.  Each is drawn as ROP [mm/s] with the contour of every limit
(its value, and the limit less its margin dashed), the exciter's force envelope, the cells that do not settle greyed
and the recommendation starred.  ``vibro optimise --limit-map`` writes them (limit_map_*.png, .parquet).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from vibrobase.statuses import SETTLED_STATUSES
from pipeline.optimise.constraints import UPPER_LIMITS, Constraints

PAIRS = (("frequency_hz", "static_force_n", "amplitude_n"), ("frequency_hz", "amplitude_n", "static_force_n"))
"""(x, y, held at the recommendation) of each map."""


@dataclass(frozen=True)
class LimitMap:
    """One map: its axes, the control held at the recommended value, the simulated table (x-major cells)."""
    x: str
    y: str
    held: str
    held_value: float
    table: pd.DataFrame


def limit_maps(res, shape: tuple[int, int] = (25, 13)) -> list[LimitMap]:
    """The maps of a result with a recommendation, over its search space (pairs whose axes are searched)."""
    rec = res.recommendation
    if rec is None:
        return []
    p, space = res.problem, res.problem.space
    out = []
    for x, y, held in PAIRS:
        if x not in space.ranges or y not in space.ranges:
            continue
        xs, ys = (np.linspace(*space.ranges[n], k) for n, k in ((x, shape[0]), (y, shape[1])))
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        rows = pd.DataFrame({x: X.ravel(), y: Y.ravel()})
        value = rec["params"].get(held, p.fixed.get(held))
        if held in rec["params"]:
            rows[held] = value
        for k, v in rec["params"].items():
            if k not in rows:
                rows[k] = v
        from pipeline.optimise.evaluators import SimulatorEvaluator

        sim = SimulatorEvaluator(p.model, p.preset, p.fixed, settings=p.settings)
        table = sim(rows)
        for c in rows.columns:
            table[c] = rows[c].to_numpy()
        out.append(LimitMap(x, y, held, float(value) if value is not None else float("nan"), table))
    return out


def plot_limit_map(m: LimitMap, cons: Constraints, rec: dict, path: Path, title: str) -> str:
    """ROP with the limit contours, the force envelope, unsettled cells and the recommendation; the PNG's path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pipeline.optimise.plots import _save

    t = m.table
    nx, ny = t[m.x].nunique(), t[m.y].nunique()
    X = t[m.x].to_numpy(float).reshape(nx, ny)
    Y = t[m.y].to_numpy(float).reshape(nx, ny)
    settled = t["status"].isin(SETTLED_STATUSES).to_numpy().reshape(nx, ny)
    rop = np.where(settled, t["rop_m_s"].to_numpy(float).reshape(nx, ny) * 1e3, np.nan)
    fig, ax = plt.subplots(figsize=(8, 5.5))
    pc = ax.pcolormesh(X, Y, rop, shading="nearest", cmap="viridis")
    fig.colorbar(pc, ax=ax, label="ROP [mm/s]")
    if (~settled).any():
        ax.contourf(X, Y, (~settled).astype(float), levels=[0.5, 1.5], colors="0.7", alpha=0.8)
    styles = iter(["C3", "C1", "C6", "C4"])
    handles = []
    for key, (label, attr) in UPPER_LIMITS.items():
        lim = getattr(cons, attr)
        if lim is None or label not in t:
            continue
        c = next(styles)
        V = t[label].to_numpy(float).reshape(nx, ny)
        ax.contour(X, Y, V, levels=[lim], colors=c, linewidths=2)
        handles.append(plt.Line2D([], [], color=c, lw=2, label=f"{label} = {lim:g}"))
        if label in cons.margins:
            kept = cons.limit_of(label, lim)
            ax.contour(X, Y, V, levels=[kept], colors=c, linewidths=1.5, linestyles="--")
            handles.append(plt.Line2D([], [], color=c, lw=1.5, ls="--", label=f"{label} = {kept:.4g} (margin)"))
    env = cons.envelope
    if env is not None and env.force_table and m.x == "frequency_hz" and m.y == "amplitude_n":
        f = np.linspace(X.min(), X.max(), 200)
        ax.plot(f, [env.max_force(v) for v in f], color="k", lw=2)
        handles.append(plt.Line2D([], [], color="k", lw=2, label="exciter force envelope"))
    ax.plot(rec["params"].get(m.x), rec["params"].get(m.y), marker="*", ms=16, color="w", mec="k")
    handles.append(plt.Line2D([], [], marker="*", ms=12, color="w", mec="k", ls="", label="recommendation"))
    ax.set_xlabel(m.x)
    ax.set_ylabel(m.y)
    ax.set_title(f"{title} ({m.held} = {m.held_value:.4g})")
    if handles:
        ax.legend(handles=handles, loc="lower right", fontsize=8)
    return _save(fig, path)


def write_limit_maps(res, out: Path, shape: tuple[int, int] = (25, 13)) -> tuple[list[str], int]:
    """limit_map_<x>_<y>.png and .parquet for each map of ``res``; (the PNG paths, simulations run)."""
    from pipeline.optimise.verify import write_parquet_atomic

    pngs, n = [], 0
    for m in limit_maps(res, shape):
        stem = f"limit_map_{m.x}_{m.y}"
        write_parquet_atomic(m.table, out / f"{stem}.parquet")
        pngs.append(plot_limit_map(m, res.constraints, res.recommendation, out / f"{stem}.png",
                                   f"ROP around the recommendation"))
        n += len(m.table)
    return pngs, n
