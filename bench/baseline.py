"""The baseline simulator (a fixed earlier commit, 33a799c), timed in the same benchmark run.

The x10 line (drill at 1e-10 label error against the baseline) needs that kernel next to the current one, with
interleaved repetitions.  Two versions of the ``sim`` package cannot share one
interpreter, so the old one runs in a worker process: ``git archive`` of the commit is unpacked once into
``bench/results/.baseline-<commit>/`` (its numba kernels are cached beside it), and the worker answers one
JSON request per line, ``{"model", "preset", "settings"}`` -> ``{"cpu_s", "wall_s", "labels"}``, timing
``sim.simulate`` with its own process clock.  The benchmark loop sends a request in its turn, so the old
kernel is interleaved with every other method.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COMMIT = "33a799c"          # the baseline the x10 line and the lean-kernel ratio are measured against

_WORKER = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
import sim
for line in sys.stdin:
    req = json.loads(line)
    c0, t0 = time.process_time(), time.perf_counter()
    lab = sim.simulate(req["model"], preset=req["preset"], settings=req["settings"]).labels
    out = {"cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - t0,
           "labels": {k: v for k, v in lab.items() if isinstance(v, (int, float, str)) and not isinstance(v, bool)}}
    sys.stdout.write(json.dumps(out) + "\n")
    sys.stdout.flush()
"""


def checkout(commit: str = COMMIT, root: Path = ROOT) -> Path:
    """The source tree of ``commit`` unpacked under bench/results (once); raises RuntimeError without git history."""
    dest = root / "bench" / "results" / f".baseline-{commit}"
    if (dest / "sim" / "api.py").exists():
        return dest
    dest.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=dest.parent) as tmp:
        tar = Path(tmp) / "src.tar"
        r = subprocess.run(["git", "-C", str(root), "archive", "--format=tar", "-o", str(tar), commit],
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"git archive {commit}: {r.stderr.strip() or 'failed'}")
        unpacked = Path(tmp) / "tree"
        with tarfile.open(tar) as tf:
            tf.extractall(unpacked, filter="data")
        os.replace(unpacked, dest)      # complete or absent: never a half-unpacked tree
    return dest


class BaselineWorker:
    """A worker process running ``sim.simulate`` of the old tree; ``run`` returns (labels, cpu_s, wall_s)."""

    def __init__(self, commit: str = COMMIT):
        self.commit = commit
        src = checkout(commit)
        env = {**os.environ, "VIBRO_KERNEL_DIR": str(src / ".numba_cache"), "PYTHONPATH": str(src)}
        self._p = subprocess.Popen([sys.executable, "-c", _WORKER, str(src)], stdin=subprocess.PIPE,
                                   stdout=subprocess.PIPE, text=True, env=env,   # stderr: its compile notices
                                   cwd=str(src))

    def run(self, model: str, preset: str | None, settings: dict) -> tuple[dict, float, float]:
        self._p.stdin.write(json.dumps({"model": model, "preset": preset, "settings": settings}) + "\n")
        self._p.stdin.flush()
        line = self._p.stdout.readline()
        if not line:
            raise RuntimeError(f"the baseline worker ({self.commit}) exited")
        out = json.loads(line)
        return out["labels"], out["cpu_s"], out["wall_s"]

    def close(self) -> None:
        if self._p.poll() is None:
            self._p.stdin.close()
            self._p.wait(timeout=30)
