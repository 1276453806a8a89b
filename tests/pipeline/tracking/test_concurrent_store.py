"""Commands started together on a fresh repository share one MLflow SQLite store without a race on its tables."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
SETUP = "from pipeline.tracking.runs import setup; setup(); print('ok')"


def test_processes_started_together_on_a_fresh_store_all_open_it(tmp_path):
    env = {**os.environ, "VIBRO_HOME": str(tmp_path), "PYTHONPATH": str(REPO)}
    env.pop("MLFLOW_TRACKING_URI", None)
    procs = [subprocess.Popen([sys.executable, "-c", SETUP], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(4)]
    outs = [p.communicate(timeout=300) for p in procs]
    # without the lock two of them both create the tables: "table experiments already exists"
    assert all(p.returncode == 0 for p in procs), [e[-400:] for _, e in outs]
    assert all(o.strip().endswith("ok") for o, _ in outs)
    assert (tmp_path / "mlflow.db").exists()
