"""Figures of the response maps (PNG, matplotlib Agg): Peterka map, ROP map, label map, bifurcation diagram.

Every function takes the table produced by :mod:`pipeline.maps.compute` and writes one PNG atomically
(temporary file in the same folder, then ``os.replace``); it returns the path.
"""
from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from pipeline.core import units  # noqa: E402
from vibrobase.files import atomic_write_figure  # noqa: E402
from pipeline.maps import compute as M  # noqa: E402

PATTERN_COLORS = {M.NO_IMPACT: "#f0f0f0", M.Z11: "#1f77b4", M.Z12: "#2ca02c", M.OTHER_PERIODIC: "#ff7f0e",
                  M.NON_PERIODIC: "#d62728", M.RUNAWAY: "#9467bd", M.FAILED: "#000000"}
REGION_COLORS = {M.ROP_NONE: "#d9d9d9", M.ROP_RUNAWAY: "#d62728", M.ROP_FAILED: "#000000",
                 M.ROP_UNSETTLED: "#ff7f0e"}


def _axis(name: str) -> tuple[float, str]:
    """Display scale and label of a parameter axis or a colour label, in engineering units (``pipeline.core.units``:
    mm, kN, mm/s, ...)."""
    return units.factor(name), units.label(name)



def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges around grid values (uniform or not); a single value gets a unit-free ±5 % cell."""
    v = np.asarray(v, dtype=float)
    if v.size == 1:
        d = abs(v[0]) * 0.05 or 0.5
        return np.array([v[0] - d, v[0] + d])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def _grid(df: pd.DataFrame, col: str, nx: int, ny: int) -> np.ndarray:
    g = np.full((ny, nx), np.nan)
    vals = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)
    g[df["iy"].to_numpy(), df["ix"].to_numpy()] = vals
    return g


def _save(fig, path: str | os.PathLike) -> str:
    return str(atomic_write_figure(path, fig, dpi=110))


def _coords(df, x, y):
    xs = np.sort(df[x].unique())
    ys = np.sort(df[y].unique())
    sx, lx = _axis(x)
    sy, ly = _axis(y)
    return xs, ys, _edges(xs) * sx, _edges(ys) * sy, lx, ly


def plot_peterka(df: pd.DataFrame, x: str, y: str, path, color: str = "peak_force_n", title: str = "") -> str:
    """Left: impact-pattern classes (Peterka map, seed 001 Figs. 13-14); right: ``color`` over impacting cells."""
    xs, ys, ex, ey, lx, ly = _coords(df, x, y)
    nx, ny = xs.size, ys.size
    pat = _grid(df, "pattern", nx, ny)
    codes = sorted(PATTERN_COLORS)
    cmap = ListedColormap([PATTERN_COLORS[c] for c in codes])
    fig, ax = plt.subplots(1, 2, figsize=(13, 5.2))
    ax[0].pcolormesh(ex, ey, pat, cmap=cmap, vmin=-0.5, vmax=len(codes) - 0.5, shading="flat")
    present = set(int(c) for c in np.unique(pat[np.isfinite(pat)]))
    handles = [Patch(facecolor=PATTERN_COLORS[c], edgecolor="k", lw=0.5, label=M.PATTERN_NAMES[c])
               for c in codes if c in present]
    # annotate the period of "other periodic" cells when the grid is small enough to read
    if nx * ny <= 400:
        for _, r in df[df["pattern"] == M.OTHER_PERIODIC].iterrows():
            ax[0].text(r[x] * _axis(x)[0], r[y] * _axis(y)[0], r["pattern_label"], ha="center", va="center",
                       fontsize=6)
    ax[0].legend(handles=handles, loc="upper left", fontsize=8, framealpha=0.9)
    ax[0].set_xlabel(lx)
    ax[0].set_ylabel(ly)
    ax[0].set_title("impact pattern (z = impacts / forcing cycles)")
    scale, clabel = _axis(color)
    val = _grid(df, color, nx, ny) * scale
    val = np.ma.masked_where((pat == M.NO_IMPACT) | ~np.isfinite(val), val)
    ax[1].set_facecolor(PATTERN_COLORS[M.NO_IMPACT])
    mesh = ax[1].pcolormesh(ex, ey, val, cmap="viridis", shading="flat")
    fig.colorbar(mesh, ax=ax[1], label=clabel)
    ax[1].set_xlabel(lx)
    ax[1].set_ylabel(ly)
    ax[1].set_title(f"{color} (no-impact cells blank)")
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def plot_rop(df: pd.DataFrame, x: str, y: str, path, color: str = "rop_m_s", title: str = "") -> str:
    """ROP (or ``color``) over progressing cells; non-progressing, runaway, not-settled and failed regions
    drawn as flat colours with a legend."""
    xs, ys, ex, ey, lx, ly = _coords(df, x, y)
    nx, ny = xs.size, ys.size
    reg = _grid(df, "rop_region", nx, ny)
    fig, ax = plt.subplots(figsize=(8, 5.6))
    codes = [M.ROP_NONE, M.ROP_RUNAWAY, M.ROP_UNSETTLED, M.ROP_FAILED]
    flat = np.ma.masked_where(reg == M.ROP_OK, reg)
    cmap = ListedColormap([REGION_COLORS[c] for c in range(1, 5)])
    ax.pcolormesh(ex, ey, flat, cmap=cmap, vmin=0.5, vmax=4.5, shading="flat")
    scale, clabel = _axis(color)
    val = _grid(df, color, nx, ny) * scale
    val = np.ma.masked_where((reg != M.ROP_OK) | ~np.isfinite(val), val)
    if val.count():
        mesh = ax.pcolormesh(ex, ey, val, cmap="viridis", shading="flat")
        fig.colorbar(mesh, ax=ax, label=clabel)
    present = set(int(c) for c in np.unique(reg[np.isfinite(reg)]))
    handles = [Patch(facecolor=REGION_COLORS[c], edgecolor="k", lw=0.5, label=M.ROP_REGION_NAMES[c])
               for c in codes if c in present]
    if handles:
        ax.legend(handles=handles, loc="upper left", fontsize=8, framealpha=0.9)
    ax.set_xlabel(lx)
    ax.set_ylabel(ly)
    ax.set_title(title)
    fig.tight_layout()
    return _save(fig, path)


def plot_bifurcation(points: pd.DataFrame, strobe: pd.DataFrame, param: str, path, title: str = "") -> str:
    """Top: stroboscopic displacement samples of the impacting mass against ``param`` (up / down
    continuation in two colours); bottom: peak impact force per point and direction."""
    sx, lx = _axis(param)
    sd, sf = units.factor("disp_m"), units.factor("peak_force_n")
    fig, ax = plt.subplots(2, 1, figsize=(9, 8), sharex=True)
    style = {"up": dict(color="C0", marker=".", label="sweep up"), "down": dict(color="C1", marker="x", label="sweep down")}
    for d, st in style.items():
        s = strobe[strobe["direction"] == d]
        if not s.empty:
            ax[0].plot(s[param] * sx, s["disp_m"] * sd, ls="none", ms=3 if d == "up" else 4, alpha=0.7,
                       color=st["color"], marker=st["marker"], label=st["label"])
        p = points[points["direction"] == d]
        if not p.empty:
            f = pd.to_numeric(p["peak_force_n"], errors="coerce")
            ax[1].plot(p[param] * sx, f * sf, color=st["color"], marker=st["marker"], ms=4, lw=1, label=st["label"])
    units.set_label(ax[0], "y", "disp_m", "impacting mass at cycle start")
    ax[0].set_title("stroboscopic samples (one per forcing cycle, recorded window)")
    units.set_label(ax[1], "y", "peak_force_n")
    ax[1].set_xlabel(lx)
    for a in ax:
        a.grid(alpha=0.3)
        if a.get_legend_handles_labels()[0]:
            a.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)
