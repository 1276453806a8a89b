"""Labelled datasets at scale: sweep specification, design, chunked resumable execution, loading.

A sweep = model + preset + fixed parameters + varied parameters (ranges, linear or log) + a
design (``sobol``, ``lhs``, ``grid``) + number of points + seed + numerical settings.  The output
is a directory holding ``part-XXXXX.parquet`` chunk files (one row per point, ordered by
``point_id``) and ``metadata.json``.  Every chunk is written atomically (temp file in the same
folder, then ``os.replace``) and tagged with the spec's fingerprint, so an interrupted sweep rerun
with the same spec computes only the missing chunks and ends with exactly the rows of an
uninterrupted run; a different spec is refused.

Units: every parameter in SI as in MODELS.md (``frequency_hz`` Hz, ``amplitude_n`` N, ...).
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import socket
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np
import pandas as pd

from pipeline.errors import UserError

FORMAT_VERSION = 1
DESIGNS = ("sobol", "lhs", "grid")
SCALES = ("linear", "log")
SPEC_KEYS = ("model", "preset", "fixed", "vary", "design", "n_points", "seed", "settings")
EXEC_KEYS = ("chunk_size", "scheduler", "workers")
STATUSES = ("ok", "no_contact", "not_settled", "runaway", "failed")
PART_GLOB = "part-*.parquet"
META_NAME = "metadata.json"
LOCK_NAME = ".sweep.lock"

# MODELS.md §2 search space of the drill's lab-scale starting point (f, F0, Fs = 0.05..0.95 Pr, Pr = 1.5 kN);
# replaced by sim.models.drill.LAB_SPACE when that exists.
_MODELS_MD_SPACE = {
    "frequency_hz": {"low": 10.0, "high": 400.0, "scale": "linear"},
    "amplitude_n": {"low": 0.0, "high": 3000.0, "scale": "linear"},
    "static_force_n": {"low": 75.0, "high": 1425.0, "scale": "linear"},
}


# --------------------------------------------------------------------------------------- spec
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
        if self.scale == "log":
            lo, hi = math.log(self.low), math.log(self.high)
            return np.exp(lo + u * (hi - lo))
        return self.low + u * (self.high - self.low)


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

    def canonical(self) -> dict:
        """The fingerprinted part of the spec, as plain JSON-able data."""
        return {
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
                "design": c["design"], "n_points": c["n_points"], "seed": c["seed"],
                "settings": c["settings"], "chunk_size": self.chunk_size}


def default_vary(model: str = "drill", preset: str | None = "lab") -> dict[str, dict]:
    """Default varied parameters: ``sim.models.drill.LAB_SPACE`` when it exists, else the MODELS.md §2 ranges."""
    if model == "drill":
        try:
            from sim.models import drill

            space = getattr(drill, "LAB_SPACE", None)
        except ImportError:
            space = None
        if space:
            out = {}
            for name, r in dict(space).items():
                if isinstance(r, dict):
                    out[name] = {"low": float(r["low"]), "high": float(r["high"]), "scale": r.get("scale", "linear")}
                else:
                    lo, hi = r[0], r[1]
                    out[name] = {"low": float(lo), "high": float(hi), "scale": (r[2] if len(r) > 2 else "linear")}
            return out
    return {k: dict(v) for k, v in _MODELS_MD_SPACE.items()}


def default_spec_dict() -> dict:
    """The built-in default sweep (same as the ``sweep`` section shipped in params.yaml)."""
    return {"model": "drill", "preset": "lab", "fixed": {}, "vary": default_vary("drill", "lab"),
            "design": "sobol", "n_points": 1024, "seed": 0, "settings": {}, "chunk_size": 64}


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
        raise UserError(f"{where}: unknown key(s) {sorted(unknown)}; known: low, high, scale, levels")
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
    d.update({k: v for k, v in overrides.items() if v is not None})
    unknown = set(d) - set(SPEC_KEYS) - set(EXEC_KEYS)
    if unknown:
        raise UserError(f"sweep: unknown key(s) {sorted(unknown)}; known: {', '.join(SPEC_KEYS + EXEC_KEYS)}")
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
    known = set(mspec.param_names)
    for where, names in (("fixed", fixed_raw), ("vary", vary_raw)):
        for name in names:
            if name not in known:
                raise UserError(f"sweep.{where}: unknown parameter '{name}' for model '{model}'; "
                                f"known: {', '.join(mspec.param_names)}")
    both = set(fixed_raw) & set(vary_raw)
    if both:
        raise UserError(f"sweep: parameter(s) {sorted(both)} are both fixed and varied")
    fixed = {k: _as_float(v, f"sweep.fixed.{k}") for k, v in fixed_raw.items()}
    # design dimensions in sorted name order: the listing order in a YAML file (which tools may
    # re-sort) does not change the dataset
    vary = {str(k): _parse_range(str(k), vary_raw[k]) for k in sorted(vary_raw, key=str)}
    design = d.get("design", "sobol")
    if design not in DESIGNS:
        raise UserError(f"sweep.design must be one of {', '.join(DESIGNS)}, got {design!r}")
    n_points = _as_int(d["n_points"], "n_points")
    if n_points < 1:
        raise UserError(f"sweep.n_points must be >= 1, got {n_points}")
    seed = _as_int(d.get("seed", 0), "seed", minimum=0)
    chunk_size = _as_int(d.get("chunk_size", 64), "chunk_size", minimum=1)
    if design != "grid":
        with_levels = [k for k, r in vary.items() if r.levels is not None]
        if with_levels:
            raise UserError(f"sweep.vary.{with_levels[0]}.levels is only used by the grid design (design is {design})")
    else:
        _grid_levels(vary, n_points)         # validates
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
                     seed=seed, settings=settings, chunk_size=chunk_size)


# ------------------------------------------------------------------------------------- design
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
    is kept, the exact balance of a power of 2 is not).  lhs: ``qmc.LatinHypercube(d, seed=seed)``.
    grid: full factorial, end points included.  Dimensions are the varied parameters sorted by
    name (the last one varies fastest in a grid).
    """
    from scipy.stats import qmc

    d = len(spec.vary)
    n = spec.n_points
    if spec.design == "sobol":
        m = max(0, math.ceil(math.log2(n)))
        return qmc.Sobol(d, scramble=True, seed=spec.seed).random_base2(m)[:n]
    if spec.design == "lhs":
        return qmc.LatinHypercube(d, seed=spec.seed).random(n)
    levels = _grid_levels(spec.vary, n)
    axes = [np.linspace(0.0, 1.0, L) for L in levels]
    return np.array(list(itertools.product(*axes)), dtype=np.float64).reshape(n, d)


def design_points(spec: SweepSpec) -> pd.DataFrame:
    """``point_id`` and the varied parameters in physical units (fixed parameters not included)."""
    u = unit_design(spec)
    cols: dict[str, np.ndarray] = {"point_id": np.arange(spec.n_points, dtype=np.int64)}
    for j, (name, r) in enumerate(spec.vary.items()):
        x = r.to_physical(u[:, j])
        cols[name] = np.clip(x, r.low, r.high)   # exp/log round-off must not leave the range
    return pd.DataFrame(cols)


def validate_points(spec: SweepSpec, points: pd.DataFrame) -> None:
    """Resolve every point (catches cross-parameter constraints) before anything is written."""
    from sim import get_model
    from sim.models.base import ParameterError

    mspec = get_model(spec.model)
    names = list(spec.vary)
    for rec in points[["point_id"] + names].itertuples(index=False):
        try:
            mspec.resolve(spec.preset, **spec.fixed, **{k: float(v) for k, v in zip(names, rec[1:])})
        except ParameterError as e:
            raise UserError(f"sweep: point {rec[0]} ({', '.join(f'{k}={v:g}' for k, v in zip(names, rec[1:]))}): {e}") from None


# ------------------------------------------------------------------------------------ schema
def columns(model: str) -> list[str]:
    from sim import get_model
    from sim.api import DIAGNOSTICS, LABELS

    return ["point_id", *get_model(model).param_names, *LABELS, "status", "reason", *DIAGNOSTICS]


def arrow_schema(model: str):
    """Fixed column types: ints for ids/diagnostics, float64 for parameters and numeric labels
    (null where a label does not exist), strings for status/reason."""
    import pyarrow as pa

    from sim.api import DIAGNOSTICS

    fields = []
    for c in columns(model):
        if c == "point_id" or c in DIAGNOSTICS:
            fields.append(pa.field(c, pa.int64(), nullable=False))
        elif c in ("status", "reason"):
            fields.append(pa.field(c, pa.string(), nullable=False))
        else:
            fields.append(pa.field(c, pa.float64()))
    return pa.schema(fields)


def compute_chunk(model: str, preset: str | None, settings: dict, fixed: dict[str, float],
                  points: pd.DataFrame, n_threads: int | None = None) -> pd.DataFrame:
    """Simulate the rows of ``points`` (``point_id`` + varied parameters); runs locally or on a Dask
    worker.  Returns the dataset rows (columns of :func:`columns`), ordered by point_id."""
    import sim

    table = points.drop(columns=["point_id"]).copy()
    for k, v in fixed.items():
        table[k] = v
    res = sim.simulate_batch(model, table, preset=preset, settings=settings, n_threads=n_threads)
    res.insert(0, "point_id", points["point_id"].to_numpy(dtype=np.int64))
    return res[columns(model)]


def _to_table(df: pd.DataFrame, model: str, meta: dict[str, str]):
    import pyarrow as pa

    schema = arrow_schema(model)
    out = {}
    for f in schema:
        col = df[f.name]
        if pa.types.is_floating(f.type):
            arr = pd.to_numeric(col, errors="raise").to_numpy(dtype=np.float64, na_value=np.nan)
            out[f.name] = pa.array(arr, type=f.type, from_pandas=True)     # NaN (missing) -> null
        elif pa.types.is_integer(f.type):
            out[f.name] = pa.array(col.to_numpy(dtype=np.int64), type=f.type)
        else:
            out[f.name] = pa.array(["" if v is None else str(v) for v in col], type=f.type)
    table = pa.table(out, schema=schema)
    return table.replace_schema_metadata({k.encode(): str(v).encode() for k, v in meta.items()})


# --------------------------------------------------------------------------------- file utils
def atomic_write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def atomic_write_json(path: Path, obj) -> None:
    from pipeline.cliutil import dump_json

    atomic_write_bytes(Path(path), (dump_json(obj) + "\n").encode())


def _write_chunk(out: Path, k: int, table) -> None:
    import pyarrow.parquet as pq

    from pipeline.integrity import write_with_checksum

    path = out / f"part-{k:05d}.parquet"
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    pq.write_table(table, tmp, compression="zstd")
    write_with_checksum(tmp, path)      # sidecar part-XXXXX.parquet.sha256, checked on resume


def _git_commit() -> dict:
    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, timeout=10)
        if head.returncode != 0:
            return {"git_commit": None, "git_dirty": None}
        return {"git_commit": head.stdout.strip(), "git_dirty": bool(dirty.stdout.strip())}
    except (OSError, subprocess.SubprocessError):
        return {"git_commit": None, "git_dirty": None}


def sim_source_hash() -> str:
    """sha256 over the simulator's sources (sim/**/*.py): resumed chunks must come from the same code."""
    import sim

    root = Path(sim.__file__).resolve().parent
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def package_versions(extra: Iterable[str] = ()) -> dict[str, str | None]:
    from importlib.metadata import PackageNotFoundError, version

    out: dict[str, str | None] = {"python": sys.version.split()[0]}
    for name in ("vibro", "numpy", "scipy", "numba", "pandas", "pyarrow", *extra):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = None
    return out


# ------------------------------------------------------------------------------------ state
def _read_meta(out: Path) -> dict | None:
    p = out / META_NAME
    if not p.exists():
        return None
    try:
        return json.loads(p.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise UserError(f"{p}: unreadable sweep metadata ({e}); use a new --out or --overwrite") from None


def _spec_diff(old: dict, new: dict, prefix: str = "") -> list[str]:
    keys = sorted(set(old) | set(new))
    diffs = []
    for k in keys:
        a, b = old.get(k), new.get(k)
        if isinstance(a, dict) and isinstance(b, dict):
            diffs += _spec_diff(a, b, f"{prefix}{k}.")
        elif a != b:
            diffs.append(f"{prefix}{k}: {a!r} -> {b!r}")
    return diffs


def _acquire_lock(out: Path):
    """The sweep's exclusive lock on ``out`` (pipeline.integrity.DirLock: flock, race-free, no stale locks)."""
    from pipeline.integrity import DirLock

    return DirLock(out / LOCK_NAME, what="sweep").acquire()


def _existing_chunks(out: Path, spec: SweepSpec) -> set[int]:
    """Chunks already complete on disk (checked against the fingerprint and expected row count)."""
    import pyarrow.parquet as pq

    from pipeline.integrity import verify_checksum

    done = set()
    fp = spec.fingerprint
    for p in sorted(out.glob(PART_GLOB)):
        try:
            k = int(p.stem.split("-")[1])
        except (IndexError, ValueError):
            raise UserError(f"{p}: unexpected file name in a sweep dataset") from None
        if not 0 <= k < spec.n_chunks:
            raise UserError(f"{p}: chunk {k} is outside this sweep's {spec.n_chunks} chunks")
        bad = verify_checksum(p)
        if bad is not None:
            print(f"warning: {p}: {bad}; it will be recomputed", file=sys.stderr)
            continue
        try:
            md = pq.read_metadata(p)
        except Exception as e:  # noqa: BLE001 - a damaged file is recomputed, and said so
            print(f"warning: {p} is unreadable ({e}); it will be recomputed", file=sys.stderr)
            continue
        kv = {a.decode(): b.decode() for a, b in (md.metadata or {}).items()}
        start, stop = spec.chunk_bounds(k)
        if kv.get("vibro.fingerprint") != fp:
            raise UserError(f"{p} belongs to a different sweep (fingerprint {kv.get('vibro.fingerprint', '?')[:12]}, "
                            f"expected {fp[:12]}); use a new --out or --overwrite")
        if md.num_rows != stop - start or kv.get("vibro.start") != str(start):
            raise UserError(f"{p}: holds {md.num_rows} rows from point {kv.get('vibro.start')}, expected "
                            f"{stop - start} from {start} (chunk_size changed?)")
        done.add(k)
    return done


def _clean_temp(out: Path) -> None:
    for p in list(out.glob(".part-*.parquet.tmp-*")) + list(out.glob(".part-*.parquet.sha256.tmp-*")):
        p.unlink(missing_ok=True)


def _prepare_out(out: Path, spec: SweepSpec, overwrite: bool) -> dict | None:
    """Check the output directory against ``spec``; returns the existing metadata (resume) or None."""
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a directory")
    if out.exists() and overwrite:
        foreign = _foreign_files(out)
        if foreign:
            raise UserError(f"--overwrite: {out} holds {len(foreign)} file(s) this sweep did not write "
                            f"(first: {foreign[0].name}); refusing to delete them: use a new --out")
    if not out.exists() or overwrite:
        return None
    meta = _read_meta(out)
    parts = list(out.glob(PART_GLOB))
    if meta is None:
        if parts:
            raise UserError(f"{out} holds chunk files but no {META_NAME}: not a sweep this tool can resume; "
                            f"use a new --out or --overwrite")
        return None
    if meta.get("fingerprint") != spec.fingerprint or meta.get("chunk_size") != spec.chunk_size:
        old = meta.get("spec_canonical") or {}
        diffs = _spec_diff(old, spec.canonical()) if old else []
        if meta.get("chunk_size") != spec.chunk_size and meta.get("fingerprint") == spec.fingerprint:
            diffs.append(f"chunk_size: {meta.get('chunk_size')} -> {spec.chunk_size}")
        raise UserError(f"{out} holds a sweep with a different spec ({'; '.join(diffs) or 'fingerprint differs'}); "
                        f"refusing to mix: use a new --out, the same spec to resume, or --overwrite")
    return meta


def _foreign_files(out: Path) -> list[Path]:
    """Files in ``out`` that a sweep did not write (--overwrite never deletes those)."""
    import pyarrow.parquet as pq

    from pipeline.integrity import CHECKSUM_SUFFIX

    own_names = {META_NAME, LOCK_NAME}
    foreign = []
    for p in sorted(out.iterdir()):
        if p.name in own_names or (p.name.startswith(".part-") and ".tmp-" in p.name):
            continue
        if p.is_file() and p.name.startswith("part-") and p.name.endswith(".parquet" + CHECKSUM_SUFFIX):
            continue
        if p.is_file() and p.match(PART_GLOB):
            try:
                if b"vibro.fingerprint" in (pq.read_metadata(p).metadata or {}):
                    continue
            except Exception:  # noqa: BLE001 - unreadable: a damaged chunk of ours is still ours if sidecar exists
                if (out / (p.name + CHECKSUM_SUFFIX)).exists():
                    continue
        foreign.append(p)
    return foreign


def _wipe(out: Path) -> None:
    from pipeline.integrity import CHECKSUM_SUFFIX

    for p in list(out.glob(PART_GLOB)) + list(out.glob(PART_GLOB + CHECKSUM_SUFFIX)) + [out / META_NAME]:
        p.unlink(missing_ok=True)


# -------------------------------------------------------------------------------------- run
@dataclass
class SweepSummary:
    """What a sweep run did: counts per status over the whole dataset, work done in this session."""

    out: str
    n_points: int
    n_chunks: int
    computed: int                 # points simulated in this session
    reused: int                   # points found complete on disk (resume)
    status_counts: dict[str, int]
    wall_time_s: float
    sims_per_s: float | None
    fingerprint: str
    backend: str
    metadata: dict = field(default_factory=dict)

    def lines(self) -> list[str]:
        counts = ", ".join(f"{k} {v}" for k, v in self.status_counts.items())
        rate = f"{self.sims_per_s:.1f} sims/s" if self.sims_per_s else "no new simulations"
        return [f"sweep: {self.n_points} points in {self.n_chunks} chunks -> {self.out}",
                f"  status: {counts}",
                f"  this run: {self.computed} simulated, {self.reused} reused from disk, "
                f"{self.wall_time_s:.1f} s, {rate} ({self.backend})"]

    def metrics(self) -> dict:
        return {"n_points": self.n_points, "n_chunks": self.n_chunks, "computed": self.computed,
                "reused": self.reused, "status_counts": self.status_counts, "wall_time_s": self.wall_time_s,
                "sims_per_s": self.sims_per_s, "fingerprint": self.fingerprint, "backend": self.backend}


def status_counts(out: Path) -> dict[str, int]:
    import pyarrow.parquet as pq

    counts = dict.fromkeys(STATUSES, 0)
    for p in sorted(Path(out).glob(PART_GLOB)):
        for s in pq.read_table(p, columns=["status"]).column("status").to_pylist():
            counts[s] = counts.get(s, 0) + 1
    return counts


def run_sweep(spec: SweepSpec, out: str | os.PathLike, *, scheduler: str | None = None,
              n_threads: int | None = None, progress: bool = True, overwrite: bool = False,
              _after_chunk: Callable[[int], None] | None = None) -> SweepSummary:
    """Run (or resume) ``spec`` into directory ``out``; returns the summary.

    Local: chunks one after another, each over ``n_threads`` threads (default all cores).
    ``scheduler``: address of a Dask distributed scheduler (or ``local:N`` for a throw-away
    N-worker LocalCluster); chunks run as tasks, results are written here as they arrive.
    ``_after_chunk(k_written)`` is a test hook called after each chunk file is written (it may
    raise to simulate an interruption).  Interrupted work (Ctrl-C, a killed process) is resumed
    by calling again with the same spec.
    """
    from tqdm import tqdm

    out = Path(out)
    t0 = time.perf_counter()
    points = design_points(spec)
    validate_points(spec, points)
    meta_old = _prepare_out(out, spec, overwrite)       # all checks done before anything is written
    out.mkdir(parents=True, exist_ok=True)
    lock = _acquire_lock(out)
    try:
        if overwrite and meta_old is None:
            _wipe(out)
        _clean_temp(out)
        src = sim_source_hash()
        if meta_old is not None and meta_old.get("sim_source_sha256") not in (None, src):
            raise UserError(f"{out}: the simulator's source (sim/) changed since this sweep started, so the chunks "
                            f"on disk were computed by different code; use --overwrite or a new --out")
        done = _existing_chunks(out, spec)
        backend = f"dask {scheduler}" if scheduler else f"local, {n_threads or os.cpu_count() or 1} threads"
        session = {"started": datetime.now(timezone.utc).isoformat(timespec="seconds"), "backend": backend,
                   "host": socket.gethostname(), "resumed_chunks": len(done)}
        meta = dict(meta_old or {})
        meta.update({
            **spec.describe(), "fingerprint": spec.fingerprint, "spec_canonical": spec.canonical(),
            "n_chunks": spec.n_chunks, "format": FORMAT_VERSION,
            "created": (meta_old or {}).get("created") or session["started"],
            **_git_commit(), "sim_source_sha256": src,
            "versions": package_versions(("dask", "distributed") if scheduler else ()),
            "columns": columns(spec.model), "complete": False,
        })
        meta["sessions"] = list((meta_old or {}).get("sessions", [])) + [session]
        atomic_write_json(out / META_NAME, meta)

        todo = [k for k in range(spec.n_chunks) if k not in done]
        n_done_pts = sum(spec.chunk_bounds(k)[1] - spec.chunk_bounds(k)[0] for k in done)
        bar = tqdm(total=spec.n_points, initial=n_done_pts, unit="sim", desc="sweep", disable=not progress,
                   dynamic_ncols=True, smoothing=0.1)
        computed = 0
        t_compute = time.perf_counter()
        base_meta = {"vibro.fingerprint": spec.fingerprint, "vibro.model": spec.model}

        def write(k: int, df: pd.DataFrame) -> None:
            nonlocal computed
            start, stop = spec.chunk_bounds(k)
            if len(df) != stop - start or not np.array_equal(df["point_id"].to_numpy(), np.arange(start, stop)):
                raise RuntimeError(f"chunk {k}: got rows for the wrong points")
            _write_chunk(out, k, _to_table(df, spec.model,
                                           {**base_meta, "vibro.chunk": k, "vibro.start": start, "vibro.stop": stop}))
            computed += stop - start
            bar.update(stop - start)
            if _after_chunk is not None:
                _after_chunk(k)

        chunks = ((k, points.iloc[slice(*spec.chunk_bounds(k))].reset_index(drop=True)) for k in todo)
        try:
            if scheduler:
                from pipeline.dask_backend import run_on_dask

                run_on_dask(scheduler, spec, chunks, write)
            else:
                for k, pts in chunks:
                    write(k, compute_chunk(spec.model, spec.preset, spec.settings, spec.fixed, pts, n_threads))
                    delay = os.environ.get("VIBRO_SWEEP_TEST_DELAY_S")   # test hook: widen the kill window
                    if delay:
                        time.sleep(float(delay))
        finally:
            bar.close()
        t_end = time.perf_counter()
        missing = [k for k in range(spec.n_chunks) if not (out / f"part-{k:05d}.parquet").exists()]
        if missing:
            raise RuntimeError(f"sweep ended with {len(missing)} chunk(s) missing (first: {missing[0]})")
        counts = status_counts(out)
        wall = t_end - t0
        rate = computed / (t_end - t_compute) if computed and t_end > t_compute else None
        session.update({"wall_time_s": round(wall, 3), "computed": computed, "sims_per_s": rate})
        meta["sessions"][-1] = session
        meta.update({"complete": True, "status_counts": counts,
                     "wall_time_s": round(sum(s.get("wall_time_s", 0.0) for s in meta["sessions"]), 3),
                     "finished": datetime.now(timezone.utc).isoformat(timespec="seconds")})
        atomic_write_json(out / META_NAME, meta)
    finally:
        lock.release()
    return SweepSummary(out=str(out), n_points=spec.n_points, n_chunks=spec.n_chunks, computed=computed,
                        reused=n_done_pts, status_counts=counts, wall_time_s=wall, sims_per_s=rate,
                        fingerprint=spec.fingerprint, backend=backend, metadata=meta)


# ------------------------------------------------------------------------------------- load
def load_dataset(path: str | os.PathLike, allow_partial: bool = False) -> pd.DataFrame:
    """Read a sweep dataset (directory of chunks, or one .parquet file), rows ordered by ``point_id``.

    Missing labels (status runaway / failed) are null in the file and NaN in the returned float
    columns; ``specific_energy_j_m`` is +inf where nothing progresses.  ``df.attrs["metadata"]``
    holds metadata.json.  An unfinished sweep raises UserError unless ``allow_partial``.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(2, "no such sweep dataset", str(path))
    if path.is_file():
        df = pq.read_table(path).to_pandas()
        return df.sort_values("point_id", kind="stable").reset_index(drop=True)
    meta = _read_meta(path)
    parts = sorted(path.glob(PART_GLOB))
    if not parts:
        raise UserError(f"{path}: no {PART_GLOB} files (not a sweep dataset, or nothing computed yet)")
    table = pa.concat_tables([pq.read_table(p) for p in parts])
    df = table.to_pandas().sort_values("point_id", kind="stable").reset_index(drop=True)
    if df["point_id"].duplicated().any():
        raise UserError(f"{path}: duplicate point_id values (files from different runs mixed by hand?)")
    n_expected = (meta or {}).get("n_points")
    if not allow_partial and (meta is None or not meta.get("complete") or len(df) != n_expected):
        raise UserError(f"{path}: incomplete sweep ({len(df)} of {n_expected} points); rerun the same "
                        f"'vibro sweep' to finish it, or load_dataset(..., allow_partial=True)")
    df.attrs["metadata"] = meta or {}
    return df


def read_params(path: str | os.PathLike, section: str = "sweep") -> dict:
    """The ``section`` mapping of a params.yaml (UserError naming the file when absent or malformed)."""
    import yaml

    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as e:
        raise UserError(f"{p}: not valid YAML ({e})") from None
    if not isinstance(data, dict) or section not in data:
        raise UserError(f"{p}: no '{section}' section")
    if not isinstance(data[section], dict):
        raise UserError(f"{p}: section '{section}' must be a mapping")
    return dict(data[section])

