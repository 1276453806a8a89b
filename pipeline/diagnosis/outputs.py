"""What ``vibro diagnose`` writes of a :class:`~pipeline.diagnosis.result.DiagnoseResult`: the corrected rig
(rig.yaml, or rig-<system>.yaml per system), the PNG figures, report.json and report.md, atomically into one folder.

Called by the command (``pipeline/cli/diagnose.py``), which picks the folder and logs it to MLflow.
"""
from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

from vibrobase.files import atomic_directory
from vibrobase.jsonable import to_jsonable
from pipeline.diagnosis.cost import CostRecorder
from pipeline.diagnosis.workflow import diagnose
from pipeline.diagnosis.report import figures, markdown
from pipeline.diagnosis.result import DiagnoseResult
from pipeline.diagnosis.run import DiagnoseConfig

RIG_COMMENT = "the corrected rig of this diagnosis (report.json 'rig')"


def write_outputs(result: DiagnoseResult, out: str | os.PathLike) -> DiagnoseResult:
    """Write ``result`` into directory ``out`` (replaced as a whole, only once every file is written); returns the
    result as written: its cost with the drawing of the figures added (report.json ``cost``)."""
    from pipeline.core.rigfile import write_rig

    with atomic_directory(Path(out)) as tmp:
        for name, rig in result.rigs:
            write_rig(tmp / name, rig, comment=RIG_COMMENT)
        drawing = []
        for diag, runs in zip(result.systems, result.runs):
            rec = CostRecorder(diag.system)
            with rec.stage("figures: drawing"):
                drawn = figures(diag, runs, result.series, tmp)
            drawing += rec.rows()
            if tuple(drawn) != diag.report.figures:     # report.json names the figures before they are drawn
                raise RuntimeError(f"{diag.system}: figures drawn {drawn} differ from those reported "
                                   f"{list(diag.report.figures)}")
        if result.cost is not None:
            cost = result.cost.with_stages(drawing)
            result = replace(result, cost=cost, report=replace(result.report, cost=cost.to_json()))
        (tmp / "report.json").write_text(json.dumps(to_jsonable(result.report.to_json()), indent=2))
        (tmp / "report.md").write_text(markdown(result.report))
    return result


def diagnose_into(ds, out: str | os.PathLike, cfg: DiagnoseConfig, log=print, progress=None) -> DiagnoseResult:
    """Diagnose ``ds`` (:func:`~pipeline.diagnosis.workflow.diagnose`) and write the result into directory ``out``."""
    return write_outputs(diagnose(ds, cfg, log, progress), out)
