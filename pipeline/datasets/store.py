"""The on-disk sweep dataset: a directory of ``part-XXXXX.parquet`` chunk files (one row per point, ordered by
``point_id``) and ``metadata.json``; its column schema, provenance, lock, resume state and reader.

Every chunk is written atomically and tagged with the spec's fingerprint, so an interrupted sweep rerun with the
same spec computes only the missing chunks; a different spec is refused.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from pipeline.core.integrity import CHECKSUM_SUFFIX, DirLock, checksum_path, verify_checksum, write_with_checksum
from vibrobase.statuses import STATUSES
from pipeline.datasets.spec import SweepSpec


PART_GLOB = "part-*.parquet"

META_NAME = "metadata.json"

LOCK_NAME = ".sweep.lock"


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


def _write_chunk(out: Path, k: int, table) -> None:
    """Write chunk ``k`` atomically with its sidecar ``part-XXXXX.parquet.sha256`` (checked on resume)."""
    import pyarrow.parquet as pq

    write_with_checksum(out / f"part-{k:05d}.parquet", lambda tmp: pq.write_table(table, tmp, compression="zstd"))


def _git_commit() -> dict:
    root = Path(__file__).resolve().parents[2]
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
    """sha256 over the simulator's sources and the bottom package it imports (sim/**/*.py, vibrobase/**/*.py: its
    statuses live there): resumed chunks must come from the same code."""
    import sim
    import vibrobase

    h = hashlib.sha256()
    for pkg in (sim, vibrobase):
        root = Path(pkg.__file__).resolve().parent
        prefix = "" if pkg is sim else f"{pkg.__name__}/"
        for f in sorted(root.rglob("*.py")):
            h.update((prefix + str(f.relative_to(root))).encode())
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


def _acquire_lock(out: Path) -> DirLock:
    """The sweep's exclusive lock on ``out`` (pipeline.core.integrity.DirLock: flock, race-free, no stale locks)."""
    return DirLock(out / LOCK_NAME, what="sweep").acquire()


def _existing_chunks(out: Path, spec: SweepSpec) -> set[int]:
    """Chunks already complete on disk (checked against the fingerprint and expected row count)."""
    import pyarrow.parquet as pq

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


TEMP_RE = re.compile(r"^\.(?:part-\d{5}\.parquet(?:\.sha256)?|metadata\.json)\.[A-Za-z0-9_-]+\.tmp$")
"""Temporaries of a chunk, its sidecar or the metadata (vibrobase.files): the only hidden files a sweep removes."""


def _clean_temp(out: Path) -> None:
    """Remove the temporaries an interrupted sweep left (the caller holds the sweep's lock: no writer is alive)."""
    for p in out.iterdir():
        if TEMP_RE.match(p.name) and p.is_file():
            p.unlink(missing_ok=True)


def _is_sweep_meta(p: Path) -> bool:
    """Whether ``p`` is a sweep's metadata.json (a JSON object with a fingerprint and a canonical spec)."""
    try:
        doc = json.loads(p.read_text())
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and "fingerprint" in doc and "spec_canonical" in doc


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
    if not (out / META_NAME).exists():
        foreign = _foreign_files(out)
        if foreign:
            raise UserError(f"--out {out} holds {len(foreign)} file(s) a sweep did not write (first: "
                            f"{foreign[0].name}); choose a new or empty --out")
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

    foreign = []
    for p in sorted(out.iterdir()):
        if p.name == LOCK_NAME or TEMP_RE.match(p.name) or (p.name == META_NAME and _is_sweep_meta(p)):
            continue
        if p.is_file() and p.name.startswith("part-") and p.name.endswith(".parquet" + CHECKSUM_SUFFIX):
            continue
        if p.is_file() and p.match(PART_GLOB):
            try:
                if b"vibro.fingerprint" in (pq.read_metadata(p).metadata or {}):
                    continue
            except Exception:  # noqa: BLE001 - unreadable: a damaged chunk of ours is still ours if its sidecar exists
                if checksum_path(p).exists():
                    continue
        foreign.append(p)
    return foreign


def _wipe(out: Path) -> None:
    for p in list(out.glob(PART_GLOB)) + list(out.glob(PART_GLOB + CHECKSUM_SUFFIX)) + [out / META_NAME]:
        p.unlink(missing_ok=True)


def status_counts(out: Path) -> dict[str, int]:
    import pyarrow.parquet as pq

    counts = dict.fromkeys(STATUSES, 0)
    for p in sorted(Path(out).glob(PART_GLOB)):
        for s in pq.read_table(p, columns=["status"]).column("status").to_pylist():
            counts[s] = counts.get(s, 0) + 1
    return counts


def _read_table(path: Path):
    """A Parquet file as a pyarrow Table; UserError naming the file when it is not readable Parquet."""
    import pyarrow.parquet as pq

    try:
        return pq.read_table(path)
    except Exception as e:  # noqa: BLE001 - damaged / foreign file: the user's to fix
        raise UserError(f"{path}: not a readable Parquet file ({type(e).__name__}: {str(e).splitlines()[0][:120]})") from None


def _check_chunk(path: Path, required: bool) -> None:
    """UserError naming the chunk unless it matches its checksum sidecar; a chunk without a sidecar
    passes only when not ``required`` (a dataset assembled by hand; 'vibro sweep' writes every sidecar)."""
    if not required and not checksum_path(path).exists():
        return
    bad = verify_checksum(path)
    if bad is not None:
        raise UserError(f"{path}: {bad}; rerun the same 'vibro sweep' to recompute it")


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
    if path.is_file():     # e.g. a simulate_batch table saved by hand: no point_id is fine, file order is kept
        _check_chunk(path, required=False)
        df = _read_table(path).to_pandas()
        if "point_id" not in df.columns:
            return df
        return df.sort_values("point_id", kind="stable").reset_index(drop=True)
    meta = _read_meta(path)
    parts = sorted(path.glob(PART_GLOB))
    if not parts:
        raise UserError(f"{path}: no {PART_GLOB} files (not a sweep dataset, or nothing computed yet)")
    for p in parts:
        _check_chunk(p, required=bool(meta and "n_chunks" in meta))
    tables = [_read_table(p) for p in parts]
    for p, t in zip(parts, tables):
        if "point_id" not in t.column_names:
            raise UserError(f"{p}: no 'point_id' column (not a part written by 'vibro sweep')")
    table = pa.concat_tables(tables)
    df = table.to_pandas().sort_values("point_id", kind="stable").reset_index(drop=True)
    if df["point_id"].duplicated().any():
        raise UserError(f"{path}: duplicate point_id values (files from different runs mixed by hand?)")
    n_expected = (meta or {}).get("n_points")
    if not allow_partial and (meta is None or not meta.get("complete") or len(df) != n_expected):
        raise UserError(f"{path}: incomplete sweep ({len(df)} of {n_expected} points); rerun the same "
                        f"'vibro sweep' to finish it, or load_dataset(..., allow_partial=True)")
    df.attrs["metadata"] = meta or {}
    return df


def load_with_metadata(path: str | os.PathLike) -> tuple[pd.DataFrame, dict]:
    """A sweep dataset (directory, or one .parquet file with an optional sibling metadata.json) and its
    metadata (``{}`` when there is none)."""
    path = Path(path)
    if not path.exists():
        raise UserError(f"dataset '{path}' does not exist")
    if path.is_file() and path.suffix != ".parquet":
        raise UserError(f"dataset '{path}' is neither a directory nor a .parquet file")
    df = load_dataset(path)
    meta = df.attrs.get("metadata") if path.is_dir() else _read_meta(path.parent)
    return df, dict(meta or {})
