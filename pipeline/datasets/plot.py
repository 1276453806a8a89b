"""Overview figure of a sweep dataset: ROP over the first two varied parameters, statuses marked."""
from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from pipeline.core import units  # noqa: E402

_MARKERS = {"aperiodic": ("d", "C2"), "no_contact": ("s", "0.6"), "not_settled": ("^", "C1"), "runaway": ("x", "C3"),
            "failed": ("X", "k")}


def plot_sweep(df: pd.DataFrame, xname: str, yname: str, path: str | os.PathLike, title: str = "") -> str:
    """Scatter of ``yname`` against ``xname`` (engineering units): ``ok`` points coloured by ROP, every other status
    with its own marker (nothing left out).  Saved as PNG at ``path`` (atomically); returns the path."""
    fig, ax = plt.subplots(figsize=(7.5, 5.5))
    ok = df["status"] == "ok"     # aperiodic points keep their own marker
    fx, fy = units.set_label(ax, "x", xname), units.set_label(ax, "y", yname)
    rop = df.loc[ok, "rop_m_s"].to_numpy(dtype=float) * units.factor("rop_m_s")
    sc = ax.scatter(df.loc[ok, xname] * fx, df.loc[ok, yname] * fy, c=rop, s=14, cmap="viridis",
                    label=f"ok ({ok.sum()})")
    fig.colorbar(sc, ax=ax, label=units.label("rop_m_s"))
    for status, (marker, color) in _MARKERS.items():
        sel = df["status"] == status
        if sel.any():
            ax.scatter(df.loc[sel, xname] * fx, df.loc[sel, yname] * fy, marker=marker, c=color, s=22,
                       label=f"{status} ({int(sel.sum())})")
    ax.set_title(title or f"sweep: {len(df)} points")
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    from vibrobase.files import atomic_write_figure

    return str(atomic_write_figure(path, fig, dpi=110))

