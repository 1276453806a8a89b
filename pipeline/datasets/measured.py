"""Measured-data datasets (MODELS.md §7): strict ingest and atomic writing.

A dataset is a directory::

    runs.csv            run_id, system, frequency_hz, amplitude_n, static_force_n, gap_m, duration_s (+ extras)
    series/<run_id>.csv t_s plus any of accel_m_s2, force_n, disp_m, progression_m (SI units)
    summary.csv         run_id plus any of rop_m_s, peak_force_n, peak_decel_g, impacts_per_cycle (+ extras)

Time series start at t = 0 at forcing phase 0 (the indenter's forcing is Fa sin(2π f t)) and are
uniformly sampled.  Every problem raises ``UserError`` naming the file, the line (1 = header) and
the column.  Nothing here writes unless the whole dataset is valid (``write_dataset`` builds the
directory next to the target and renames it into place).
"""
from __future__ import annotations


import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from pipeline.core.numbers import PLAUSIBLE_FACTOR, number, plausible
from pipeline.core.bounded import MAX_CSV_BYTES, check_size
from vibrobase.files import atomic_directory, duplicate_csv_column
from pipeline.datasets.daq import DAQ_COLUMNS, DeclaredChain, declared_chains
from sim.controls import CONTROLS

RUN_COLUMNS = ("run_id", "system", "frequency_hz", "gap_m", "duration_s")
"""Required for every run.  The amplitude and static-force columns are required for the runs whose
model has them as parameters: amplitude_n (indenter, drill, rimd) or amplitude_m (pendulum, MODELS.md §3),
static_force_n (indenter, drill)."""
RUN_NUMERIC = {"frequency_hz": "positive", "amplitude_n": "nonnegative", "amplitude_m": "nonnegative",
               "static_force_n": "nonnegative", "gap_m": "nonnegative", "duration_s": "positive"}
RUN_UPPER = {"frequency_hz": 1e6, "amplitude_n": 1e9, "amplitude_m": 10.0, "static_force_n": 1e9, "gap_m": 1.0,
             "duration_s": 1e5}
"""Largest physical value of each numeric runs.csv column [SI] (a lab rig is far inside; 1e300 is a typo)."""
CONTROL_COLUMNS = tuple(c for c in CONTROLS if c not in RUN_COLUMNS)
"""Controls needed only by the runs whose model has them as a parameter (amplitude_n, amplitude_m, static_force_n)."""
OPTIONAL_RUN_COLUMNS = {"record_start_s": "nonnegative"}
"""Optional numeric runs.csv columns; an empty cell means 'not given' for that run (record in steady state)."""
MAX_RUNS = 500
"""Most runs (rows of runs.csv, hence of summary.csv) of a measured dataset: a rig campaign holds tens; a diagnosis
simulates every run at every fit step and its memory grows with the runs (2000 summary runs passed 2 GB, 500 stayed
under 1 GB; 100 000 ended in std::bad_alloc)."""
MAX_FROM_REST_CYCLES = 10_000
"""Most forcing cycles from rest to the end of a record from rest (record_start_s + duration_s): the simulator's
largest window (--setting window); a record that late is in steady state: leave record_start_s empty."""
SERIES_SIGNALS = ("accel_m_s2", "force_n", "disp_m", "progression_m")
SUMMARY_FEATURES = ("rop_m_s", "peak_force_n", "peak_decel_g", "impacts_per_cycle")
SUMMARY_EXTRAS = ("spectral_ratio", "spectral_ratio_ref_hz", "spectral_peak_hz", "impacts_per_cycle_lower_bound")
"""Extra summary columns the diagnosis understands (README.md); ``<feature>_sd`` columns
give a feature's measurement standard deviation.  Other extra columns are allowed and ignored."""
_RUN_ID = re.compile(r"^[A-Za-z0-9_.\-]+$")


@dataclass
class Dataset:
    """A validated measured dataset.  ``runs`` keeps the file order; ``series`` maps run_id to a
    DataFrame (t_s + signals); ``summary`` is indexed by run_id (or None)."""

    runs: pd.DataFrame
    series: dict[str, pd.DataFrame] = field(default_factory=dict)
    summary: pd.DataFrame | None = None
    path: Path | None = None
    known: dict[str, dict[str, float]] = field(default_factory=dict)   # run_id -> known rig parameters
    extra_files: dict[str, str] = field(default_factory=dict)   # relative path -> text (README.md, truth.json)
    chains: dict[str, DeclaredChain] = field(default_factory=dict)   # run_id -> declared DAQ chain (daq_* columns)

    @property
    def systems(self) -> list[str]:
        return sorted(self.runs["system"].unique())


def _where(file: str, line: int, column: str) -> str:
    return f"{file} line {line}, column '{column}'"


def _read_csv(path: Path, label: str) -> pd.DataFrame:
    if not path.exists():
        raise UserError(f"{label}: file not found ({path})")
    check_size(path, MAX_CSV_BYTES, label)          # a folder, device or FIFO is named as such
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    except pd.errors.EmptyDataError:
        raise UserError(f"{label}: file is empty") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as e:
        raise UserError(f"{label}: not a readable CSV file ({str(e).splitlines()[0]})") from None
    df.columns = [str(c).strip() for c in df.columns]
    dup = duplicate_csv_column(path)
    if dup:
        raise UserError(f"{label}: column '{dup}' appears more than once")
    return df


def _numeric(df: pd.DataFrame, col: str, label: str, rule: str | None = None,
             allow_empty: bool | np.ndarray = False, first_row: int = 0) -> np.ndarray:
    """Column as float; the first bad cell raises an error naming file, line and column.
    ``allow_empty``: an empty cell means "not measured" / "not needed" (NaN in memory); a boolean
    array allows it row by row.  ``first_row``: the data row ``df`` starts at (a chunk of a longer file)."""
    raw = df[col].astype(str).str.strip()
    vals = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
    empty = (raw == "").to_numpy()
    bad = ~np.isfinite(vals) & ~(empty & allow_empty)
    if bad.any():
        i = int(np.argmax(bad))
        what = "empty" if raw.iloc[i] == "" else f"'{raw.iloc[i]}' is not a finite number"
        raise UserError(f"{_where(label, first_row + i + 2, col)}: {what}")
    if rule == "positive" and (vals <= 0).any():
        i = int(np.argmax(vals <= 0))
        raise UserError(f"{_where(label, i + 2, col)}: must be > 0, got {vals[i]:g}")
    if rule == "nonnegative" and (vals < 0).any():
        i = int(np.argmax(vals < 0))
        raise UserError(f"{_where(label, i + 2, col)}: must be >= 0, got {vals[i]:g}")
    hi = RUN_UPPER.get(col) if label == "runs.csv" else None
    if hi is not None and (np.nan_to_num(vals) > hi).any():
        i = int(np.argmax(np.nan_to_num(vals) > hi))
        raise UserError(f"{_where(label, i + 2, col)}: {vals[i]:g} is above {hi:g}, the largest physical value")
    return vals


def _load_runs(root: Path) -> pd.DataFrame:
    import sim

    label = "runs.csv"
    df = _read_csv(root / "runs.csv", label)
    missing = [c for c in RUN_COLUMNS if c not in df.columns]
    if missing:
        raise UserError(f"{label}: missing required column(s) {', '.join(missing)} "
                        f"(required: {', '.join(RUN_COLUMNS)})")
    if df.empty:
        raise UserError(f"{label}: no runs (the file has a header but no rows)")
    if len(df) > MAX_RUNS:
        raise UserError(f"{label}: {len(df)} runs, more than the {MAX_RUNS} a measured dataset may hold (MAX_RUNS: "
                        f"each run is simulated at every step of a diagnosis); split the dataset")
    out = pd.DataFrame({"run_id": df["run_id"].str.strip(), "system": df["system"].str.strip()})
    for i, rid in enumerate(out["run_id"]):
        if not _RUN_ID.match(rid):
            raise UserError(f"{_where(label, i + 2, 'run_id')}: '{rid}' is not a valid run id "
                            "(letters, digits, '_', '-', '.')")
    dup = out["run_id"].duplicated()
    if dup.any():
        i = int(np.argmax(dup.to_numpy()))
        raise UserError(f"{_where(label, i + 2, 'run_id')}: run id '{out['run_id'].iloc[i]}' appears twice")
    known = sim.model_names()
    for i, s_ in enumerate(out["system"]):
        if s_ not in known:
            raise UserError(f"{_where(label, i + 2, 'system')}: unknown system '{s_}' (known: {', '.join(known)})")
    params_of = {s_: set(sim.get_model(s_).param_names) for s_ in set(out["system"])}
    for col in CONTROL_COLUMNS:
        need = np.array([col in params_of[s_] for s_ in out["system"]])
        if need.any() and col not in df.columns:
            i = int(np.argmax(need))
            raise UserError(f"{label}: missing column '{col}' (needed by run '{out['run_id'].iloc[i]}', "
                            f"system {out['system'].iloc[i]})")
    for col, rule in RUN_NUMERIC.items():
        if col in RUN_COLUMNS:
            out[col] = _numeric(df, col, label, rule)
        elif col in df.columns:
            need = np.array([col in params_of[s_] for s_ in out["system"]])
            vals = _numeric(df, col, label, rule, allow_empty=~need)
            if (~need & np.isfinite(vals) & (vals != 0)).any():
                i = int(np.argmax(~need & np.isfinite(vals) & (vals != 0)))
                raise UserError(f"{_where(label, i + 2, col)}: system {out['system'].iloc[i]} has no parameter "
                                f"'{col}' (leave the cell empty)")
            out[col] = vals
    for col, rule in OPTIONAL_RUN_COLUMNS.items():
        if col in df.columns:
            out[col] = _numeric(df, col, label, rule, allow_empty=True)
    if "record_start_s" in out.columns:
        cycles = (out["record_start_s"].to_numpy(dtype=float) + out["duration_s"].to_numpy(dtype=float)) \
            * out["frequency_hz"].to_numpy(dtype=float)
        over = np.nan_to_num(cycles, nan=0.0) > MAX_FROM_REST_CYCLES
        if over.any():
            i = int(np.argmax(over))
            raise UserError(f"{_where(label, i + 2, 'record_start_s')}: {out['record_start_s'].iloc[i]:g} s is "
                            f"{cycles[i]:.3g} forcing cycles from rest to the record's end, more than the "
                            f"{MAX_FROM_REST_CYCLES} a record from rest may span (leave the cell empty for a "
                            "steady-state record)")
    for col in df.columns:
        if col not in out.columns:
            out[col] = df[col].to_numpy()
    return out


MAX_SERIES_SAMPLES = 2**24
"""Most samples (rows) of one series file: 16.8 M, 28 min at 10 kHz.  What is kept is 8 bytes per sample and
column (at most 5 columns: 670 MB); the text is read in chunks of :data:`SERIES_CHUNK_ROWS` rows."""
MAX_TOTAL_SAMPLES = 2**25
"""Most samples of all series of a dataset together (at most 1.3 GB of floats)."""
SERIES_CHUNK_ROWS = 2**18
"""Rows parsed at a time: the text of one chunk (tens of MB) is all a series costs beyond its floats."""


def _load_series(path: Path, rid: str, budget: int = MAX_SERIES_SAMPLES) -> pd.DataFrame:
    """Series ``path`` as floats, read chunk by chunk; refused as soon as it passes ``budget`` samples."""
    label = f"series/{rid}.csv"
    if not path.exists():
        raise UserError(f"{label}: file not found ({path})")
    check_size(path, MAX_CSV_BYTES, label)
    limit = min(budget, MAX_SERIES_SAMPLES)
    dup = duplicate_csv_column(path)
    if dup:
        raise UserError(f"{label}: column '{dup}' appears more than once")
    parts: dict[str, list[np.ndarray]] = {}
    n = 0
    try:
        reader = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True,
                             chunksize=SERIES_CHUNK_ROWS)
        for chunk in reader:
            chunk.columns = [str(c).strip() for c in chunk.columns]
            if not parts:
                if "t_s" not in chunk.columns:
                    raise UserError(f"{label}: missing required column 't_s'")
                signals = [c for c in SERIES_SIGNALS if c in chunk.columns]
                if not signals:
                    raise UserError(f"{label}: no signal column (need at least one of {', '.join(SERIES_SIGNALS)})")
                parts = {c: [] for c in ["t_s", *signals]}
            if n + len(chunk) > limit:
                raise UserError(f"{label}: more than {limit} samples (the most "
                                f"{'one series' if limit == MAX_SERIES_SAMPLES else 'the rest of the dataset'} "
                                f"may hold; MAX_SERIES_SAMPLES {MAX_SERIES_SAMPLES}, all series together "
                                f"MAX_TOTAL_SAMPLES {MAX_TOTAL_SAMPLES})")
            for c in parts:
                parts[c].append(_numeric(chunk, c, label, first_row=n))
            n += len(chunk)
    except pd.errors.EmptyDataError:
        raise UserError(f"{label}: file is empty") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as e:
        raise UserError(f"{label}: not a readable CSV file ({str(e).splitlines()[0]})") from None
    if not parts:         # a header and no rows
        raise UserError(f"{label}: only 0 samples (need at least 16)")
    if n < 16:
        raise UserError(f"{label}: only {n} samples (need at least 16)")
    out = pd.DataFrame({c: np.concatenate(v) if len(v) > 1 else v[0] for c, v in parts.items()})
    del parts
    t = out["t_s"].to_numpy()
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.argmax(dt <= 0)) + 1
        raise UserError(f"{_where(label, i + 2, 't_s')}: time is not increasing ({t[i - 1]:.9g} then {t[i]:.9g})")
    med = float(np.median(dt))
    off = np.abs(dt - med) > 1e-3 * med
    if off.any():
        i = int(np.argmax(off)) + 1
        raise UserError(f"{_where(label, i + 2, 't_s')}: not uniformly sampled (step {dt[i - 1]:.6g} s, "
                        f"median step {med:.6g} s)")
    if abs(t[0]) > 0.5 * med:
        raise UserError(f"{_where(label, 2, 't_s')}: series must start at t = 0 (forcing phase 0), got {t[0]:.6g} s")
    return out


DURATION_RTOL = 0.02
"""A run's duration_s may differ from its series' length (samples x step) by one step plus this fraction."""


def _check_durations(runs: pd.DataFrame, series: dict[str, pd.DataFrame]) -> None:
    """UserError naming runs.csv, the line and 'duration_s' when a run's duration disagrees with its series."""
    for i, (rid, dur) in enumerate(zip(runs["run_id"], runs["duration_s"])):
        if rid not in series:
            continue
        t = series[rid]["t_s"].to_numpy()
        dt = float(np.median(np.diff(t)))
        length = len(t) * dt
        if abs(float(dur) - length) > dt + DURATION_RTOL * length:
            raise UserError(f"{_where('runs.csv', i + 2, 'duration_s')}: {float(dur):.6g} s, but series/{rid}.csv "
                            f"holds {len(t)} samples every {dt:.6g} s = {length:.6g} s (they must agree within one "
                            f"sample + {DURATION_RTOL:.0%})")


def _load_summary(root: Path, run_ids: set[str]) -> pd.DataFrame | None:
    path = root / "summary.csv"
    if not path.exists():
        return None
    label = "summary.csv"
    df = _read_csv(path, label)
    if "run_id" not in df.columns:
        raise UserError(f"{label}: missing required column 'run_id'")
    ids = df["run_id"].str.strip()
    for i, rid in enumerate(ids):
        if rid not in run_ids:
            raise UserError(f"{_where(label, i + 2, 'run_id')}: run '{rid}' is not in runs.csv")
    if ids.duplicated().any():
        i = int(np.argmax(ids.duplicated().to_numpy()))
        raise UserError(f"{_where(label, i + 2, 'run_id')}: run '{ids.iloc[i]}' appears twice")
    feats = [c for c in SUMMARY_FEATURES if c in df.columns]
    if not feats:
        raise UserError(f"{label}: no feature column (need at least one of {', '.join(SUMMARY_FEATURES)})")
    out = pd.DataFrame({"run_id": ids})
    numeric = feats + [c for c in SUMMARY_EXTRAS if c in df.columns]
    numeric += [c for c in df.columns if c.endswith("_sd") and c[:-3] in SUMMARY_FEATURES + ("spectral_ratio",)]
    for c in numeric:
        rule = "positive" if c.endswith("_sd") or c == "spectral_ratio_ref_hz" else (
            "nonnegative" if c in ("peak_decel_g", "peak_force_n", "impacts_per_cycle", "spectral_ratio") else None)
        out[c] = _numeric(df, c, label, rule, allow_empty=True)
    have = out[feats].notna().any(axis=1).to_numpy()
    if not have.all():
        i = int(np.argmax(~have))
        raise UserError(f"{_where(label, i + 2, feats[0])}: run '{ids.iloc[i]}' has no feature value "
                        f"(all of {', '.join(feats)} are empty)")
    return out.set_index("run_id")


def load_dataset(path: str | os.PathLike) -> Dataset:
    """Read and validate a dataset directory (MODELS.md §7); raises UserError on any problem."""
    root = Path(path)
    if not root.exists():
        raise UserError(f"dataset '{root}' does not exist")
    if not root.is_dir():
        raise UserError(f"dataset '{root}' is not a directory (expected runs.csv, series/, summary.csv)")
    runs = _load_runs(root)
    ids = set(runs["run_id"])
    series: dict[str, pd.DataFrame] = {}
    sdir = root / "series"
    if sdir.exists():
        left = MAX_TOTAL_SAMPLES
        for f in sorted(sdir.iterdir()):
            if f.suffix != ".csv":
                continue
            if f.stem not in ids:
                raise UserError(f"series/{f.name}: run '{f.stem}' is not in runs.csv")
            series[f.stem] = _load_series(f, f.stem, budget=left)
            left -= len(series[f.stem])
    _check_durations(runs, series)
    chains = declared_chains(runs, {rid: 1.0 / float(np.median(np.diff(df["t_s"].to_numpy())))
                                    for rid, df in series.items()})
    summary = _load_summary(root, ids)
    known = known_parameters(runs)
    for i, rid in enumerate(runs["run_id"]):
        if rid not in series and (summary is None or rid not in summary.index):
            raise UserError(f"{_where('runs.csv', i + 2, 'run_id')}: run '{rid}' has neither a series "
                            f"(series/{rid}.csv) nor a row in summary.csv")
    return Dataset(runs=runs, series=series, summary=summary, path=root, known=known, chains=chains)


def known_parameters(runs: pd.DataFrame) -> dict[str, dict[str, float]]:
    """Known rig parameters of every run (MODELS.md §7): the model defaults, then the ``preset`` column's
    named preset, then explicit columns named after a parameter of the run's model (``M1``, ``k2``, ...).
    An unknown preset, a parameter column that belongs to no parameter of the run's model but to another
    model's, a bad value: UserError naming runs.csv, the line and the column."""
    import sim

    label = "runs.csv"
    controls = set(RUN_NUMERIC) | {"run_id", "system", "preset", *OPTIONAL_RUN_COLUMNS, *DAQ_COLUMNS}
    all_params = {p for m in sim.model_names() for p in sim.get_model(m).param_names} - controls
    out: dict[str, dict[str, float]] = {}
    for i, row in enumerate(runs.to_dict("records")):
        spec = sim.get_model(row["system"])
        preset = str(row.get("preset", "") or "").strip()
        if preset and preset not in spec.presets:
            raise UserError(f"{_where(label, i + 2, 'preset')}: unknown preset '{preset}' for system {row['system']} "
                            f"(known: {', '.join(sorted(spec.presets)) or 'none'})")
        vals: dict[str, float] = {k: v for k, v in spec.presets.get(preset, {}).items() if k not in RUN_NUMERIC}
        for col in runs.columns:
            if col not in all_params:
                continue
            cell = str(row[col]).strip()
            if cell in ("", "nan"):
                continue
            if col not in spec.param_names:
                raise UserError(f"{_where(label, i + 2, col)}: '{col}' is not a parameter of system {row['system']} "
                                f"(known: {', '.join(p for p in spec.param_names if p not in controls)})")
            vals[col] = number(cell, _where(label, i + 2, col))
            default = spec.defaults(preset or None)[col]
            if not plausible(vals[col], default):
                raise UserError(f"{_where(label, i + 2, col)}: {vals[col]:g} is not within a factor "
                                f"{PLAUSIBLE_FACTOR:g} of the model's default {default:g}; not a physical value")
        ctrl = {c: row[c] for c in RUN_NUMERIC if c in spec.param_names and c != "duration_s"
                and c in row and np.isfinite(row[c])}
        try:
            spec.resolve(preset or None, **{**vals, **ctrl})
        except sim.ParameterError as e:
            bad = next((c for c in (*vals, *ctrl) if f"'{c}'" in str(e)), "preset" if preset else "system")
            raise UserError(f"{_where(label, i + 2, bad)}: {e}") from None
        out[row["run_id"]] = vals
    return out


def _fmt(df: pd.DataFrame) -> str:
    """CSV text; NaN (a control a run's system does not have, an unmeasured summary feature) is an empty cell."""
    return df.to_csv(index=False, float_format="%.10g", lineterminator="\n", na_rep="")


def write_dataset(ds: Dataset, path: str | os.PathLike) -> Path:
    """Write ``ds`` to directory ``path`` atomically: the dataset is built in a sibling temporary
    directory and renamed into place (an existing dataset there is replaced only at the end)."""
    root = Path(path)
    if root.exists() and not root.is_dir():
        raise UserError(f"--out '{root}' exists and is not a directory")
    if root.exists() and any(root.iterdir()) and not (root / "runs.csv").exists():
        raise UserError(f"--out '{root}' is a non-empty directory that is not a dataset; choose another path")
    with atomic_directory(root) as tmp:
        (tmp / "runs.csv").write_text(_fmt(ds.runs))
        if ds.series:
            (tmp / "series").mkdir()
            for rid, df in ds.series.items():
                if not np.isfinite(df.to_numpy(dtype=float)).all():
                    raise UserError(f"refusing to write non-finite values in series/{rid}.csv")
                (tmp / "series" / f"{rid}.csv").write_text(_fmt(df))
        if ds.summary is not None:
            (tmp / "summary.csv").write_text(_fmt(ds.summary.reset_index()))
        for rel, text in ds.extra_files.items():
            (tmp / rel).write_text(text)
    return root

