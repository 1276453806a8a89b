"""Whole-dataset diagnosis: every system, figures, report.json and report.md written atomically."""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

from pipeline.core.files import atomic_directory
from pipeline.core.jsonable import to_jsonable
from pipeline.diagnosis.features import simulated_features
from pipeline.diagnosis.report import figures, markdown, residual_structure
from pipeline.diagnosis.rigout import corrected_rig, rig_file_name
from pipeline.diagnosis.run import DiagnoseConfig, build_targets, diagnose_system

SUMMARY_NOTE = ("summary data: the measurement sd is assumed (summary.csv '<feature>_sd' columns or the defaults of "
                "pipeline/diagnosis/features.py), not estimated from the data, so 'explained' is only as good as that "
                "assumption")


def diagnose(ds, out: str | os.PathLike, cfg: DiagnoseConfig, log=print, progress=None) -> dict:
    """Diagnose ``ds`` into directory ``out`` (report.json, report.md, PNG figures, and the corrected rig:
    rig.yaml, or rig-<system>.yaml per system of a several-system dataset); returns the report.
    BLAS runs one thread meanwhile: the simulations run in threads of their own, and OpenBLAS threads beside
    them spin for the cores (its least-squares feature fits took ~40x longer)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        return _diagnose(ds, out, cfg, log, progress)


def _diagnose(ds, out: str | os.PathLike, cfg: DiagnoseConfig, log=print, progress=None) -> dict:
    t0 = time.time()
    out = Path(out)
    targets = build_targets(ds, cfg)
    per = []
    for system, tgs in targets.items():
        rep = diagnose_system(system, tgs, cfg, log, progress)
        ev = rep["_ev"]
        idx = list(range(len(tgs)))
        sets = [{}, rep["_fits"]["base"].values, rep["_fits"][rep["_final"]].values]
        sims = ev.simulate(sets, idx)
        runs = [[{"run": i, "residual": ev.residual_of(i, r), "result": r,
                  "model": simulated_features(ev.targets[i], r),
                  "peak_velocity_m_s": (float(r.history["vel_m_s"].max()) if r.history is not None else None)}
                 for i, r in zip(idx, row)] for row in sims]
        rep["residual_structure"] = residual_structure(rep, runs[1], runs[2])
        rep["notes"] = [SUMMARY_NOTE] if "summary" in rep["data"] else []
        rep["_runs"] = runs
        per.append(rep)
    dataset = str(ds.path) if ds.path else "dataset"
    rigs = []
    for rep in per:
        rows = ds.runs[ds.runs["system"] == rep["system"]]
        presets = [str(p).strip() if isinstance(p, str) and p.strip() else None
                   for p in (rows["preset"] if "preset" in rows else [None] * len(rows))]
        rig, info = corrected_rig(rep, ev_targets(rep), presets, dataset)
        info["file"] = rig_file_name(rep["system"], len(per))
        rep["rig"] = info
        rigs.append((info["file"], rig))
    with atomic_directory(out) as tmp:
        from pipeline.core.rigfile import write_rig

        for name, rig in rigs:
            write_rig(tmp / name, rig, comment="the corrected rig of this diagnosis (report.json 'rig')")
        for rep in per:
            rep["figures"] = figures(rep, ds, rep["_runs"][1], rep["_runs"][2], rep["_runs"][0], tmp)
        public = [{k: v for k, v in r.items() if not k.startswith("_")} for r in per]
        report = _combine(public, dataset, cfg)
        report["wall_time_s"] = round(time.time() - t0, 1)
        (tmp / "report.json").write_text(json.dumps(to_jsonable(report), indent=2))
        (tmp / "report.md").write_text(markdown(report, public, report["wall_time_s"]))
    return report


def ev_targets(rep: dict) -> list:
    """The targets (runs.csv order) a system's diagnosis was evaluated on."""
    return list(rep["_ev"].targets)


KEYS = ("verdict", "calibrated", "noise_floor", "default_error", "base_error", "candidates", "selected", "final_error",
        "default_nrms", "base_nrms", "final_nrms", "base_systematic", "final_systematic", "rig")


def _combine(per: list[dict], dataset: str, cfg: DiagnoseConfig) -> dict:
    """One system: its keys at the top level.  Several: `system` is the list and every key maps system ->
    value (`explained` is true only if every system is explained)."""
    from dataclasses import asdict

    base = {"dataset": dataset, "config": asdict(cfg)}
    if len(per) == 1:
        return {**base, **per[0], "systems": {per[0]["system"]: per[0]}}
    out = {**base, "system": [p["system"] for p in per]}
    for k in KEYS:
        out[k] = {p["system"]: p[k] for p in per}
    out["explained"] = all(p["explained"] for p in per)
    out["systems"] = {p["system"]: p for p in per}
    return out
