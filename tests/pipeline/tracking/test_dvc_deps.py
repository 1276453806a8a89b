"""dvc.yaml: every stage depends on whole code folders (a module added to a package is tracked without editing
dvc.yaml), and each 'vibro <command>' stage depends on the package its command's workflow lives in."""
from __future__ import annotations

from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[3]
CODE = ("vibrobase", "sim", "surrogate", "pipeline")
WORKFLOW = {"sweep": "pipeline/datasets", "train": "surrogate", "optimise": "pipeline/optimise",
            "verify": "pipeline/optimise", "diagnose": "pipeline/diagnosis", "report": "pipeline/report",
            # the corrected chain
            "sweep_rig": "pipeline/datasets", "train_rig": "surrogate", "optimise_rig": "pipeline/optimise",
            "compare": "pipeline/optimise"}


def _stages() -> dict:
    return yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]


def test_code_deps_are_existing_folders():
    for name, st in _stages().items():
        deps = (st.get("do") or st)["deps"]
        for d in deps:
            if d.split("/")[0] in CODE:
                assert (REPO / d).is_dir(), f"stage {name}: dep '{d}' is not a folder of the repository"


def test_each_stage_depends_on_its_workflow_and_the_cli():
    for name, st in _stages().items():
        deps = set((st.get("do") or st)["deps"])
        assert {WORKFLOW[name], "pipeline/cli", "pipeline/core", "sim", "vibrobase"} <= deps, (name, sorted(deps))
