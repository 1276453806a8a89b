"""Bounds of the ``diagnose`` settings and the check ``DiagnoseConfig`` runs on itself when built."""
from __future__ import annotations

import math
from numbers import Integral, Real

from pipeline.core.errors import UserError

INT_BOUNDS: dict[str, tuple[int, int | None]] = {
    "holdout_every": (1, 1000), "min_runs_holdout": (1, 100_000), "n_starts": (1, 100), "grid": (1, 100),
    "profile_points": (1, 100), "profile_nfev": (0, 1000), "candidate_starts": (1, 2), "max_nfev": (1, 10_000),
    "seed": (0, 2**32 - 1), "n_threads": (1, None), "record_window": (0, 10_000), "max_effects": (1, 2)}
"""Integer settings: (low, high); the highs bound the work (fits x starts x iterations).  The command caps
``n_threads`` too."""

FLOAT_BOUNDS: dict[str, float] = {
    "max_harmonic_hz": 1e6, "diff_step": 1.0, "bic_margin": 1e12, "explained_nrms": 1e6, "fs_sim_hz": 1e7,
    "test_margin": 1e12, "systematic_tol": 1.0, "nrms_ratio": 1.0, "model_floor": 1.0, "summary_floor": 1.0}
"""Real settings: the high; the low is 0, excluded except for the floors (:data:`ZERO_ALLOWED`)."""

ZERO_ALLOWED = ("model_floor", "summary_floor")


def _fmt(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else f"{x:g}"


def check_setting(name: str, value) -> None:
    """UserError when the numeric setting ``name`` is not a number of its kind inside its bounds (None passes)."""
    what = f"diagnose setting '{name}'"
    if value is None or (name not in INT_BOUNDS and name not in FLOAT_BOUNDS):
        return
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(float(value)):
        raise UserError(f"{what}: expected a finite number, got {value!r}")
    if name in INT_BOUNDS:
        lo, hi = INT_BOUNDS[name]
        if not isinstance(value, Integral):
            raise UserError(f"{what}: must be an integer, got {value!r}")
        lo_open = False
    else:
        lo, hi, lo_open = 0.0, FLOAT_BOUNDS[name], name not in ZERO_ALLOWED
    if value < lo or (lo_open and value == lo):
        raise UserError(f"{what}: must be {'>' if lo_open else '>='} {_fmt(lo)}, got {value!r}")
    if hi is not None and value > hi:
        raise UserError(f"{what}: must be <= {_fmt(hi)} (an upper bound on the work), got {value!r}")


def check_config(cfg) -> None:
    """UserError naming the first bad setting of a ``DiagnoseConfig``: numbers inside their bounds, ``effects`` a
    list of names, ``sim_settings`` and ``summary_sd`` mappings."""
    for name in (*INT_BOUNDS, *FLOAT_BOUNDS):
        check_setting(name, getattr(cfg, name))
    if cfg.effects is not None and (not isinstance(cfg.effects, list) or not all(isinstance(e, str) for e in cfg.effects)):
        raise UserError(f"diagnose setting 'effects' must be a list of effect names, got {cfg.effects!r}")
    for name in ("sim_settings", "summary_sd"):
        if not isinstance(getattr(cfg, name), dict):
            raise UserError(f"diagnose setting '{name}' must be a mapping, got {getattr(cfg, name)!r}")
