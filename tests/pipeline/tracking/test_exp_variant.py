"""A dvc experiment says up front what it will rerun and for how long, and one that fails or is interrupted leaves
the workspace as it was (params.yaml, dvc.lock and the stage outputs)."""
from __future__ import annotations

import io
import os
import subprocess
import sys
from contextlib import redirect_stdout
from pathlib import Path

import pytest

from pipeline.tracking import repro

REPO = Path(__file__).resolve().parents[3]
DVC = Path(sys.executable).with_name("dvc")


def test_a_variant_names_the_stages_it_reruns():
    train = repro.exp_stages(REPO, ["-S", "train.seed=1"])
    assert {"train", "train_rig", "optimise@rop", "optimise@pareto", "verify", "optimise_rig", "compare",
            "report"} == set(train)
    assert not {"sweep", "sweep_rig", "diagnose@drill-rig"} & set(train)
    assert repro.exp_stages(REPO, ["-S", "report.title=x"]) == ["report"]
    assert repro.exp_stages(REPO, ["--set-param=diagnose.seed=1"])[:2] == ["diagnose@seed000-published",
                                                                          "diagnose@drill-rig"]
    assert repro.exp_stages(REPO, []) == []


STAGE = """stages:
  make:
    cmd: python -c "import yaml,sys; v=yaml.safe_load(open('params.yaml'))['make']['value']; open('out.txt','w').write(str(v)); sys.exit(v == 2)"
    params: [make]
    outs: [out.txt]
"""


@pytest.mark.slow
@pytest.mark.skipif(not DVC.exists(), reason="dvc not installed in this environment")
def test_a_failed_experiment_leaves_the_workspace_as_it_was(tmp_path, monkeypatch):
    env = {**os.environ, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t",
           "GIT_COMMITTER_EMAIL": "t@t", "DVC_NO_ANALYTICS": "1", "PATH": f"{DVC.parent}:{os.environ['PATH']}"}
    (tmp_path / "dvc.yaml").write_text(STAGE)
    (tmp_path / "params.yaml").write_text("make:\n  value: 1   # kept\n")
    for cmd in (["git", "init", "-q"], [str(DVC), "init", "-q"], [str(DVC), "repro", "-q"],
                ["git", "add", "-A"], ["git", "commit", "-qm", "base"]):
        subprocess.run(cmd, cwd=tmp_path, env=env, check=True, capture_output=True)
    before = {p: (tmp_path / p).read_bytes() for p in ("params.yaml", "dvc.lock", "out.txt")}
    monkeypatch.setenv("VIBRO_NO_MLFLOW", "1")
    monkeypatch.setenv("PATH", env["PATH"])
    for k in ("GIT_AUTHOR_NAME", "GIT_AUTHOR_EMAIL", "GIT_COMMITTER_NAME", "GIT_COMMITTER_EMAIL"):
        monkeypatch.setenv(k, "t@t" if k.endswith("EMAIL") else "t")
    out = io.StringIO()
    with redirect_stdout(out):
        rc = repro._run(tmp_path, ["-S", "make.value=2"], exp=True)     # the stage writes out.txt, then fails
    assert rc != 0
    assert "This runs 1 stage(s)" in out.getvalue()
    assert {p: (tmp_path / p).read_bytes() for p in before} == before
