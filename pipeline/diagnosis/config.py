"""The settings of ``vibro diagnose`` (``DiagnoseConfig``), their bounds and the check it runs on itself when built."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from numbers import Integral, Real

from pipeline.core.errors import UserError
from pipeline.diagnosis.verdict import VerdictRule

INT_BOUNDS: dict[str, tuple[int, int | None]] = {
    "holdout_every": (1, 1000), "min_runs_holdout": (1, 100_000), "n_starts": (1, 100), "grid": (1, 100),
    "profile_points": (1, 100), "profile_nfev": (0, 1000), "candidate_starts": (1, 2), "max_nfev": (1, 10_000),
    "seed": (0, 2**32 - 1), "n_threads": (1, None), "record_window": (0, 10_000), "max_effects": (1, 2),
    "max_proposals": (0, 3)}
"""Integer settings: (low, high); the highs bound the work (fits x starts x iterations).  The command caps
``n_threads`` too."""

FLOAT_BOUNDS: dict[str, float] = {
    "max_harmonic_hz": 1e6, "diff_step": 1.0, "bic_margin": 1e12, "explained_nrms": 1e6, "fs_sim_hz": 1e7,
    "test_margin": 1e12, "systematic_tol": 1.0, "nrms_ratio": 1.0, "model_floor": 1.0, "summary_floor": 1.0,
    "systematic_nrms_cap": 1e6, "pair_nrms": 1e6, "empirical_gain": 1.0}
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
    for name in ("estimate_chain", "fit_unreproducible", "antialias"):
        value = getattr(cfg, name)
        if value is not None and not isinstance(value, bool):
            raise UserError(f"diagnose setting '{name}' must be true or false, got {value!r}")
    for name in ("sim_settings", "summary_sd"):
        if not isinstance(getattr(cfg, name), dict):
            raise UserError(f"diagnose setting '{name}' must be a mapping, got {getattr(cfg, name)!r}")


@dataclass
class DiagnoseConfig:
    """Settings of ``vibro diagnose`` (params.yaml section ``diagnose``; README.md)."""

    max_harmonic_hz: float | None = None  # harmonics of f up to this frequency are features (None: per system,
    #                                       model.default_max_harmonic_hz: indenter 1000, drill 3000, pendulum 100, rimd 200)
    holdout_every: int = 4              # single split: every n-th run (sorted by static force, f) is held out, at
    #                                     distinct frequencies where it can (judge.make_folds)
    min_runs_holdout: int = 8           # fewer runs of a system -> leave-one-run-out cross-validation
    n_starts: int = 2                   # base-model starts: defaults + (n_starts - 1) seeded random points
    grid: int = 4                       # candidate start search: grid points per effect parameter
    profile_points: int = 2             # ... at the best of which the base parameters are refitted (profile)
    profile_nfev: int = 3               # ... for this many iterations (0: no profile, the grid's best point)
    candidate_starts: int | None = None  # candidate starts: effect grid at the calibrated base (1), also at the
    #                                      defaults (2); None: per system (model.default_fit_settings)
    max_nfev: int | None = None         # least_squares iterations per start; None: per system
    diff_step: float = 0.01             # forward-difference step in log10 of a parameter (2.3 %; polished at 0.46 %)
    refine_nfev: int = 15               # more iterations for the leading candidate if not yet at the noise level (0: off)
    bic_margin: float = 10.0            # a candidate must beat the base BIC by this much on the calibration runs
    test_margin: float = 25.0           # ... and the base's held-out chi2 by this much (5 sd of a 1-parameter gain)
    explained_nrms: float = 2.0         # adequate: held-out nrms at or below this ("at the noise level") ...
    systematic_tol: float = 0.005       # ... or held-out systematic error (split-half) at or below this
    nrms_ratio: float = 0.5             # a candidate that cuts the base's held-out nrms to this fraction is material
    systematic_nrms_cap: float = 4.0    # ... adequate by systematic error only up to this held-out nrms (2x explained_nrms:
    #                                     the noise estimate is checked to a factor 2); further above the noise is an error
    max_effects: int = 2                # 2: a leader that improves but leaves held-out nrms above pair_nrms is fitted with
    #                                     each other effect (1: one effect only)
    pair_nrms: float = 2.0              # ... the pair stage's trigger (1: also look for a weaker effect within explained_nrms)
    max_proposals: int = 3              # unexplained: fit at most this many discrepancy proposals (0: no discovery)
    empirical_gain: float = 0.2         # unexplained: an empirical ROP correction is adopted when it cuts the held-out
    #                                     ROP error by this fraction (1: never adopted; pipeline.diagnosis.empirical)
    model_floor: float = 1e-3           # feature sd floor: this x the signal's RMS harmonic amplitude (model error)
    summary_floor: float = 0.01         # summary feature sd floor: this x the value
    effects: list[str] | None = None    # restrict the candidates (default: every §6 effect of the system)
    fs_sim_hz: float = 20000.0          # model sample rate for summary runs (series runs use the data's rate)
    # rtol 1e-7 = the simulator's default (and vibro synth's): at 1e-6 the drill's guide friction (a regularised
    # sign(v) switch) drifted from the truth by nrms 1.3 on 3 runs, 7.3 on 16; the cost is the same
    sim_settings: dict = field(default_factory=lambda: {"rtol": 1e-7, "window": 2, "max_step_frac": 0.05})
    record_window: int = 64             # a steady-state series is compared over its first this many cycles
    summary_sd: dict = field(default_factory=dict)   # e.g. {"peak_decel_g": ["rel", 0.05]}
    seed: int = 0
    n_threads: int | None = None
    estimate_chain: bool | None = None  # estimate an undeclared DAQ chain (delay per channel, clock) as nuisance
    #                                     beside every fit; None: the model's default (ModelSpec.diagnose_chain)
    antialias: bool | None = None       # low-pass the model below each record's Nyquist before sampling it, as a
    #                                     DAQ's anti-alias filter did the signal; None: where runs.csv declares a
    #                                     filter, or the undeclared chain's delays show one (nuisance.FILTER_SAMPLES)
    fit_unreproducible: bool = False    # fit and judge on runs whose model response is chaotic (unreproducible_runs);
    #                                     false: they are left out of every fold (the split is kept)

    def __post_init__(self) -> None:
        check_config(self)

    def rule(self) -> VerdictRule:
        """The verdict's thresholds (pipeline.diagnosis.verdict)."""
        return VerdictRule(self.explained_nrms, self.systematic_tol, self.bic_margin, self.test_margin, self.nrms_ratio,
                           self.systematic_nrms_cap)
