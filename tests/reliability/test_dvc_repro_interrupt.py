"""kill -9 / Ctrl-C of ``dvc repro``: a rerun finishes the stage and its output equals an
uninterrupted run's; no lock is left that blocks it.  A one-stage project (a small drill sweep) in a temporary git
repository, run by the real dvc.  Slow (dvc start-up, numba load): ``pytest -m slow tests/reliability``."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

REPO = Path(__file__).resolve().parents[2]
DVC = Path(sys.executable).with_name("dvc")

STAGE = f"""stages:
  sweep:
    cmd: {sys.executable} -m pipeline.cli sweep --params params.yaml --out data/sweep --no-progress --no-mlflow
    params: [sweep]
    outs: [data/sweep]
"""
PARAMS = """sweep:
  model: drill
  preset: lab
  vary:
    frequency_hz: {low: 100.0, high: 450.0, scale: linear}
    static_force_n: {low: 600.0, high: 1800.0, scale: linear}
  design: sobol
  n_points: 24
  seed: 0
  chunk_size: 2
  workers: 1
"""

pytestmark = [pytest.mark.slow, pytest.mark.skipif(not DVC.exists(), reason="dvc not installed in this environment")]


def _project(root: Path) -> dict:
    root.mkdir()
    env = {**os.environ, "PYTHONPATH": str(REPO),     # the suite's kernel cache: compiled once, not per project
           "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t"}
    for cmd in (["git", "init", "-q"], [str(DVC), "init", "-q"]):
        subprocess.run(cmd, cwd=root, check=True, env=env, capture_output=True)
    (root / "dvc.yaml").write_text(STAGE)
    (root / "params.yaml").write_text(PARAMS)
    return env


def _dataset(root: Path):
    from pipeline.datasets.store import load_dataset

    return load_dataset(root / "data" / "sweep")


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT], ids=["kill-9", "ctrl-c"])
def test_dvc_repro_interrupted_then_rerun_equals_uninterrupted(tmp_path, sig):
    ref = tmp_path / "ref"
    env = _project(ref)
    subprocess.run([str(DVC), "repro", "-q"], cwd=ref, env=env, check=True, capture_output=True, timeout=900)
    expected = _dataset(ref)

    work = tmp_path / "work"
    env = _project(work)
    p = subprocess.Popen([str(DVC), "repro", "-q"], cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         start_new_session=True)
    deadline = time.time() + 600
    while not list((work / "data" / "sweep").glob("part-*.parquet")):     # interrupt mid-stage
        assert p.poll() is None, p.stderr.read().decode()
        assert time.time() < deadline
        time.sleep(0.1)
    os.killpg(p.pid, sig)            # the whole process group, as a terminal's Ctrl-C / a kill of the job would
    p.communicate(timeout=120)
    assert p.returncode != 0

    rerun = subprocess.run([str(DVC), "repro", "-q"], cwd=work, env=env, capture_output=True, timeout=900)
    assert rerun.returncode == 0, rerun.stderr.decode()
    assert not list((work / "data" / "sweep").glob(".part-*"))        # no temporaries left
    pd.testing.assert_frame_equal(_dataset(work), expected, check_exact=True)
    shutil.rmtree(tmp_path, ignore_errors=True)
