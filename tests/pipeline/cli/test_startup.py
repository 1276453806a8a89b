"""Start-up of the command line, guarded by what a run imports, never by a timing.

`vibro --help` and every subcommand's --help import no heavy package (not even numpy): commands import their
workflow lazily, and ``pipeline.core.errors`` takes ``ParameterError`` from the numpy-free ``sim.models.param``
(through ``import sim``) and its base from ``vibrobase.errors``.
``vibro simulate`` imports numpy and numba (and numba itself pulls in scipy.linalg when it loads a cached
kernel), but no table, plotting, tracking or learning package.
"""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from pipeline.cli import SUBCOMMANDS

HEAVY = ("numpy", "numba", "scipy", "pandas", "matplotlib", "sklearn", "mlflow", "optuna", "dask",
         "importlib.metadata")     # the last: --version is read only when asked (~20 ms)
CODE = ("import sys\nfrom pipeline.cli import main\ntry:\n    main(sys.argv[1:] + ['--help'])\nexcept SystemExit:\n    pass\n"
        "print(','.join(m for m in %r if m in sys.modules), file=sys.stderr)\n" % (HEAVY,))

NOT_FOR_SIMULATE = ("pandas", "pyarrow", "matplotlib", "sklearn", "mlflow", "optuna", "dask", "skops", "tqdm",
                    "pipeline.datasets", "pipeline.tracking", "surrogate")
"""Imported by other commands; a plain ``vibro simulate`` (no --plot) needs none of them.  (importlib.metadata
is not listed: numba's entry-point scan imports it.)"""


def _imported_by(argv: list[str], names: tuple[str, ...]) -> tuple[subprocess.CompletedProcess, list[str]]:
    """Run ``main(argv)`` in a fresh interpreter; the ``names`` found in its sys.modules afterwards."""
    code = ("import sys\nfrom pipeline.cli import main\nrc = main(%r)\n"
            "print('IMPORTED=' + ','.join(m for m in %r if m in sys.modules), file=sys.stderr)\nsys.exit(rc)\n"
            % (argv, names))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    line = [ln for ln in proc.stderr.splitlines() if ln.startswith("IMPORTED=")]
    return proc, (line[-1].removeprefix("IMPORTED=").split(",") if line and line[-1] != "IMPORTED=" else [])


@pytest.mark.parametrize("command", ("",) + SUBCOMMANDS)
def test_help_imports_no_heavy_package(command):
    proc = subprocess.run([sys.executable, "-c", CODE, *command.split()], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.strip().splitlines()[-1:] in ([], [""]), f"'vibro {command} --help' imported {proc.stderr}"


def test_version_still_printed():
    """--version reads the version only when asked (importlib.metadata is not imported otherwise)."""
    proc = subprocess.run([sys.executable, "-m", "pipeline.cli", "--version"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("vibro ") and proc.stdout.strip() != "vibro unknown"


def test_simulate_imports_only_what_it_needs():
    proc, extra = _imported_by(["simulate", "drill", "--preset", "lab", "--json"], NOT_FOR_SIMULATE)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["status"] == "ok"        # it did simulate
    assert extra == [], f"'vibro simulate drill --preset lab' imported {extra}"
