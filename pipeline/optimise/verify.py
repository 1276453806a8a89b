"""Re-simulate predicted operating points, compare prediction and simulation, close the loop."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
import os
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from pipeline.core.bounded import MAX_CSV_BYTES, check_size
from pipeline.optimise.constraints import Constraints
from vibrobase.files import atomic_write_parquet
from surrogate.names import REGIME_TO_STATUS, TARGETS  # noqa: F401 (TARGETS re-exported)

COMPARED = TARGETS
"""Labels whose prediction is set next to the simulation (every surrogate target)."""


def _f(x) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return math.nan
    return v


def _rel_error(p: float, s: float, floor: float) -> float:
    return abs(p - s) / max(abs(s), floor) if math.isfinite(p) and math.isfinite(s) else math.inf


REL_FLOOR = {"rop_m_s": 1e-9}
"""Smallest denominator of a relative error [label units] (default 1e-12)."""


def compare(pred: pd.DataFrame, simres: pd.DataFrame, inputs: list[str], constraints: Constraints,
            rel_tol: float, objectives: list[str] | tuple[str, ...] = ("rop_m_s",)) -> pd.DataFrame:
    """One row per point: inputs, ``T_pred`` [``T_lo``, ``T_hi``] and ``T_sim`` for each label,
    status_pred / status_sim, feasible_pred / feasible_sim, ``T_rel_error`` of ROP and of every
    optimised objective, in_interval (ROP), surrogate_wrong and why (text).

    The prediction is *wrong* when its feasibility differs from the simulator's, or its ROP or any
    objective in ``objectives`` is off by more than ``rel_tol`` relative to the simulated value
    (absolute floor 1e-9 m/s for ROP).
    """
    checked = ["rop_m_s", *[o for o in objectives if o != "rop_m_s"]]
    pred = pred.reset_index(drop=True)
    simres = simres.reset_index(drop=True)
    rows = []
    for i in range(len(pred)):
        p, s = pred.iloc[i].to_dict(), simres.iloc[i].to_dict()
        rec = {n: p[n] for n in inputs}
        for t in COMPARED:
            if t in p:
                rec[f"{t}_pred"] = _f(p[t])
            for b in ("lo", "hi"):
                if f"{t}_{b}" in p:
                    rec[f"{t}_{b}"] = _f(p[f"{t}_{b}"])
            rec[f"{t}_sim"] = _f(s.get(t))
        s_row = {**s}
        p_row = {**p, "static_force_n": s.get("static_force_n", p.get("static_force_n"))}
        rec["status_pred"] = p.get("regime", p.get("status"))
        rec["status_sim"] = s["status"]
        rec["reason_sim"] = s.get("reason", "")
        rec["feasible_pred"] = constraints.feasible(p_row)
        rec["feasible_sim"] = constraints.feasible(s_row)
        rec["violation_sim"] = constraints.violation(s_row)
        rels = {}
        for t in checked:
            rec.setdefault(f"{t}_sim", _f(s.get(t)))
            rec.setdefault(f"{t}_pred", _f(p.get(t)))
            rels[t] = _rel_error(rec[f"{t}_pred"], rec[f"{t}_sim"], REL_FLOOR.get(t, 1e-12))
            rec[f"{t}_rel_error"] = rels[t]
        rec["rop_rel_error"] = rels["rop_m_s"]
        rs = rec["rop_m_s_sim"]
        lo, hi = rec.get("rop_m_s_lo"), rec.get("rop_m_s_hi")
        rec["in_interval"] = (bool(lo <= rs <= hi) if lo is not None and hi is not None and math.isfinite(rs)
                              else None)
        why = []
        if rec["feasible_pred"] != rec["feasible_sim"]:
            why.append(f"predicted {'feasible' if rec['feasible_pred'] else 'infeasible'} but simulated "
                       f"{'feasible' if rec['feasible_sim'] else 'infeasible'} (status {s['status']})")
        for t, rel in rels.items():
            if rel > rel_tol:
                what = "ROP" if t == "rop_m_s" else t
                why.append(f"{what} off by {rel:.1%}" if math.isfinite(rel) else f"no simulated {what}")
        rec["surrogate_wrong"] = bool(why)
        rec["why"] = "; ".join(why)
        rows.append(rec)
    return pd.DataFrame(rows)


def best_verified(table: pd.DataFrame) -> pd.Series | None:
    """The verified feasible point with the largest simulated ROP (None if none is feasible)."""
    ok = table[table["feasible_sim"] & np.isfinite(table["rop_m_s_sim"].astype(float))]
    if ok.empty:
        return None
    return ok.loc[ok["rop_m_s_sim"].astype(float).idxmax()]


def write_parquet_atomic(df: pd.DataFrame, path: Path) -> None:
    """Write ``df`` to Parquet atomically (vibrobase.files); NaN → null."""
    atomic_write_parquet(path, df)


def append_feedback(simres: pd.DataFrame, path: str | os.PathLike, source: str, study: str,
                    wrong: list[bool] | None = None, inputs: list[str] | None = None) -> int:
    """Append simulated points (resolved inputs + labels, the sweep dataset's columns) to the
    feedback Parquet file that ``vibro train`` can include.  Returns the number of rows now in it.

    Extra columns: point_id (continuing the file's numbering), source, study, created (UTC ISO),
    surrogate_wrong.  Numeric labels stay null where the simulator gives none (runaway/failed).
    Rows already in the file for the same study and ``inputs`` values (a rerun) are not added twice.
    """
    path = Path(path)
    new = simres.reset_index(drop=True).copy()
    old = None
    if path.exists():
        try:
            old = pd.read_parquet(path)
        except Exception as e:  # noqa: BLE001
            raise UserError(f"feedback file {path}: cannot be read as Parquet ({e})") from None
    if old is not None and inputs and "study" in old and all(n in old for n in inputs):
        seen = set(map(tuple, old.loc[old["study"] == study, inputs].to_numpy(float).round(12)))
        keep = [tuple(r) not in seen for r in new[inputs].to_numpy(float).round(12)]
        new = new[keep].reset_index(drop=True)
        wrong = [w for w, k in zip(wrong, keep) if k] if wrong is not None else None
        if new.empty:
            return len(old)
    start = int(old["point_id"].max()) + 1 if old is not None and len(old) and "point_id" in old else 0
    new.insert(0, "point_id", np.arange(start, start + len(new), dtype=np.int64))
    new["source"] = source
    new["study"] = study
    new["created"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
    new["surrogate_wrong"] = list(wrong) if wrong is not None else [False] * len(new)
    for c in new.columns:
        if new[c].dtype == object and c not in ("status", "reason", "source", "study", "created"):
            try:
                new[c] = pd.to_numeric(new[c])
            except (TypeError, ValueError):
                pass
    allrows = new if old is None else pd.concat([old, new], ignore_index=True)
    write_parquet_atomic(allrows, path)
    return len(allrows)


def read_feedback(path: str | os.PathLike, studies: list[str] | tuple[str, ...]) -> pd.DataFrame:
    """The rows of the feedback file ``path`` that the studies ``studies`` appended (empty when none): the
    simulated points a surrogate is retrained on."""
    path = Path(path)
    if not path.exists():
        return pd.DataFrame()
    try:
        fb = pd.read_parquet(path)
    except Exception as e:  # noqa: BLE001
        raise UserError(f"feedback file {path}: cannot be read as Parquet ({e})") from None
    if "study" not in fb:
        raise UserError(f"feedback file {path}: no 'study' column (not written by vibro optimise or verify)")
    return fb[fb["study"].isin(list(studies))].reset_index(drop=True)


__all__ = ["compare", "best_verified", "append_feedback", "read_feedback", "write_parquet_atomic", "TARGETS"]


def read_points(path: str | os.PathLike) -> pd.DataFrame:
    """Points to verify from a CSV or Parquet file (UserError naming the file on failure)."""
    p = Path(path)
    if not p.exists():
        raise UserError(f"points file {p}: not found")
    check_size(p, MAX_CSV_BYTES, "points file")
    try:
        df = pd.read_parquet(p) if p.suffix.lower() in (".parquet", ".pq") else pd.read_csv(p)
    except Exception as e:  # noqa: BLE001
        raise UserError(f"points file {p}: cannot be read ({str(e).splitlines()[0]})") from None
    if df.empty:
        raise UserError(f"points file {p}: no rows")
    if p.suffix.lower() not in (".parquet", ".pq"):
        from vibrobase.files import duplicate_csv_column

        dup = duplicate_csv_column(p)
        if dup:
            raise UserError(f"points file {p}: column '{dup}' appears more than once")
    return df


def verify_points(points: pd.DataFrame, model: str, preset: str | None, inputs: list[str], constraints: Constraints,
                  rel_tol: float, bundle=None, fixed: dict | None = None, settings=None, n_threads=None,
                  source: str = "points file") -> tuple[pd.DataFrame, pd.DataFrame]:
    """Re-simulate ``points[inputs]``; predictions from ``bundle`` if given, else from the file's
    ``rop_m_s``/``peak_force_n``/... columns (or ``T_pred``).  Returns (comparison table, simulator rows).

    Non-numeric or missing input values raise UserError naming the row and column."""
    from pipeline.optimise.evaluators import SimulatorEvaluator, SurrogateEvaluator

    for c in inputs:
        if c not in points.columns:
            raise UserError(f"{source}: missing column '{c}' (needs {', '.join(inputs)})")
        col = pd.to_numeric(points[c], errors="coerce")
        bad = np.flatnonzero(~np.isfinite(col.to_numpy(dtype=float)))
        if bad.size:
            raise UserError(f"{source}: row {int(bad[0])} column '{c}': {points[c].iloc[bad[0]]!r} is not a finite number")
    X = points[inputs].astype(float).reset_index(drop=True)
    if bundle is not None:
        pred = SurrogateEvaluator(bundle, fixed)(X)
    else:
        pred = X.copy()
        for t in COMPARED:
            for src in (f"{t}_pred", t):
                if src in points.columns:
                    pred[t] = pd.to_numeric(points[src], errors="coerce").to_numpy()
                    break
            for b in ("lo", "hi"):
                if f"{t}_{b}" in points.columns:
                    pred[f"{t}_{b}"] = pd.to_numeric(points[f"{t}_{b}"], errors="coerce").to_numpy()
        if "status" in points.columns:
            pred["status"] = points["status"].astype(str).to_numpy()
        elif "regime" in points.columns:
            pred["status"] = [REGIME_TO_STATUS.get(str(r), "failed") for r in points["regime"]]
        else:
            pred["status"] = "ok"
        if "rop_m_s" not in pred:
            raise UserError(f"{source}: nothing to compare with — give --surrogate, or a column rop_m_s "
                            f"(or rop_m_s_pred) with the predicted ROP")
    simres = SimulatorEvaluator(model, preset, fixed, settings=settings, n_threads=n_threads)(X)
    return compare(pred, simres, inputs, constraints, rel_tol), simres


def summarise(table: pd.DataFrame) -> dict:
    """Metrics of a verification: ROP errors, interval coverage, feasibility agreement, wrong count."""
    rel = table["rop_rel_error"].astype(float)
    fin = rel[np.isfinite(rel)]
    cov = table["in_interval"].dropna() if "in_interval" in table else pd.Series([], dtype=object)
    return {"n_points": int(len(table)), "n_surrogate_wrong": int(table["surrogate_wrong"].sum()),
            "rop_rel_error_median": float(fin.median()) if len(fin) else None,
            "rop_rel_error_max": float(fin.max()) if len(fin) else None,
            "rop_interval_coverage": float(cov.astype(bool).mean()) if len(cov) else None,
            "feasibility_agreement": float((table["feasible_pred"] == table["feasible_sim"]).mean()),
            "status_sim_counts": {str(k): int(v) for k, v in table["status_sim"].value_counts().items()}}


CHUNK = 32
"""Points re-simulated per call (the progress bar's step)."""


def verify_in_chunks(points: pd.DataFrame, model: str, preset: str | None, inputs: list[str], constraints: Constraints,
                     rel_tol: float, bundle=None, fixed: dict | None = None, settings=None, n_threads=None,
                     source: str = "points file", progress: bool = True) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``verify_points`` over chunks of ``points`` with a progress bar on stderr; same result as one call
    (every point is verified on its own)."""
    import sys

    from tqdm import tqdm

    for c in inputs:                      # row numbers of the whole file in the error, not of a chunk
        if c in points.columns:
            col = pd.to_numeric(points[c], errors="coerce").to_numpy(dtype=float)
            bad = np.flatnonzero(~np.isfinite(col))
            if bad.size:
                raise UserError(f"{source}: row {int(bad[0])} column '{c}': {points[c].iloc[bad[0]]!r} "
                                "is not a finite number")
    tables, sims = [], []
    with tqdm(total=len(points), desc="verify (simulate)", unit="pt", disable=not progress, file=sys.stderr) as bar:
        for i in range(0, max(len(points), 1), CHUNK):
            t, r = verify_points(points.iloc[i:i + CHUNK], model, preset, inputs, constraints, rel_tol, bundle=bundle,
                                 fixed=fixed, settings=settings, n_threads=n_threads, source=source)
            tables.append(t)
            sims.append(r)
            bar.update(len(t))
    return pd.concat(tables, ignore_index=True), pd.concat(sims, ignore_index=True)


@dataclass(frozen=True)
class VerifyConfig:
    """What ``run_verify`` re-simulates: the points (already read), where they came from, the model and how
    predictions are made (``bundle`` or the file's own columns)."""
    points: pd.DataFrame
    source: str                      # the points file (messages, feedback study name, figure title)
    model: str
    preset: str | None
    inputs: list[str]
    constraints: Constraints
    rel_tol: float = 0.1             # ROP relative error marking a wrong prediction [-]
    bundle: object | None = None     # surrogate bundle predicting the points, else the file's columns
    fixed: dict = field(default_factory=dict)
    settings: object | None = None
    n_threads: int | None = None
    feedback: str | None = None      # parquet file the simulated points are appended to


@dataclass(frozen=True)
class VerifyResult:
    """The comparison table, the simulator rows, the summary metrics and the files written."""
    table: pd.DataFrame
    simres: pd.DataFrame
    summary: dict
    table_path: Path                 # verified.csv
    summary_path: Path               # summary.json
    figure: str                      # verification.png


def run_verify(cfg: VerifyConfig, out_dir: str | os.PathLike, progress: bool = True) -> VerifyResult:
    """Re-simulate ``cfg.points``, write verified.csv, verification.png and summary.json under ``out_dir``,
    append the simulated points to ``cfg.feedback`` (its row count goes into the summary)."""
    from vibrobase.files import atomic_write_text, atomic_write_with
    from vibrobase.jsonable import dump_json
    from pipeline.optimise import plots

    out = Path(out_dir)
    table, simres = verify_in_chunks(cfg.points, cfg.model, cfg.preset, cfg.inputs, cfg.constraints, cfg.rel_tol,
                                     bundle=cfg.bundle, fixed=cfg.fixed, settings=cfg.settings,
                                     n_threads=cfg.n_threads, source=cfg.source, progress=progress)
    summary = summarise(table)
    atomic_write_with(out / "verified.csv", lambda f: table.to_csv(f, index=False))
    fig = plots.plot_verification(table, out / "verification.png", f"verify: {Path(cfg.source).name}")
    if cfg.feedback:
        summary["feedback_rows"] = append_feedback(simres, cfg.feedback, source="verify", study=Path(cfg.source).name,
                                                   wrong=table["surrogate_wrong"].tolist(), inputs=cfg.inputs)
    atomic_write_text(out / "summary.json", dump_json(summary))
    return VerifyResult(table, simres, summary, out / "verified.csv", out / "summary.json", fig)
