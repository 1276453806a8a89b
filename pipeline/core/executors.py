"""Executors: how a workflow runs a batch of independent tasks, in this process or on a Dask cluster.

A task is ``fn(shared, item)``: ``fn`` a module-level function (pickled by reference for the workers), ``shared`` an
object every task of the batch reads (sent to a cluster once, not once per task), ``item`` the task's own input.
``map`` returns the results in the order of the items, whatever order they finished in, so a workflow that combines
them in that order gets the same numbers from every executor.
"""
from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Protocol, Sequence


@dataclass
class TaskStats:
    """What an executor ran: batches, and per task its batch number and its wall and CPU time [s] where it ran."""

    n_batches: int = 0
    batch: list[int] = field(default_factory=list)
    wall_s: list[float] = field(default_factory=list)
    cpu_s: list[float] = field(default_factory=list)

    @property
    def n_tasks(self) -> int:
        return len(self.wall_s)

    def add(self, timed: Sequence[tuple[Any, float, float]]) -> list:
        """Record ``(result, wall_s, cpu_s)`` of one batch; the results."""
        self.batch += [self.n_batches] * len(timed)
        self.n_batches += 1
        self.wall_s += [w for _, w, _ in timed]
        self.cpu_s += [c for _, _, c in timed]
        return [r for r, _, _ in timed]


class Executor(Protocol):
    """Runs batches of tasks; ``task_threads`` is how many threads one task may use (None: as many as the
    workflow would use itself)."""

    task_threads: int | None
    stats: TaskStats
    description: str

    def map(self, fn: Callable[[Any, Any], Any], shared: Any, items: Sequence) -> list: ...


def _timed(fn: Callable, shared: Any, item: Any, clock: Callable[[], float]) -> tuple[Any, float, float]:
    """``(fn(shared, item), wall_s, cpu_s)`` with CPU seconds from ``clock``."""
    w, c = time.perf_counter(), clock()
    out = fn(shared, item)
    return out, time.perf_counter() - w, clock() - c


def _timed_in_thread(fn: Callable, shared: Any, item: Any) -> tuple[Any, float, float]:
    """A task on a worker: CPU of its own thread (other tasks may share the worker process)."""
    return _timed(fn, shared, item, time.thread_time)


@dataclass
class InlineExecutor:
    """Tasks one after another in this process; each may use the workflow's own threads."""

    task_threads: int | None = None
    stats: TaskStats = field(default_factory=TaskStats)
    description: str = "local"
    on_task_done: Callable[[], None] | None = None      # called after every task (progress bars)

    def map(self, fn: Callable[[Any, Any], Any], shared: Any, items: Sequence) -> list:
        out = []
        for it in items:
            out.append(_timed(fn, shared, it, time.process_time))
            if self.on_task_done is not None:
                self.on_task_done()
        return self.stats.add(out)


class DaskExecutor:
    """Tasks on a ``distributed.Client``, one thread each: ``shared`` scattered to the workers once per object,
    results gathered in the order submitted.  An exception (or Ctrl-C) cancels the batch's pending tasks."""

    task_threads: int | None = 1
    runs_elsewhere = True       # tasks' CPU time is not this process's (pipeline.diagnosis.cost)

    def __init__(self, client, description: str = "dask") -> None:
        self.client = client
        self.description = description
        self.stats = TaskStats()
        self._shared: tuple[Any, Any] | None = None     # (object, its future on the cluster)
        self.on_task_done: Callable[[], None] | None = None     # called as each task finishes (progress bars)

    def _scatter(self, shared: Any):
        if self._shared is None or self._shared[0] is not shared:
            self._shared = (shared, self.client.scatter(shared, broadcast=True, hash=False))
        return self._shared[1]

    def map(self, fn: Callable[[Any, Any], Any], shared: Any, items: Sequence) -> list:
        ref = self._scatter(shared)
        futures = [self.client.submit(_timed_in_thread, fn, ref, it, pure=False) for it in items]
        try:
            if self.on_task_done is not None:
                from distributed import as_completed

                for _ in as_completed(futures):
                    self.on_task_done()
            return self.stats.add(self.client.gather(futures))
        except BaseException:
            self.client.cancel(futures)
            raise


@contextlib.contextmanager
def open_executor(scheduler: str | None) -> Iterator[Executor]:
    """The executor for a ``--scheduler`` value: None runs the tasks in this process, an address (``tcp://host:port``
    or ``local:N``) on that Dask cluster, connected for the ``with`` block (UserError when it cannot be reached)."""
    if scheduler is None:
        yield InlineExecutor()
        return
    from pipeline.core.dask_client import connect

    with connect(scheduler) as client:
        yield DaskExecutor(client, description=f"dask {scheduler}")
