"""``run_sweep_job``: what ``vibro sweep`` does after parsing — the backend, the sweep, the overview figure.

The command builds a :class:`SweepJob` from params.yaml and the flags, calls :func:`run_sweep_job` inside its
MLflow run, then prints, writes the metrics file and logs the :class:`SweepJobResult`.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from pipeline.datasets.runner import SweepSummary, run_sweep
from pipeline.datasets.spec import SweepSpec, design_points, validate_points


def _local(scheduler: str | None, workers: int | None):
    from pipeline.datasets.runner import LocalBackend

    return LocalBackend(workers)


def _dask(scheduler: str, workers: int | None):
    from pipeline.datasets.dask_backend import DaskBackend

    return DaskBackend(scheduler)


BACKENDS = {"local": _local, "dask": _dask}
"""Backend kind -> factory(scheduler, workers); a scheduler address selects 'dask'."""


def make_backend(scheduler: str | None, workers: int | None):
    """The sweep backend for a scheduler address (Dask) or else local threads (``workers``, default all cores)."""
    return BACKENDS["dask" if scheduler else "local"](scheduler, workers)


@dataclass(frozen=True)
class SweepJob:
    """One sweep run: the validated spec, where the dataset goes and how it is computed."""
    spec: SweepSpec
    out: Path                         # dataset directory
    scheduler: str | None = None      # Dask scheduler address; None = local threads
    workers: int | None = None        # local worker threads (None = all cores)
    overwrite: bool = False
    plot: Path | None = None          # overview figure (PNG) of the first two varied parameters; None = none


@dataclass(frozen=True)
class SweepJobResult:
    """The sweep summary and the overview figure drawn (None with fewer than two varied parameters)."""
    summary: SweepSummary
    plot: Path | None


def plan_lines(spec: SweepSpec, out: str) -> list[str]:
    """The --dry-run plan of ``spec`` (the design points are drawn and checked, nothing is written)."""
    validate_points(spec, design_points(spec))
    lines = [f"sweep plan: model {spec.model}, preset {spec.preset}, design {spec.design}, {spec.n_points} points "
             f"in {spec.n_chunks} chunks of {spec.chunk_size}, seed {spec.seed}, fingerprint {spec.fingerprint[:12]}"]
    lines += [f"  vary {name}: {r.low:g} .. {r.high:g} ({r.scale})" for name, r in spec.vary.items()]
    lines += [f"  fixed {name} = {v:g}" for name, v in spec.fixed.items()]
    lines.append(f"  -> {out} (nothing written: --dry-run)")
    return lines


def run_sweep_job(job: SweepJob, progress: bool = True) -> SweepJobResult:
    """Run (or resume) the sweep; draw the overview figure to ``job.plot`` when two parameters vary."""
    spec = job.spec
    summary = run_sweep(spec, job.out, backend=make_backend(job.scheduler, job.workers), progress=progress,
                        overwrite=job.overwrite)
    plot = None
    names = list(spec.vary)
    if job.plot is not None and len(names) >= 2:
        from pipeline.datasets.plot import plot_sweep
        from pipeline.datasets.store import load_dataset

        plot_sweep(load_dataset(job.out), names[0], names[1], job.plot,
                   title=f"{spec.model} ({spec.preset or 'defaults'}): {spec.n_points} {spec.design} points")
        plot = Path(job.plot)
    return SweepJobResult(summary, plot)
