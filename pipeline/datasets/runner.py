"""Chunked, resumable execution of a sweep on a backend (local threads, or any object with the same ``run``).

The runner owns the output folder (lock, metadata, atomic chunk files, resume); a backend only computes chunks
and hands each back through ``write``.  The Dask backend lives in ``dask_backend.py``; the CLI picks one by name.
"""
from __future__ import annotations

import os
import socket
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Iterable, Protocol

import numpy as np
import pandas as pd

from pipeline.core.errors import UserError
from vibrobase.files import atomic_write_json
from pipeline.datasets.compute import compute_chunk
from pipeline.datasets.spec import SweepSpec, design_points, validate_points
from pipeline.datasets.spec import FORMAT_VERSION
from pipeline.datasets.store import (META_NAME, _acquire_lock, _clean_temp, _existing_chunks, _git_commit,
                                     _prepare_out, _to_table, _wipe, _write_chunk, columns, package_versions,
                                     sim_source_hash, status_counts)


class Backend(Protocol):
    """Where a sweep's chunks are computed: ``run`` calls ``write(k, rows)`` once per ``(k, points)`` chunk."""

    description: str
    extra_packages: tuple[str, ...]

    def run(self, spec: SweepSpec, chunks: Iterable[tuple[int, pd.DataFrame]],
            write: Callable[[int, pd.DataFrame], None]) -> None: ...


@dataclass(frozen=True)
class LocalBackend:
    """Chunks one after another in this process, each over ``n_threads`` threads (default: all cores)."""

    n_threads: int | None = None
    extra_packages: tuple[str, ...] = ()

    @property
    def description(self) -> str:
        return f"local, {self.n_threads or os.cpu_count() or 1} threads"

    def run(self, spec: SweepSpec, chunks: Iterable[tuple[int, pd.DataFrame]],
            write: Callable[[int, pd.DataFrame], None]) -> None:
        for k, pts in chunks:
            write(k, compute_chunk(spec.model, spec.preset, spec.settings, spec.fixed, pts, self.n_threads))
            delay = os.environ.get("VIBRO_SWEEP_TEST_DELAY_S")   # test hook: widen the kill window
            if delay:
                time.sleep(float(delay))


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


def run_sweep(spec: SweepSpec, out: str | os.PathLike, *, backend: Backend | None = None,
              progress: bool = True, overwrite: bool = False,
              _after_chunk: Callable[[int], None] | None = None) -> SweepSummary:
    """Run (or resume) ``spec`` into directory ``out``; returns the summary.

    ``backend`` computes the chunks (default :class:`LocalBackend` over all cores; the Dask backend
    runs them as tasks on a cluster); results are written here, atomically, as they arrive.
    ``_after_chunk(k_written)`` is a test hook called after each chunk file is written (it may
    raise to simulate an interruption).  Interrupted work (Ctrl-C, a killed process) is resumed
    by calling again with the same spec.
    """
    out = Path(out)
    t0 = time.perf_counter()
    points = design_points(spec)
    validate_points(spec, points)
    meta_old = _prepare_out(out, spec, overwrite)       # all checks done before anything is written
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    lock = _acquire_lock(out)
    written = _Written()
    undo = False
    try:
        if overwrite and meta_old is None:
            _wipe(out)
        _clean_temp(out)
        src = _source_hash(out, meta_old)
        done = _existing_chunks(out, spec)
        backend = backend if backend is not None else LocalBackend()
        description = backend.description
        meta, session = _start_session(out, spec, meta_old, backend, description, src, len(done))
        n_done_pts = sum(spec.chunk_bounds(k)[1] - spec.chunk_bounds(k)[0] for k in done)
        t_compute, t_end = _compute_chunks(spec, out, points, done, n_done_pts, backend, written, progress,
                                           _after_chunk)
        computed = written.points
        wall = t_end - t0
        rate = computed / (t_end - t_compute) if computed and t_end > t_compute else None
        counts = _finish_session(out, spec, meta, session, computed, wall, rate)
    except UserError:
        undo = created and not written.any     # e.g. the scheduler failed: a folder this call made holds nothing
        raise
    finally:
        lock.release()
        if undo:
            import shutil

            shutil.rmtree(out, ignore_errors=True)
    return SweepSummary(out=str(out), n_points=spec.n_points, n_chunks=spec.n_chunks, computed=computed,
                        reused=n_done_pts, status_counts=counts, wall_time_s=wall, sims_per_s=rate,
                        fingerprint=spec.fingerprint, backend=description, metadata=meta)


@dataclass
class _Written:
    """What this session wrote: whether any chunk, and how many points."""

    any: bool = False
    points: int = 0


def _source_hash(out: Path, meta_old: dict | None) -> str:
    """The simulator's source hash, refused when it differs from the one the chunks on disk were computed with."""
    src = sim_source_hash()
    if meta_old is not None and meta_old.get("sim_source_sha256") not in (None, src):
        raise UserError(f"{out}: the simulator's source (sim/) changed since this sweep started, so the chunks "
                        f"on disk were computed by different code; use --overwrite or a new --out")
    return src


def _start_session(out: Path, spec: SweepSpec, meta_old: dict | None, backend: Backend, description: str,
                   src: str, n_resumed: int) -> tuple[dict, dict]:
    """The metadata (the old one updated, this session appended, not complete) written to ``out``; it and the
    session's entry."""
    session = {"started": datetime.now(timezone.utc).isoformat(timespec="seconds"), "backend": description,
               "host": socket.gethostname(), "resumed_chunks": n_resumed}
    meta = dict(meta_old or {})
    meta.update({
        **spec.describe(), "fingerprint": spec.fingerprint, "spec_canonical": spec.canonical(),
        "n_chunks": spec.n_chunks, "format": FORMAT_VERSION,
        "created": (meta_old or {}).get("created") or session["started"],
        **_git_commit(), "sim_source_sha256": src,
        "versions": package_versions(backend.extra_packages),
        "columns": columns(spec.model), "complete": False,
    })
    meta["sessions"] = list((meta_old or {}).get("sessions", [])) + [session]
    atomic_write_json(out / META_NAME, meta)
    return meta, session


def _compute_chunks(spec: SweepSpec, out: Path, points: pd.DataFrame, done, n_done_pts: int, backend: Backend,
                    written: _Written, progress: bool,
                    _after_chunk: Callable[[int], None] | None) -> tuple[float, float]:
    """The chunks not ``done`` computed on ``backend`` and written to ``out`` as they arrive (counted in
    ``written``), with a progress bar; the clock at the start and end of the computation."""
    from tqdm import tqdm

    todo = [k for k in range(spec.n_chunks) if k not in done]
    bar = tqdm(total=spec.n_points, initial=n_done_pts, unit="sim", desc="sweep", disable=not progress,
               dynamic_ncols=True, smoothing=0.1)
    t_compute = time.perf_counter()
    base_meta = {"vibro.fingerprint": spec.fingerprint, "vibro.model": spec.model}

    def write(k: int, df: pd.DataFrame) -> None:
        written.any = True
        start, stop = spec.chunk_bounds(k)
        if len(df) != stop - start or not np.array_equal(df["point_id"].to_numpy(), np.arange(start, stop)):
            raise RuntimeError(f"chunk {k}: got rows for the wrong points")
        _write_chunk(out, k, _to_table(df, spec.model,
                                       {**base_meta, "vibro.chunk": k, "vibro.start": start, "vibro.stop": stop}))
        written.points += stop - start
        bar.update(stop - start)
        if _after_chunk is not None:
            _after_chunk(k)

    chunks = ((k, points.iloc[slice(*spec.chunk_bounds(k))].reset_index(drop=True)) for k in todo)
    try:
        backend.run(spec, chunks, write)
    finally:
        bar.close()
    return t_compute, time.perf_counter()


def _finish_session(out: Path, spec: SweepSpec, meta: dict, session: dict, computed: int, wall: float,
                    rate: float | None) -> dict[str, int]:
    """Every chunk checked present, the session's numbers and the dataset's status counts written to the metadata
    (now complete); the status counts."""
    missing = [k for k in range(spec.n_chunks) if not (out / f"part-{k:05d}.parquet").exists()]
    if missing:
        raise RuntimeError(f"sweep ended with {len(missing)} chunk(s) missing (first: {missing[0]})")
    counts = status_counts(out)
    session.update({"wall_time_s": round(wall, 3), "computed": computed, "sims_per_s": rate})
    meta["sessions"][-1] = session
    meta.update({"complete": True, "status_counts": counts,
                 "wall_time_s": round(sum(s.get("wall_time_s", 0.0) for s in meta["sessions"]), 3),
                 "finished": datetime.now(timezone.utc).isoformat(timespec="seconds")})
    atomic_write_json(out / META_NAME, meta)
    return counts
