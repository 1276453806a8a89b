"""What importing ``sim`` costs, guarded by sys.modules in a fresh interpreter (never by a timing).

``import sim`` (ParameterError, model_names, Rig) imports no numpy: the CLI's error handling and every --help use
it.  Looking a model up (``get_model``) imports numpy but not numba (sim/jit.py defers it to the first compile or
call, so a ``vibro simulate`` served by an ahead-of-time kernel never loads it), nor scipy.linalg (numba's
``numba.np.arraymath`` imports it to check for BLAS), nor pandas (only a history or a batch builds a DataFrame).
"""
from __future__ import annotations

import subprocess
import sys


def _modules_after(code: str, names: tuple[str, ...]) -> list[str]:
    probe = code + "\nimport sys\nprint(','.join(m for m in %r if m in sys.modules))\n" % (names,)
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout.strip().splitlines()[-1:]
    return out[0].split(",") if out and out[0] else []


def test_import_sim_is_light():
    code = "import sim\nsim.ParameterError, sim.model_names(), sim.Rig\nimport pipeline.core.errors"
    assert _modules_after(code, ("numpy", "numba", "scipy", "pandas")) == []


def test_get_model_loads_no_numba_and_no_pandas():
    code = "import sim\nfor m in sim.model_names():\n    sim.get_model(m)"
    assert _modules_after(code, ("numpy", "numba", "scipy.linalg", "pandas")) == ["numpy"]
