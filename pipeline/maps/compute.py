"""Response maps (computations): Peterka maps, ROP maps and bifurcation diagrams on top of ``sim``.

* :func:`classify_pattern` / :func:`add_pattern` — impact-pattern class of a labelled run (MODELS.md §5
  labels ``status``, ``impacts_per_cycle``, ``period``): no impact, z = 1/1, z = 1/2, other periodic
  (with its period and impacts per period), non-periodic, and runaway / failed.
* :func:`grid_map` — a 2-D grid of two parameters through ``sim.simulate_batch`` (threads, GIL released),
  in chunks so a progress bar can follow it.  Used for the Peterka map (seed 001 Figs. 13-14: gap ×
  frequency, coloured by the maximum impact force) and for ROP maps (frequency × amplitude / static force).
* :func:`bifurcation` — a one-parameter continuation sweep: each point starts from the previous point's
  final state (``sim.simulate(..., initial_state=...)``), swept up, down or both, so coexisting attractors
  and jumps show; records the stroboscopic samples (once per forcing cycle, exact cycle starts) of the
  impacting mass's displacement and every label.

Files are written atomically by :func:`write_parquet` (temporary file in the same folder, then ``os.replace``).
"""
from __future__ import annotations

import math
import os
from typing import Callable, Iterable

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from vibrobase.errors import did_you_mean
from vibrobase.files import atomic_write_parquet

# ----------------------------------------------------------------------------- impact-pattern classes
NO_IMPACT, Z11, Z12, OTHER_PERIODIC, NON_PERIODIC, RUNAWAY, FAILED = range(7)
PATTERN_NAMES = {NO_IMPACT: "no impact", Z11: "z=1/1", Z12: "z=1/2", OTHER_PERIODIC: "other periodic",
                 NON_PERIODIC: "non-periodic", RUNAWAY: "runaway", FAILED: "failed"}

KINDS = {"pattern": "peterka", "rop": "rop"}
"""ModelSpec.map_kind -> the 2-D map a model gets by default (``vibro map --kind auto``)."""


def default_kind(model: str) -> str:
    """The default 2-D map of ``model``: its ``ModelSpec.map_kind`` (impact patterns when it names none)."""
    from sim import get_model

    return KINDS.get(get_model(model).map_kind, "peterka")


def classify_pattern(status: str, impacts_per_cycle, period) -> tuple[int, str]:
    """Impact-pattern class and its short label for one run.

    status: MODELS.md §5 status; impacts_per_cycle: contact onsets per forcing cycle; period: smallest
    n ≤ 8 of the stroboscopic samples (0 = none).  Returns (class code, label):
    ``no impact`` (no contact in the window), ``z=1/1`` (period 1, one impact per cycle), ``z=1/2``
    (period 2, one impact per two cycles), ``other periodic`` labelled ``k/n`` (k impacts per period of n
    cycles), ``non-periodic`` (no period ≤ 8, including runs still transient at the cap), ``runaway``,
    ``failed``.  A run without impacts is ``no impact`` whatever its period.
    """
    if status == "runaway":
        return RUNAWAY, "runaway"
    if status == "failed" or impacts_per_cycle is None:
        return FAILED, "failed"
    ipc = float(impacts_per_cycle)
    if status == "no_contact" or ipc == 0.0:
        return NO_IMPACT, "no impact"
    n = 0 if period is None or (isinstance(period, float) and math.isnan(period)) else int(period)
    if status == "not_settled" or n <= 0:
        return NON_PERIODIC, "non-periodic"
    k = int(round(ipc * n))
    if n == 1 and k == 1:
        return Z11, "z=1/1"
    if n == 2 and k == 1:
        return Z12, "z=1/2"
    return OTHER_PERIODIC, f"{k}/{n}"


def add_pattern(df: pd.DataFrame) -> pd.DataFrame:
    """Add ``pattern`` (class code), ``pattern_name`` and ``pattern_label`` columns to a labelled table."""
    out = df.copy()
    codes, labels = [], []
    for st, ipc, per in zip(out["status"], out["impacts_per_cycle"], out["period"]):
        c, lab = classify_pattern(st, None if _isnull(ipc) else ipc, None if _isnull(per) else per)
        codes.append(c)
        labels.append(lab)
    out["pattern"] = np.array(codes, dtype=np.int64)
    out["pattern_name"] = [PATTERN_NAMES[c] for c in codes]
    out["pattern_label"] = labels
    return out


def _isnull(v) -> bool:
    return v is None or (isinstance(v, float) and math.isnan(v))


# ----------------------------------------------------------------------------- ROP regions
ROP_OK, ROP_NONE, ROP_RUNAWAY, ROP_FAILED, ROP_UNSETTLED = range(5)
ROP_REGION_NAMES = {ROP_OK: "progressing", ROP_NONE: "non-progressing", ROP_RUNAWAY: "runaway",
                    ROP_FAILED: "failed", ROP_UNSETTLED: "not settled"}


def rop_region(status: str, rop_m_s, floor_m_s: float = 1e-9) -> int:
    """Region of an ROP map cell: progressing (ROP > floor [m/s]), non-progressing (no contact or
    ROP ≤ floor), runaway (no bounded steady state), not settled, failed."""
    if status == "runaway":
        return ROP_RUNAWAY
    if status == "failed" or _isnull(rop_m_s):
        return ROP_FAILED
    if status == "not_settled":
        return ROP_UNSETTLED if float(rop_m_s) > floor_m_s else ROP_NONE
    return ROP_OK if float(rop_m_s) > floor_m_s else ROP_NONE


def add_rop_region(df: pd.DataFrame, floor_m_s: float = 1e-9) -> pd.DataFrame:
    out = df.copy()
    codes = [rop_region(s, None if _isnull(r) else r, floor_m_s) for s, r in zip(out["status"], out["rop_m_s"])]
    out["rop_region"] = np.array(codes, dtype=np.int64)
    out["rop_region_name"] = [ROP_REGION_NAMES[c] for c in codes]
    return out


# ----------------------------------------------------------------------------- axes
def axis_values(model: str, name: str, lo: float | None, hi: float | None, n: int, log: bool = False,
                base: dict | None = None) -> np.ndarray:
    """Grid values of one axis: ``n`` points from ``lo`` to ``hi`` (defaults: ``ModelSpec.map_ranges``; a range in
    ``map_relative_to`` is a multiple of that parameter taken from ``base``, the resolved parameters of the map's preset)."""
    from sim import get_model

    spec = get_model(model)
    if name not in spec.param_names:
        raise UserError(f"'{name}' is not a parameter of model '{model}'{did_you_mean(name, spec.param_names)}; "
                        f"known: {', '.join(spec.param_names)}")
    if lo is None or hi is None:
        rng = spec.map_ranges.get(name)
        if rng is None:
            raise UserError(f"no default range for '{name}' of model '{model}': give its range, e.g. "
                            f"--x-range LO HI")
        ref = spec.map_relative_to.get(name)
        if ref is not None:
            scale = float((base or spec.defaults())[ref])
            rng = (rng[0] * scale, rng[1] * scale)
        lo = rng[0] if lo is None else lo
        hi = rng[1] if hi is None else hi
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi < lo:
        raise UserError(f"range of '{name}' must be finite with LO <= HI, got {lo:g} .. {hi:g}")
    if n < 1:
        raise UserError(f"number of points along '{name}' must be >= 1, got {n}")
    if log:
        if lo <= 0:
            raise UserError(f"log axis of '{name}' needs LO > 0, got {lo:g}")
        return np.geomspace(lo, hi, n)
    return np.linspace(lo, hi, n) if n > 1 else np.array([lo])


# ----------------------------------------------------------------------------- grid maps
def grid_map(model: str, x: str, xs: Iterable[float], y: str, ys: Iterable[float], preset: str | None = None,
             fixed: dict | None = None, settings=None, n_threads: int | None = None,
             progress: Callable[[int], None] | None = None, chunk: int | None = None) -> pd.DataFrame:
    """Simulate every (x, y) cell from rest and return the labelled table with pattern and ROP-region columns.

    fixed: other parameter overrides (validated by ``sim``).  progress(k) is called after each chunk
    with the number of cells just finished.  Rows are ordered y-major (all x for the first y, ...).
    """
    import sim

    xs = np.asarray(list(xs), dtype=float)
    ys = np.asarray(list(ys), dtype=float)
    if x == y:
        raise UserError(f"--x and --y must be different parameters (both are '{x}')")
    fixed = dict(fixed or {})
    for k in (x, y):
        fixed.pop(k, None)
    table = [dict(fixed, **{x: float(xv), y: float(yv)}) for yv in ys for xv in xs]
    # validate every row before anything runs (ParameterError names the row and the column)
    spec = sim.get_model(model)
    for i, rec in enumerate(table):
        try:
            spec.resolve(preset, **rec)
        except sim.ParameterError as e:
            raise sim.ParameterError(f"map cell {i} ({x}={rec[x]:g}, {y}={rec[y]:g}): {e}") from None
    threads = n_threads or os.cpu_count() or 1
    chunk = chunk or max(4 * threads, 16)
    parts = []
    for start in range(0, len(table), chunk):
        part = sim.simulate_batch(model, table[start:start + chunk], preset=preset, settings=settings,
                                  n_threads=threads)
        parts.append(part)
        if progress is not None:
            progress(len(part))
    df = pd.concat(parts, ignore_index=True)
    df.insert(0, "iy", np.repeat(np.arange(ys.size), xs.size))
    df.insert(0, "ix", np.tile(np.arange(xs.size), ys.size))
    df = add_pattern(df)
    if "rop_m_s" in df:
        df = add_rop_region(df)
    return df


# ----------------------------------------------------------------------------- bifurcation diagram
def bifurcation(model: str, param: str, values: Iterable[float], direction: str = "both",
                preset: str | None = None, fixed: dict | None = None, settings=None,
                progress: Callable[[int], None] | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Continuation sweep of ``param`` over ``values`` (up = increasing order, down = decreasing).

    Each point after the first starts from the previous point's final state (the first from rest),
    so the sweep follows one attractor until it disappears (a jump).  Returns
    ``(points, strobe)``: points = one row per (direction, value) with every label and the pattern
    class; strobe = one row per recorded forcing cycle with the impacting mass's displacement ``disp_m``
    [m] at the cycle start (and its velocity ``vel_m_s``) — the stroboscopic (Poincaré) samples.
    """
    import sim

    if direction not in ("up", "down", "both"):
        raise UserError(f"--direction must be up, down or both, got '{direction}'")
    vals = np.sort(np.asarray(list(values), dtype=float))
    if vals.size < 2:
        raise UserError(f"a bifurcation sweep of '{param}' needs at least 2 values")
    spec = sim.get_model(model)
    if param not in spec.param_names:
        raise UserError(f"'{param}' is not a parameter of model '{model}'{did_you_mean(param, spec.param_names)}; "
                        f"known: {', '.join(spec.param_names)}")
    fixed = {k: v for k, v in dict(fixed or {}).items() if k != param}
    st = sim.api.make_settings(spec, settings)
    st = sim.Settings(**{**st.__dict__, "samples_per_cycle": 2})     # 2 samples per cycle: index 0, 2, 4 ...
    dirs = ["up", "down"] if direction == "both" else [direction]
    points, strobes = [], []
    for d in dirs:
        seq = vals if d == "up" else vals[::-1]
        state = None
        for k, v in enumerate(seq):
            res = sim.simulate(model, preset=preset, settings=st, history=True, initial_state=state,
                               **{**fixed, param: float(v)})
            state = res.final_state
            row = {"direction": d, "step": k, param: float(v), **res.labels}
            points.append(row)
            h = res.history
            if h is not None:
                at_start = h.iloc[::st.samples_per_cycle]
                strobes.append(pd.DataFrame({"direction": d, "step": k, param: float(v),
                                             "cycle": np.arange(len(at_start)),
                                             "disp_m": at_start["disp_m"].to_numpy(),
                                             "vel_m_s": at_start["vel_m_s"].to_numpy()}))
            if progress is not None:
                progress(1)
    pts = add_pattern(pd.DataFrame(points))
    strobe = (pd.concat(strobes, ignore_index=True) if strobes else
              pd.DataFrame(columns=["direction", "step", param, "cycle", "disp_m", "vel_m_s"]))
    return pts, strobe


# ----------------------------------------------------------------------------- band resonances
def band_resonance(df: pd.DataFrame, pattern: int, x: str = "frequency_hz", value: str = "peak_force_n"):
    """(x, value) of the largest ``value`` among the rows of impact-pattern ``pattern`` (None if none).

    Used for the impact resonances of seed 001 Table 2 (frequency of maximum impact force within the
    z = 1/1 or z = 1/2 band) and the first impact resonance of seed 002 Table 3."""
    d = df[df["pattern"] == pattern]
    if d.empty:
        return None
    i = d[value].astype(float).idxmax()
    return float(d.at[i, x]), float(d.at[i, value])


# ----------------------------------------------------------------------------- files
def write_parquet(df: pd.DataFrame, path: str | os.PathLike) -> str:
    """Write ``df`` to ``path`` atomically (vibrobase.files); returns the path."""
    return str(atomic_write_parquet(path, df))
