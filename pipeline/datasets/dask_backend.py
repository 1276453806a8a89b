"""Run sweep chunks on a Dask distributed cluster; the results come back and are written locally.

Workers only compute (``pipeline.datasets.compute.compute_chunk``, one thread per task: a worker with
several threads runs several chunks at once); this process writes each chunk atomically as it
arrives, so resumability and results are the same as a local run.  Workers must have the
``vibro`` package importable (same environment); each worker process loads (or on first use
compiles) the numba kernel once.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable

import pandas as pd

from pipeline.core.dask_client import check_address, connect
from pipeline.datasets.compute import compute_chunk


@dataclass(frozen=True)
class DaskBackend:
    """Chunks as tasks on the Dask scheduler at ``address`` (``tcp://host:port`` or ``local:N``)."""

    address: str
    extra_packages: tuple[str, ...] = ("dask", "distributed")

    def __post_init__(self) -> None:
        check_address(self.address)      # refuse a bad local:N before anything is written

    @property
    def description(self) -> str:
        return f"dask {self.address}"

    def run(self, spec, chunks: Iterable[tuple[int, pd.DataFrame]],
            write: Callable[[int, pd.DataFrame], None]) -> None:
        """Submit every ``(k, points)`` chunk of ``spec`` and call ``write(k, rows)`` as each finishes.

        On an exception (including KeyboardInterrupt) pending tasks are cancelled; chunks already
        written stay on disk for the next resume."""
        run_on_dask(self.address, spec, chunks, write)


def run_on_dask(address: str, spec, chunks: Iterable[tuple[int, pd.DataFrame]],
                write: Callable[[int, pd.DataFrame], None]) -> None:
    """See :meth:`DaskBackend.run`."""
    from distributed import as_completed

    with connect(address) as client:
        keys: dict[str, int] = {}
        futures = []
        for k, pts in chunks:
            fut = client.submit(compute_chunk, spec.model, spec.preset, spec.settings, spec.fixed, pts, 1,
                                key=f"vibro-sweep-{spec.fingerprint[:16]}-{k:05d}", pure=False)
            keys[fut.key] = k
            futures.append(fut)
        try:
            for fut in as_completed(futures):
                write(keys[fut.key], fut.result())
        except BaseException:
            client.cancel(futures)
            raise
