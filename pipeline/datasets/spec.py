"""Sweep specification: model + preset + fixed parameters + varied parameters (ranges, linear or log) + a
design (``sobol``, ``sobol-boundary``, ``lhs``, ``grid``: :mod:`pipeline.datasets.designs`) + number of points + seed +
numerical settings; the design points.

Units: every parameter in SI as in MODELS.md (``frequency_hz`` Hz, ``amplitude_n`` N, ...).
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from pipeline.datasets import designs
from vibrobase.errors import did_you_mean
from vibrobase.unitcube import from_unit

FORMAT_VERSION = 1
"""Version of the dataset format (part of every spec fingerprint)."""
DESIGNS = tuple(designs.DESIGN_MEANINGS)

SCALES = ("linear", "log")

SPEC_KEYS = ("model", "preset", "fixed", "vary", "design", "boundary_fraction", "n_points", "seed", "settings")

EXEC_KEYS = ("chunk_size", "scheduler", "workers")





@dataclass(frozen=True)
class Range:
    """One varied parameter: ``low``..``high`` (SI units of the parameter), ``linear`` or ``log``
    spacing; ``levels`` = grid points along this axis (grid design only)."""

    low: float
    high: float
    scale: str = "linear"
    levels: int | None = None

    def to_physical(self, u: np.ndarray) -> np.ndarray:
        """Map unit-interval coordinates ``u`` ∈ [0, 1] to parameter values."""
        return from_unit(u, self.low, self.high, self.scale == "log")


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep (construct with :func:`make_spec`).  ``chunk_size`` is an execution detail
    (results do not depend on it) and is not part of the fingerprint."""

    model: str
    preset: str | None
    fixed: dict[str, float]
    vary: dict[str, Range]           # sorted by name = design dimension order
    design: str
    n_points: int
    seed: int
    settings: dict[str, Any]         # every sim.Settings field, resolved (model defaults <- given)
    chunk_size: int = 64
    boundary_fraction: float | None = None   # sobol-boundary only: share of the points on the box's boundary

    def canonical(self) -> dict:
        """The fingerprinted part of the spec, as plain JSON-able data (``boundary_fraction`` only in a
        sobol-boundary spec: the other designs' fingerprints are those of the specs before it existed)."""
        c = {
            "format": FORMAT_VERSION,
            "model": self.model,
            "preset": self.preset,
            "fixed": {k: self.fixed[k] for k in sorted(self.fixed)},
            "vary": [[k, {"low": r.low, "high": r.high, "scale": r.scale, "levels": r.levels}]
                     for k, r in self.vary.items()],
            "design": self.design,
            "n_points": self.n_points,
            "seed": self.seed,
            "settings": {k: self.settings[k] for k in sorted(self.settings)},
        }
        if self.design == "sobol-boundary":
            c["boundary_fraction"] = self.boundary_fraction
        return c

    @property
    def fingerprint(self) -> str:
        """sha256 of the canonical spec (JSON, sorted keys, repr-exact floats)."""
        text = json.dumps(self.canonical(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    @property
    def n_chunks(self) -> int:
        return -(-self.n_points // self.chunk_size)

    def chunk_bounds(self, k: int) -> tuple[int, int]:
        """Point ids [start, stop) of chunk ``k``."""
        start = k * self.chunk_size
        return start, min(start + self.chunk_size, self.n_points)

    def describe(self) -> dict:
        """Human-facing spec (metadata.json, MLflow params)."""
        c = self.canonical()
        return {"model": c["model"], "preset": c["preset"], "fixed": c["fixed"],
                "vary": {k: {kk: vv for kk, vv in v.items() if vv is not None} for k, v in c["vary"]},
                "design": c["design"], **({"boundary_fraction": c["boundary_fraction"]} if "boundary_fraction" in c else {}),
                "n_points": c["n_points"], "seed": c["seed"],
                "settings": c["settings"], "chunk_size": self.chunk_size}


def default_vary(model: str, preset: str | None) -> dict[str, dict]:
    """Default varied parameters: the model's search space for ``preset`` (``ModelSpec.search_spaces``; the
    model-defaults space "" when the preset has none)."""
    from sim import get_model

    spaces = get_model(model).search_spaces
    space = spaces.get(preset or "") or spaces.get("")
    if not space:
        raise UserError(f"sweep: model '{model}' (preset {preset}) has no default search space; give 'vary'")
    return {name: {"low": float(lo), "high": float(hi), "scale": "linear"} for name, (lo, hi) in space.items()}


def default_spec_dict() -> dict:
    """The built-in default sweep (same as the ``sweep`` section shipped in params.yaml)."""
    from sim.registry import DEFAULT_MODEL, DEFAULT_PRESET

    return {"model": DEFAULT_MODEL, "preset": DEFAULT_PRESET, "fixed": {}, "vary": default_vary(DEFAULT_MODEL, DEFAULT_PRESET),
            "design": "sobol-boundary", "boundary_fraction": designs.BOUNDARY_FRACTION, "n_points": 1024, "seed": 0,
            "settings": {}, "chunk_size": 64}


def _as_int(value, name: str, minimum: int | None = None) -> int:
    if isinstance(value, bool) or value is None:
        raise UserError(f"sweep.{name} must be an integer, got {value!r}")
    try:
        f = float(value)
    except (TypeError, ValueError):
        raise UserError(f"sweep.{name} must be an integer, got {value!r}") from None
    if not math.isfinite(f) or f != int(f):
        raise UserError(f"sweep.{name} must be an integer, got {value!r}")
    v = int(f)
    if minimum is not None and v < minimum:
        raise UserError(f"sweep.{name} must be >= {minimum}, got {v}")
    return v


def _as_float(value, name: str) -> float:
    if isinstance(value, bool):
        raise UserError(f"{name} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UserError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise UserError(f"{name} must be finite, got {value!r}")
    return v


def _parse_range(name: str, raw) -> Range:
    where = f"sweep.vary.{name}"
    if isinstance(raw, (list, tuple)) and len(raw) in (2, 3):
        raw = {"low": raw[0], "high": raw[1], **({"scale": raw[2]} if len(raw) == 3 else {})}
    if not isinstance(raw, dict):
        raise UserError(f"{where} must be a mapping {{low, high, scale}}, got {raw!r}")
    unknown = set(raw) - {"low", "high", "scale", "levels"}
    if unknown:
        first = sorted(map(str, unknown))[0]
        keys = ("low", "high", "scale", "levels")
        raise UserError(f"{where}: unknown key(s) {sorted(unknown)}{did_you_mean(first, keys)}; "
                        f"known: {', '.join(keys)}")
    for key in ("low", "high"):
        if key not in raw:
            raise UserError(f"{where} has no '{key}'")
    low, high = _as_float(raw["low"], f"{where}.low"), _as_float(raw["high"], f"{where}.high")
    scale = raw.get("scale", "linear") or "linear"
    if scale not in SCALES:
        raise UserError(f"{where}.scale must be one of {', '.join(SCALES)}, got {scale!r}")
    if low == high:
        raise UserError(f"{where}: empty range (low = high = {low:g}); put a constant parameter under 'fixed'")
    if low > high:
        raise UserError(f"{where}: inverted range (low = {low:g} > high = {high:g})")
    if scale == "log" and low <= 0:
        raise UserError(f"{where}: a log scale needs low > 0, got low = {low:g}")
    levels = raw.get("levels")
    if levels is not None:
        levels = _as_int(levels, f"vary.{name}.levels", minimum=2)
    return Range(low, high, scale, levels)


def _coerce_settings(raw: dict, model_spec) -> dict[str, Any]:
    from sim.api import Settings, make_settings

    if not isinstance(raw, dict):
        raise UserError(f"sweep.settings must be a mapping of sim.Settings fields, got {raw!r}")
    base = Settings()
    out = {}
    for k, v in raw.items():
        if k in Settings.__dataclass_fields__ and isinstance(getattr(base, k), int):
            v = _as_int(v, f"settings.{k}")
        out[k] = v
    return asdict(make_settings(model_spec, out))


def make_spec(raw: dict | None = None, **overrides) -> SweepSpec:
    """Validate a sweep description (params.yaml ``sweep`` section, CLI overrides on top).

    Raises UserError / sim.ParameterError naming the offending key, parameter or value; touches
    no file.  ``overrides`` with value None are ignored.
    """
    from sim import get_model
    from sim.models.base import ParameterError

    d = dict(default_spec_dict() if raw is None else raw)
    if overrides.get("design") not in (None, "sobol-boundary") and overrides.get("boundary_fraction") is None:
        d.pop("boundary_fraction", None)        # the raw spec's share belongs to its own sobol-boundary design
    d.update({k: v for k, v in overrides.items() if v is not None})
    unknown = set(d) - set(SPEC_KEYS) - set(EXEC_KEYS)
    if unknown:
        first = sorted(map(str, unknown))[0]
        raise UserError(f"sweep: unknown key(s) {sorted(unknown)}{did_you_mean(first, SPEC_KEYS + EXEC_KEYS)}; "
                        f"known: {', '.join(SPEC_KEYS + EXEC_KEYS)}")
    for key in ("model", "vary", "n_points"):
        if key not in d:
            raise UserError(f"sweep: missing key '{key}'")
    model = d["model"]
    if not isinstance(model, str):
        raise UserError(f"sweep.model must be a model name, got {model!r}")
    mspec = get_model(model)
    preset = d.get("preset")
    if preset in ("", "none", "None"):
        preset = None
    if preset is not None:
        mspec.defaults(str(preset))          # ParameterError naming the known presets
        preset = str(preset)
    fixed_raw = d.get("fixed") or {}
    if not isinstance(fixed_raw, dict):
        raise UserError(f"sweep.fixed must be a mapping name -> value, got {fixed_raw!r}")
    vary_raw = d.get("vary") or {}
    if not isinstance(vary_raw, dict):
        raise UserError(f"sweep.vary must be a mapping name -> {{low, high, scale}}, got {vary_raw!r}")
    if not vary_raw:
        raise UserError("sweep.vary is empty: give at least one parameter to vary")
    for where, names in (("fixed", fixed_raw), ("vary", vary_raw)):
        mspec.check_names(names, f"sweep.{where}")
    both = set(fixed_raw) & set(vary_raw)
    if both:
        raise UserError(f"sweep: parameter(s) {sorted(both)} are both fixed and varied")
    fixed = {k: _as_float(v, f"sweep.fixed.{k}") for k, v in fixed_raw.items()}
    # design dimensions in sorted name order: the listing order in a YAML file (which tools may
    # re-sort) does not change the dataset
    vary = {str(k): _parse_range(str(k), vary_raw[k]) for k in sorted(vary_raw, key=str)}
    n_points = _as_int(d["n_points"], "n_points")
    if n_points < 1:
        raise UserError(f"sweep.n_points must be >= 1, got {n_points}")
    design, fraction = _design_options(d, vary, n_points)
    seed = _as_int(d.get("seed", 0), "seed", minimum=0)
    chunk_size = _as_int(d.get("chunk_size", 64), "chunk_size", minimum=1)
    settings = _coerce_settings(d.get("settings") or {}, mspec)
    # every range end must be a valid value of its parameter (e.g. frequency_hz > 0)
    by_name = {p.name: p for p in mspec.params}
    for name, r in vary.items():
        for end in ("low", "high"):
            try:
                by_name[name].validate(getattr(r, end))
            except ParameterError as e:
                raise UserError(f"sweep.vary.{name}.{end}: {e}") from None
    try:
        mspec.resolve(preset, **fixed)
    except ParameterError as e:
        raise UserError(f"sweep.fixed: {e}") from None
    return SweepSpec(model=model, preset=preset, fixed=fixed, vary=vary, design=design, n_points=n_points,
                     seed=seed, settings=settings, chunk_size=chunk_size, boundary_fraction=fraction)


def _design_options(d: dict, vary: dict[str, Range], n_points: int) -> tuple[str, float | None]:
    """The checked design name and its ``boundary_fraction`` (sobol-boundary only: default
    ``designs.BOUNDARY_FRACTION``; None for the other designs); UserError naming the option."""
    design = d.get("design", "sobol")
    if design is None:
        design = "sobol"
    if not isinstance(design, str) or design not in DESIGNS:
        hint = did_you_mean(design, DESIGNS) if isinstance(design, str) else ""
        raise UserError(f"sweep.design: unknown design {design!r}{hint}; known: {', '.join(DESIGNS)}")
    fraction = d.get("boundary_fraction")
    if design != "sobol-boundary":
        if fraction is not None:
            raise UserError(f"sweep.boundary_fraction is only used by the sobol-boundary design (design is {design})")
    else:
        fraction = designs.BOUNDARY_FRACTION if fraction is None else _as_float(fraction, "sweep.boundary_fraction")
        if not 0.0 <= fraction <= 1.0:
            raise UserError(f"sweep.boundary_fraction must be in [0, 1] (a share of n_points), got {fraction:g}")
    if design != "grid":
        with_levels = [k for k, r in vary.items() if r.levels is not None]
        if with_levels:
            raise UserError(f"sweep.vary.{with_levels[0]}.levels is only used by the grid design (design is {design})")
    else:
        _grid_levels(vary, n_points)         # validates
    return design, fraction


def _grid_levels(vary: dict[str, Range], n_points: int) -> list[int]:
    """Levels per axis of a full grid: each axis's ``levels``, the rest share the remaining factor equally."""
    given = {k: r.levels for k, r in vary.items() if r.levels is not None}
    rest = [k for k in vary if k not in given]
    prod_given = math.prod(given.values()) if given else 1
    if not rest:
        if prod_given != n_points:
            raise UserError(f"sweep: grid levels {given} make {prod_given} points but n_points is {n_points}")
        return [given[k] for k in vary]
    if n_points % prod_given:
        raise UserError(f"sweep: n_points = {n_points} is not a multiple of the given grid levels' product {prod_given}")
    m = n_points // prod_given
    per = round(m ** (1.0 / len(rest)))
    if per < 2 or per ** len(rest) != m:
        raise UserError(f"sweep: a full grid over {len(rest)} axis/axes without 'levels' needs n_points "
                        f"(/{prod_given}) to be an exact {len(rest)}-th power >= {2 ** len(rest)}, got {m}; "
                        f"e.g. {max(2, per) ** len(rest) * prod_given}, or give 'levels' per parameter")
    return [given.get(k, per) for k in vary]


def unit_design(spec: SweepSpec) -> np.ndarray:
    """Design in the unit cube, shape (n_points, d), deterministic in ``spec.seed``.

    sobol: scrambled Sobol' (``qmc.Sobol(d, scramble=True, seed=seed)``); for n not a power of 2 the
    first n points of the 2^ceil(log2 n) sequence are taken (a prefix of the sequence: low discrepancy
    is kept, the exact balance of a power of 2 is not).  sobol-boundary: ``boundary_fraction`` of the points on
    the cube's corners, edges and faces, the rest sobol (:func:`designs.sobol_boundary`).
    lhs: ``qmc.LatinHypercube(d, seed=seed)``.  grid: full factorial, end points included.  Dimensions are the
    varied parameters sorted by name (the last one varies fastest in a grid).
    """
    return UNIT_DESIGNS[spec.design](spec, len(spec.vary), spec.n_points)


def _grid_unit(spec: SweepSpec, d: int, n: int) -> np.ndarray:
    """Full factorial over each axis's levels in [0, 1], end points included (the last axis varies fastest)."""
    axes = [np.linspace(0.0, 1.0, L) for L in _grid_levels(spec.vary, n)]
    return np.array(list(itertools.product(*axes)), dtype=np.float64).reshape(n, d)


UNIT_DESIGNS = {
    "sobol": lambda spec, d, n: designs.sobol(d, n, spec.seed),
    "sobol-boundary": lambda spec, d, n: designs.sobol_boundary(d, n, spec.seed, spec.boundary_fraction),
    "lhs": lambda spec, d, n: designs.lhs(d, n, spec.seed),
    "grid": _grid_unit,
}
"""Design name -> (spec, d, n) -> unit-cube points: the one place a design's name becomes its points."""
assert set(UNIT_DESIGNS) == set(DESIGNS), "every design of designs.DESIGN_MEANINGS needs its UNIT_DESIGNS entry"


def design_points(spec: SweepSpec) -> pd.DataFrame:
    """``point_id`` and the varied parameters in physical units (fixed parameters not included)."""
    u = unit_design(spec)
    cols: dict[str, np.ndarray] = {"point_id": np.arange(spec.n_points, dtype=np.int64)}
    for j, (name, r) in enumerate(spec.vary.items()):
        x = r.to_physical(u[:, j])
        cols[name] = np.clip(x, r.low, r.high)   # exp/log round-off must not leave the range
    return pd.DataFrame(cols)


def validate_points(spec: SweepSpec, points: pd.DataFrame) -> None:
    """Resolve every point (catches cross-parameter constraints) before anything is written; UserError naming the
    first point refused.  Vectorised (1e7 points in seconds, a few bytes per point beside the design): see
    :func:`first_refused`."""
    names = list(spec.vary)
    bad = first_refused(spec, {k: points[k].to_numpy(dtype=np.float64) for k in names})
    if bad is not None:
        row, msg = bad
        vals = ", ".join(f"{k}={points[k].iat[row]:g}" for k in names)
        raise UserError(f"sweep: point {points['point_id'].iat[row]} ({vals}): {msg}")


def first_refused(spec: SweepSpec, columns: dict[str, np.ndarray]) -> tuple[int, str] | None:
    """A row of ``columns`` (the varied parameters' values) that the model's ``resolve`` refuses, with its message
    (the first of the rows checked), or None when every row resolves.  Each column's own checks (finite, > 0, >= 0: the parameter's declared flags) run on the whole
    column; ``resolve`` itself then runs on the first row so flagged, on each column's smallest and largest value and
    on one row per pattern of signs (negative, zero, positive) of the varied values -- resolve's cross-parameter
    rules test whether a value is zero (a discrepancy term the model lacks, a hidden mode without a frequency)."""
    from sim import get_model
    from sim.models.base import ParameterError

    mspec = get_model(spec.model)
    names = list(columns)
    n = len(columns[names[0]]) if names else 0
    if n == 0:
        return None
    by_name = {p.name: p for p in mspec.params}

    def refusal(row: int) -> str | None:
        try:
            mspec.resolve(spec.preset, **spec.fixed, **{k: float(columns[k][row]) for k in names})
        except ParameterError as e:
            return str(e)
        return None

    flagged = np.zeros(n, dtype=bool)
    pattern = np.zeros(n, dtype=np.int64)
    rows = {0}
    for k in names:
        x, p = columns[k], by_name.get(k)
        with np.errstate(invalid="ignore"):
            flagged |= ~np.isfinite(x)
            if p is not None and p.positive:
                flagged |= ~(x > 0.0)
            if p is not None and p.nonnegative:
                flagged |= x < 0.0
            pattern = pattern * 3 + (np.sign(np.nan_to_num(x)).astype(np.int64) + 1)
        finite = np.flatnonzero(np.isfinite(x))
        if finite.size:
            rows.update((int(finite[np.argmin(x[finite])]), int(finite[np.argmax(x[finite])])))
    if len(names) > 39:        # 3^40 > 2^63: the patterns no longer fit one integer
        signs = np.column_stack([np.sign(np.nan_to_num(columns[k])) for k in names])
        rows.update(int(i) for i in np.unique(signs, axis=0, return_index=True)[1])
    else:
        rows.update(int(i) for i in np.unique(pattern, return_index=True)[1])
    if flagged.any():
        rows.add(int(np.argmax(flagged)))
    refused = [(r, m) for r in sorted(rows) if (m := refusal(r)) is not None]
    return refused[0] if refused else None
