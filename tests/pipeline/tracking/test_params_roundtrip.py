"""`dvc exp run -S` rewrites params.yaml with dvc's round-trip YAML writer: it must change only the value set
(docs/pipeline-dvc.md) -- comments, order and flow-style lists kept, every other parameter equal."""
from __future__ import annotations

import shutil
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[3]


def test_dvc_set_changes_only_the_value_set(tmp_path):
    from dvc.utils.serialize import modify_yaml

    p = tmp_path / "params.yaml"
    shutil.copy(ROOT / "params.yaml", p)
    before_text = p.read_text()
    with modify_yaml(str(p)) as data:          # what `dvc exp run -S train.seed=7` does
        data["train"]["seed"] = 7
    after_text = p.read_text()
    before, after = yaml.safe_load(before_text), yaml.safe_load(after_text)
    assert after["train"].pop("seed") == 7 and before["train"].pop("seed") == 0
    assert after == before                                     # nulls read back as nulls, lists as lists
    comments = [ln.split("#", 1)[1] for ln in before_text.splitlines() if "#" in ln]
    assert all(c in after_text for c in comments)              # every comment kept
    assert "regressors: [gp, gbt, mlp]" in after_text          # flow-style lists kept
    changed = set(before_text.splitlines()) ^ set(after_text.splitlines())
    assert all("seed" in ln or "null" in ln or ln.split("#")[0].rstrip().endswith(":") for ln in changed)
