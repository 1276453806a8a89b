"""Progress of a diagnosis: named stages, each with the number of fit tasks it is expected to run.

The workflow announces each stage (``stage``); the executor reports every finished task (``task_done``, wired by
the command); a terminal bar shows the stage, the tasks done and an estimate of the stage's time left.
"""
from __future__ import annotations

from typing import Protocol


class Progress(Protocol):
    def stage(self, name: str, tasks: int | None = None) -> None:
        """A new stage ``name`` begins; ``tasks``: the fit tasks it is expected to run (None: unknown)."""

    def task_done(self) -> None:
        """One task of the current stage finished."""


class NoProgress:
    """Progress that shows nothing (library use, ``--quiet``)."""

    def stage(self, name: str, tasks: int | None = None) -> None:
        pass

    def task_done(self) -> None:
        pass


def fit_tasks(n_folds: int, n_candidates: int, n_starts: int, candidate_starts: int, warm: bool) -> int:
    """Expected tasks of ``calibrate.fit_models`` [count]: per fold the base's starts and its polish, each
    candidate's start grid (not when warm-started), starts and polish, and the refit of the base and the leader
    (a start and a polish each)."""
    base = (1 if warm else n_starts) + 1
    per_candidate = (1 if warm else 2 * candidate_starts) + 1
    return n_folds * (base + n_candidates * per_candidate + 4)
