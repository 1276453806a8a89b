"""Rows a surrogate may learn from: inputs that are no labels, input values inside the sweep's space, labels
the simulator can write.  A bad row is refused (UserError naming the column and the row), never dropped: the
trained ranges and the fitted models then come only from rows that passed."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError

INF_WHEN_NO_PROGRESS = ("specific_energy_j_m",)
"""Labels the simulator writes as +inf where the bit does not progress (rop_m_s <= 0): energy over no depth."""

RANGE_RTOL = 1e-9
"""A value may pass its declared range's ends by this fraction of the range's width (round-off of the design)."""
OUTLIER_IQR = 100.0
"""Without a declared range, an input value this many interquartile ranges beyond the middle half is refused: a
design never puts a point there (1e300 Hz among 150-450 Hz), a damaged row does."""


def check_not_labels(inputs: list[str], where: str) -> None:
    """UserError when an input is a MODELS.md §5 label (an output of the simulator, unknown before it runs)."""
    from sim import LABELS

    for n in inputs:
        if n in LABELS or n in ("status", "reason"):
            raise UserError(f"{where}: input '{n}' is a label (MODELS.md §5), an output of the simulator; "
                            f"a surrogate's inputs are parameters or controls")


def _row(df: pd.DataFrame, i: int) -> str:
    pid = f" (point_id {int(df['point_id'].iloc[i])})" if "point_id" in df.columns else ""
    return f"row {i}{pid}"


def check_inputs(df: pd.DataFrame, inputs: list[str], meta: dict, model: str, where: str) -> None:
    """UserError naming the column and row of an input value that is not finite, no valid value of its
    parameter (the model's ``Param``), or outside the sweep's declared range (metadata ``vary``)."""
    import sim

    params = {p.name: p for p in sim.get_model(model).params} if model in sim.model_names() else {}
    vary = meta.get("vary") or {}
    for n in inputs:
        x = pd.to_numeric(df[n], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(x)
        if bad.any():
            i = int(np.argmax(bad))
            raise UserError(f"{where}: column '{n}', {_row(df, i)}: {x[i]!r} is not a finite number")
        if n in params:
            for i, v in enumerate(x):
                try:
                    params[n].validate(v)
                except sim.ParameterError as e:
                    raise UserError(f"{where}: column '{n}', {_row(df, i)}: {e}") from None
        r = vary.get(n) or {}
        if not ("low" in r and "high" in r) and x.size >= 8:   # no declared range: a value far outside the rest
            q1, q3 = np.percentile(x, [25, 75])
            span = max(q3 - q1, 0.1 * abs(float(np.median(x))), 1e-300)    # a column held mostly at one value
            out = (x < q1 - OUTLIER_IQR * span) | (x > q3 + OUTLIER_IQR * span)
            if out.any():
                i = int(np.argmax(out))
                raise UserError(f"{where}: column '{n}', {_row(df, i)}: {x[i]:g} lies {OUTLIER_IQR:g} interquartile "
                                f"ranges outside the other values [{q1:g}, {q3:g}] and no sweep range is declared: "
                                f"a corrupt row? remove it or train on the sweep's folder")
        if "low" in r and "high" in r:
            lo, hi = float(r["low"]), float(r["high"])
            tol = RANGE_RTOL * (hi - lo)
            out = (x < lo - tol) | (x > hi + tol)
            if out.any():
                i = int(np.argmax(out))
                raise UserError(f"{where}: column '{n}', {_row(df, i)}: {x[i]:g} is outside the sweep's declared "
                                f"range [{lo:g}, {hi:g}]")


def check_labels(df: pd.DataFrame, where: str) -> None:
    """UserError naming the column and row of a label that is negative or infinite (every §5 label is a
    magnitude, a count, a rate of an irreversible progression or an energy taken from the exciter); null labels
    are the failed rows' and pass; ``INF_WHEN_NO_PROGRESS`` labels may be +inf where rop_m_s <= 0."""
    from sim import LABELS

    rop = pd.to_numeric(df["rop_m_s"], errors="coerce").to_numpy(dtype=float) if "rop_m_s" in df else None
    for n in LABELS:
        if n not in df.columns:
            continue
        y = pd.to_numeric(df[n], errors="coerce").to_numpy(dtype=float)
        allowed = np.zeros(len(y), dtype=bool)
        if n in INF_WHEN_NO_PROGRESS and rop is not None:
            allowed = (y == math.inf) & ~(rop > 0)
        bad = (np.isinf(y) & ~allowed) | (y < 0)
        if bad.any():
            i = int(np.argmax(bad))
            why = "infinite" if np.isinf(y[i]) else "negative"
            raise UserError(f"{where}: column '{n}', {_row(df, i)}: {y[i]:g} is {why}; a simulated label never is")
