"""`vibro --help` and every subcommand's --help import no heavy package: commands import their workflow lazily."""
from __future__ import annotations

import subprocess
import sys

import pytest

from pipeline.cli import SUBCOMMANDS

HEAVY = ("numba", "pandas", "sklearn", "mlflow", "optuna", "dask")
CODE = ("import sys\nfrom pipeline.cli import main\ntry:\n    main(sys.argv[1:] + ['--help'])\nexcept SystemExit:\n    pass\n"
        "print(','.join(m for m in %r if m in sys.modules), file=sys.stderr)\n" % (HEAVY,))


@pytest.mark.parametrize("command", ("",) + SUBCOMMANDS)
def test_help_imports_no_heavy_package(command):
    proc = subprocess.run([sys.executable, "-c", CODE, *command.split()], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.strip().splitlines()[-1:] in ([], [""]), f"'vibro {command} --help' imported {proc.stderr}"
