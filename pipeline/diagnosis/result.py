"""Typed results of a diagnosis: one system's (``SystemDiagnosis``) and the whole dataset's (``DiagnoseResult``)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np
    import pandas as pd

    import sim
    from sim.empirical import EmpiricalCorrection
    from pipeline.diagnosis.cost import DiagnosisCost, StageCost
    from pipeline.diagnosis.features import Target
    from pipeline.diagnosis.fit import FitResult
    from pipeline.diagnosis.model import Evaluator
    from pipeline.diagnosis.report_types import DiagnoseReport, SystemReport


@dataclass(frozen=True)
class SystemDiagnosis:
    """One system's diagnosis.

    report: the system's entry of report.json (``pipeline.diagnosis.report_types.SystemReport``);
    evaluator: the simulator of the system's runs (its ``targets`` in runs.csv order);
    fits: the reported fits by model name ('base' and every candidate effect);
    held_out: indices into the targets of the held-out runs, fold after fold;
    final: the final model's name, the selected effect or 'base';
    cost: the cost of each stage of the system's diagnosis (``pipeline.diagnosis.cost``);
    empirical: the adopted empirical correction of ROP (``sim.empirical``; None: none adopted).
    """

    report: SystemReport
    evaluator: Evaluator
    fits: dict[str, FitResult]
    held_out: list[int]
    final: str
    cost: tuple[StageCost, ...] = ()
    empirical: EmpiricalCorrection | None = None

    @property
    def system(self) -> str:
        return self.report.system

    @property
    def targets(self) -> list[Target]:
        """The runs the system was evaluated on, in runs.csv order."""
        return list(self.evaluator.targets)


@dataclass(frozen=True)
class SimulatedRun:
    """One run simulated for the report: ``run`` (target index), ``residual`` (noise-normalised), ``result``
    (SimulationResult or None), ``model`` (simulated features or None), ``peak_velocity_m_s`` [m/s] (None without a
    history)."""

    run: int
    residual: np.ndarray
    result: object
    model: np.ndarray | None
    peak_velocity_m_s: float | None


@dataclass(frozen=True)
class SimulatedRuns:
    """Every run of a system simulated with the default, calibrated base and final parameters."""

    default: list[SimulatedRun]
    base: list[SimulatedRun]
    final: list[SimulatedRun]


@dataclass(frozen=True)
class DiagnoseResult:
    """A whole dataset's diagnosis; nothing written yet (``pipeline.diagnosis.outputs`` writes it).

    systems: per system, in the dataset's order; report: report.json as a ``DiagnoseReport`` (its ``to_json``);
    runs: the simulated runs the figures draw, aligned with ``systems``;
    rigs: (file name, corrected ``sim.Rig``) per system; series: the measured series by run id [SI units];
    cost: where the time went, per stage (report.json ``cost``; None: not recorded).
    """

    systems: tuple[SystemDiagnosis, ...]
    report: DiagnoseReport
    runs: tuple[SimulatedRuns, ...]
    rigs: tuple[tuple[str, sim.Rig], ...]
    series: dict[str, pd.DataFrame]
    cost: DiagnosisCost | None = None
