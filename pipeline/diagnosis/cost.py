"""Where a diagnosis's time goes: per stage, the simulations it asked for, the CPU seconds and the wall seconds.

A ``CostRecorder`` times named stages (``with recorder.stage("calibration"):``), counting simulations with a
counter it is given (the evaluator's ``n_sims``, which every simulation of the diagnosis adds to, tasks on an
executor included).  CPU time is this process's (every thread) plus its reaped children's plus, where the fit tasks
run elsewhere (a Dask cluster), the CPU time the executor measured where they ran.  A stage opened inside another
is recorded as part of it (``part_of``) and left out of the total, as are the per-model shares of a stage's fit
tasks (``tasks``).  ``DiagnosisCost`` is report.json's ``cost``.
"""
from __future__ import annotations

import contextlib
import os
import time
from dataclasses import asdict, dataclass, replace
from typing import Callable, Iterator, Sequence

SCHEMA = 1
"""Version of report.json ``cost``."""


@dataclass(frozen=True)
class StageCost:
    """One stage: simulations asked for [count], CPU time [s] and wall time [s].  ``system``: the system it
    belongs to ('' for the whole dataset); ``part_of``: the stage it is a part of (None: a top-level stage, counted
    in the total)."""

    stage: str
    simulations: int
    cpu_s: float
    wall_s: float
    system: str = ""
    part_of: str | None = None


@dataclass(frozen=True)
class DiagnosisCost:
    """Every stage of a diagnosis, in the order they began, and the machine's load average when it ended
    (1, 5, 15 min; ``os.getloadavg``)."""

    stages: tuple[StageCost, ...]
    load_avg: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def total(self) -> StageCost:
        """The sum of the top-level stages (a part is already in its stage)."""
        top = [s for s in self.stages if s.part_of is None]
        return StageCost("total", sum(s.simulations for s in top), sum(s.cpu_s for s in top),
                         sum(s.wall_s for s in top))

    def with_stages(self, more: Sequence[StageCost]) -> DiagnosisCost:
        """These stages and ``more`` after them, with the load average now."""
        return DiagnosisCost(self.stages + tuple(more), load_average())

    def to_json(self) -> dict:
        t = self.total
        return {"schema": SCHEMA, "stages": [_row(s) for s in self.stages],
                "total": {"simulations": t.simulations, "cpu_s": round(t.cpu_s, 3), "wall_s": round(t.wall_s, 3)},
                "load_avg": list(self.load_avg)}

    @classmethod
    def from_json(cls, d: dict) -> DiagnosisCost:
        return cls(tuple(StageCost(**s) for s in d["stages"]), tuple(d["load_avg"]))


def _row(s: StageCost) -> dict:
    return {**asdict(s), "cpu_s": round(s.cpu_s, 3), "wall_s": round(s.wall_s, 3)}


def load_average() -> tuple[float, float, float]:
    """The machine's load average over 1, 5 and 15 min (zeros where the platform has none)."""
    try:
        return tuple(round(x, 2) for x in os.getloadavg())
    except OSError:
        return (0.0, 0.0, 0.0)


def _no_simulations() -> int:
    return 0


def _no_remote_cpu() -> float:
    return 0.0


def process_cpu_s() -> float:
    """CPU seconds of this process (every thread) and of its children that have ended [s]."""
    t = os.times()
    return time.process_time() + t.children_user + t.children_system


def remote_cpu_of(executor) -> Callable[[], float]:
    """The running CPU seconds of ``executor``'s tasks when they run outside this process (its ``runs_elsewhere``),
    as measured where they ran; 0 for an executor whose tasks this process's own CPU time covers."""
    if not getattr(executor, "runs_elsewhere", False):
        return _no_remote_cpu
    return lambda: float(sum(executor.stats.cpu_s))


class CostRecorder:
    """Records the cost of named stages of ``system``; ``simulations``: the running count of simulations asked for;
    ``remote_cpu``: the running CPU seconds of tasks run outside this process (0 when they run here)."""

    def __init__(self, system: str = "", simulations: Callable[[], int] = _no_simulations,
                 remote_cpu: Callable[[], float] = _no_remote_cpu) -> None:
        self.system, self.simulations, self.remote_cpu = system, simulations, remote_cpu
        self._rows: list[StageCost | None] = []
        self._open: list[str] = []
        self._parts: dict[tuple[str, str], int] = {}      # (stage, part) -> its row

    def _now(self) -> tuple[int, float, float]:
        return self.simulations(), process_cpu_s() + self.remote_cpu(), time.perf_counter()

    @contextlib.contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the ``with`` block as stage ``name`` (part of the stage open around it, if any)."""
        parent = self._open[-1] if self._open else None
        k = len(self._rows)
        self._rows.append(None)             # the row keeps its place: stages are listed in the order they began
        self._open.append(name)
        s0, c0, w0 = self._now()
        try:
            yield
        finally:
            s1, c1, w1 = self._now()
            self._open.pop()
            self._rows[k] = StageCost(name, s1 - s0, c1 - c0, w1 - w0, self.system, parent)

    def tasks(self, labels: Sequence[str], simulations: Sequence[int], cpu_s: Sequence[float],
              wall_s: Sequence[float]) -> None:
        """Fit tasks of the open stage, each with the part it belongs to (a model's name): each part's simulations,
        CPU and wall seconds [s] summed into a row that is part of the stage (none outside a stage)."""
        if not self._open:
            return
        stage = self._open[-1]
        for label, n, c, w in zip(labels, simulations, cpu_s, wall_s):
            key = (stage, label)
            if key not in self._parts:
                self._parts[key] = len(self._rows)
                self._rows.append(StageCost(label, 0, 0.0, 0.0, self.system, stage))
            k = self._parts[key]
            r = self._rows[k]
            self._rows[k] = replace(r, simulations=r.simulations + int(n), cpu_s=r.cpu_s + c, wall_s=r.wall_s + w)

    def rows(self) -> tuple[StageCost, ...]:
        """The stages recorded so far, closed ones only, in the order they began."""
        return tuple(r for r in self._rows if r is not None)
