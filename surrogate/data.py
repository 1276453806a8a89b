"""Training data (in memory): check a sweep frame, name its inputs and ranges, derive the regime label.

Regimes (one per point): ``progressing`` (status ok or aperiodic, and rop_m_s > 0), ``no_progress``
(status ok / aperiodic / no_contact with rop_m_s = 0: the bit does not advance the rock), and the
simulator's own ``runaway``, ``not_settled`` and ``failed``.
"""
from __future__ import annotations

import hashlib

import numpy as np
import pandas as pd

from vibrobase.statuses import BOUNDED_STATUSES, IMPACTING_STATUSES, SETTLED_STATUSES, STATUSES
from surrogate.errors import ConfigError, DataError
from surrogate.names import CONTROLS, REGIMES

# Points a regressor of each target is trained and scored on.  ROP and specific energy
# only exist as numbers inside the progressing regime (elsewhere ROP is 0 and specific
# energy infinite); peak force and impacts per cycle exist at every settled point.
DEFAULT_DOMAINS = {"rop_m_s": "progressing", "specific_energy_j_m": "progressing",
                   "peak_force_n": "settled", "impacts_per_cycle": "settled", "power_w": "settled",
                   "peak_decel_g": "settled"}


def regime_of(df: pd.DataFrame) -> pd.Series:
    """Regime label of every row (see module docstring)."""
    status = df["status"].astype(str)
    rop = pd.to_numeric(df["rop_m_s"], errors="coerce")
    out = status.copy()
    out[status.isin(list(SETTLED_STATUSES))] = "no_progress"
    out[status.isin(list(IMPACTING_STATUSES)) & (rop > 0)] = "progressing"
    unknown = sorted(set(out) - set(REGIMES))
    if unknown:
        raise DataError(f"column 'status' has unknown value(s) {unknown}; expected one of {', '.join(STATUSES)}")
    return out


def domain_mask(df: pd.DataFrame, target: str, domain: str) -> np.ndarray:
    """Rows on which ``target`` is learned/scored: 'progressing', 'settled' (a finite label), or 'all'."""
    y = pd.to_numeric(df[target], errors="coerce").to_numpy(dtype=float)
    finite = np.isfinite(y)
    if domain == "progressing":
        return (regime_of(df) == "progressing").to_numpy() & finite
    if domain == "settled":
        return df["status"].isin(list(BOUNDED_STATUSES)).to_numpy() & finite
    if domain == "all":
        return finite
    raise ConfigError(f"train.domains.{target}: unknown domain '{domain}' (progressing, settled or all)")


def fingerprint_frame(df: pd.DataFrame) -> str:
    """sha256 of a frame's content (used when a dataset has no metadata.json fingerprint)."""
    h = hashlib.sha256(pd.util.hash_pandas_object(df, index=False).to_numpy().tobytes())
    h.update(",".join(map(str, df.columns)).encode())
    return h.hexdigest()


def check_frame(df: pd.DataFrame, name: str = "dataset") -> pd.DataFrame:
    """A sweep frame ready for training: the ``status`` and ``rop_m_s`` columns present (DataError naming
    ``name`` otherwise), rows ordered by ``point_id`` when there is one."""
    for col in ("status", "rop_m_s"):
        if col not in df.columns:
            raise DataError(f"{name} has no column '{col}' (is it a vibro sweep dataset?)")
    if "point_id" in df.columns:
        df = df.sort_values("point_id", kind="stable").reset_index(drop=True)
    return df


def infer_inputs(df: pd.DataFrame, meta: dict, inputs: list[str] | None = None) -> tuple[list[str], dict]:
    """Input names and their (low, high) ranges: given, else metadata ``vary``, else varying controls."""
    vary = meta.get("vary") or {}
    if inputs:
        names = list(inputs)
    elif vary:
        names = list(vary)
    else:
        names = [c for c in CONTROLS if c in df.columns and df[c].nunique() > 1]
    if not names:
        raise DataError("no inputs: the dataset has no metadata 'vary' and no varying control column; "
                        "name them with --inputs")
    ranges = {}
    for n in names:
        if n not in df.columns:
            raise DataError(f"input '{n}' is not a column of the dataset")
        col = pd.to_numeric(df[n], errors="coerce")
        if col.isna().any():
            raise DataError(f"column '{n}' has missing or non-numeric values (row {int(np.flatnonzero(col.isna())[0])})")
        if n in vary and "low" in vary[n] and "high" in vary[n]:
            ranges[n] = (float(vary[n]["low"]), float(vary[n]["high"]))
        else:
            ranges[n] = (float(col.min()), float(col.max()))
        if not ranges[n][1] > ranges[n][0]:
            raise DataError(f"input '{n}' does not vary in the dataset (range {ranges[n]})")
    return names, ranges


def scales(meta: dict, inputs: list[str]) -> dict[str, str]:
    """'log' or 'linear' per input, from metadata ``vary[name].scale`` (default linear)."""
    vary = meta.get("vary") or {}
    return {n: str((vary.get(n) or {}).get("scale", "linear")) for n in inputs}
