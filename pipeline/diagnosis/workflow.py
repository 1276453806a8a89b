"""Whole-dataset diagnosis: every system diagnosed, its runs simulated for the figures, its corrected rig and the
report built (``pipeline.diagnosis.report_types.DiagnoseReport``).  Nothing is written
(``pipeline.diagnosis.outputs`` does that)."""
from __future__ import annotations

import time
from dataclasses import asdict, replace

from pipeline.core.executors import Executor, InlineExecutor
from pipeline.diagnosis.cost import CostRecorder, DiagnosisCost, load_average
from pipeline.diagnosis.features import peak_velocity, simulated_features
from pipeline.diagnosis.report import figure_names, residual_structure
from pipeline.diagnosis.report_types import DiagnoseReport
from pipeline.diagnosis.result import DiagnoseResult, SimulatedRun, SimulatedRuns, SystemDiagnosis
from pipeline.diagnosis.rigout import corrected_rig, rig_file_name
from pipeline.diagnosis.run import DiagnoseConfig, build_targets, diagnose_system

SUMMARY_NOTE = ("summary data: the measurement sd is assumed (summary.csv '<feature>_sd' columns or the defaults of "
                "pipeline/diagnosis/features.py), not estimated from the data, so 'explained' is only as good as that "
                "assumption")
UNREPRODUCIBLE_NOTE = ("run {run}: the model's response there is chaotic or multi-stable (solved again at a hundredth "
                       "of the tolerance, its features move by nrms {nrms:.3g}), so no trajectory of the model can be "
                       "compared with the record cycle by cycle and the fit may bend parameters to match it; {what}")
LEFT_OUT = "left out of the fits and the held-out errors (setting fit_unreproducible: true keeps it)"
KEPT = {True: "kept in the fits (setting fit_unreproducible: true)",
        False: "kept in the fits (leaving it out would leave a fold fewer than two calibration runs); consider "
               "leaving it out of runs.csv"}
"""Why an unreproducible run is still in the split: asked for, or ``judge.without_runs`` declined."""


def diagnose(ds, cfg: DiagnoseConfig, log=print, progress=None, executor: Executor | None = None) -> DiagnoseResult:
    """Diagnose every system of the measured dataset ``ds``; writes nothing.  The independent fits run on
    ``executor`` (default: in this process; a ``DaskExecutor`` sends them to a cluster, with the same result).
    BLAS runs one thread meanwhile: the simulations run in threads of their own, and OpenBLAS threads beside
    them spin for the cores (its least-squares feature fits took ~40x longer)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        return _diagnose(ds, cfg, log, progress, executor or InlineExecutor())


def simulate_runs(diag: SystemDiagnosis) -> SimulatedRuns:
    """Every run of ``diag``'s system simulated at the default, calibrated base and final parameters, each with a
    history (for the peak velocity; a run whose features are labels gets the labels the fits saw: the same
    integrator, ``model.run_settings``)."""
    ev = diag.evaluator
    idx = list(range(len(ev.targets)))
    sets = [{}, diag.fits["base"].values, diag.fits[diag.final].values]
    rows = [[SimulatedRun(i, ev.residual_of(i, r), r, simulated_features(ev.targets[i], r), peak_velocity(r))
             for i, r in zip(idx, row)] for row in ev.simulate(sets, idx, history=True)]
    return SimulatedRuns(default=rows[0], base=rows[1], final=rows[2])


def _presets(ds, system: str) -> list[str | None]:
    """The runs' ``preset`` column of ``system`` (None where a run names none)."""
    rows = ds.runs[ds.runs["system"] == system]
    return [str(p).strip() if isinstance(p, str) and p.strip() else None
            for p in (rows["preset"] if "preset" in rows else [None] * len(rows))]


def _diagnose(ds, cfg: DiagnoseConfig, log, progress, executor: Executor) -> DiagnoseResult:
    t0 = time.time()
    skipped: dict[str, list[str]] = {}
    features = CostRecorder()
    with features.stage("features"):
        targets = build_targets(ds, cfg, skipped)
    diags, runs, costs = [], [], list(features.rows())
    for system, tgs in targets.items():
        diag = diagnose_system(system, tgs, cfg, log, progress, executor)
        if progress is not None:
            progress.stage(f"{system}: simulating the reported models for the figures")
        figs = CostRecorder(system, lambda: diag.evaluator.n_sims)
        with figs.stage("figures: runs"):
            sim_runs = simulate_runs(diag)
        costs += [*diag.cost, *figs.rows()]
        notes = [SUMMARY_NOTE] if "summary" in diag.report.data else []
        notes += diag.report.notes          # what the diagnosis itself left out
        used = {r for fold in diag.report.split.folds for r in (*fold.calibration, *fold.held_out)}
        notes += [UNREPRODUCIBLE_NOTE.format(run=r, nrms=x,
                                             what=KEPT[cfg.fit_unreproducible] if r in used else LEFT_OUT)
                  for r, x in diag.report.unreproducible.items()]
        notes += skipped.get(system, []) + [n for t in tgs for n in t.notes]     # what the recording left out
        structure = residual_structure(diag, sim_runs.base, sim_runs.final)
        diag = replace(diag, report=replace(diag.report, residual_structure=structure, notes=tuple(notes)))
        diags.append(diag)
        runs.append(sim_runs)
    dataset = str(ds.path) if ds.path else "dataset"
    systems, rigs = [], []
    for diag in diags:
        rig, info = corrected_rig(diag, _presets(ds, diag.system), dataset)
        info = replace(info, file=rig_file_name(diag.system, len(diags)))
        rigs.append((info.file, rig))
        diag = replace(diag, report=replace(diag.report, rig=info))
        systems.append(replace(diag, report=replace(diag.report, figures=tuple(figure_names(diag)))))
    cost = DiagnosisCost(tuple(costs), load_average())
    report = DiagnoseReport(dataset=dataset, config=asdict(cfg), systems=tuple(d.report for d in systems),
                            wall_time_s=round(time.time() - t0, 1), cost=cost.to_json())
    return DiagnoseResult(systems=tuple(systems), report=report, runs=tuple(runs), rigs=tuple(rigs),
                          series=dict(ds.series), cost=cost)

